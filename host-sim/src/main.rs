//! `host-sim`: the simulated prototype and the host tools of the cable-joint
//! project.
//!
//! Subcommands (each module owns its arguments and its `run`):
//!
//! * `report` (default): the seed's experimental programme on the simulated
//!   prototype, with a report.
//! * `simulate`: one scenario, written as a CSV log.
//! * `import`: convert a measured run (MRDLab) to the project's CSV schema.
//! * `residual`: identification and the residual → effect → refit loop.
//! * `ingest`: decoded defmt telemetry → CSV log.
//! * `estimate`: replay any log through the core, write every estimate and
//!   the fused force's bound.
//! * `simulate-wrist`, `identify-wrist`: the wrist's free run as one log
//!   per joint, and Eq. 3 identified on such a run.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "host-sim",
    version,
    about = "Simulated cable-driven joint prototype and host tools"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    // Each helper adds its variant here: `Name(host_sim::module::Args)`.
    /// Convert a measured run (MRDLab) to the project's CSV log.
    Import(host_sim::cli::import::ImportArgs),
    /// Decoded defmt telemetry (probe-rs run / defmt-print) to a CSV log.
    Ingest(host_sim::cli::ingest::IngestArgs),
    /// Record the sensor trace the QEMU firmware replays.
    Trace(host_sim::cli::trace::TraceArgs),
    /// Processor in the loop: the firmware binary on QEMU against the simulated prototype.
    Pil(host_sim::cli::pil::PilArgs),
    /// Operate the firmware over its link: configuration, faults, scenarios, recording.
    Link(host_sim::cli::link::LinkArgs),
    /// Run one scenario on the simulated prototype and write the CSV log.
    Simulate(host_sim::cli::simulate::SimulateArgs),
    /// Tool payload identification and tool-end wrench estimation (KUKA wrist data).
    Payload(host_sim::cli::payload::PayloadArgs),
    /// Design an identification excitation (Fourier series, least condition number) for `--scenario excite`; with `--wrist`, the wrist's four joints for Eq. 3.
    Excite(host_sim::cli::excite::ExciteArgs),
    /// Identify Eq. 3 (the free wrist's inverse dynamics) on a run recorded as one log per joint.
    IdentifyWrist(host_sim::cli::wrist::IdentifyWristArgs),
    /// Run the simulated wrist free (or grasping, --grasp) and write one log per joint (the input of identify-wrist, estimate-wrist).
    SimulateWrist(host_sim::cli::wrist::SimulateWristArgs),
    /// The wrist's forces (Eq. 4-5: each jaw's force, the clamp force, their bounds) from a run recorded as one log per joint.
    EstimateWrist(host_sim::cli::wrist::EstimateWristArgs),
    /// Identify B_m, the JAE and the tension models from logs, or the force scale from known weights; write the configuration.
    Identify(host_sim::cli::identify::IdentifyArgs),
    /// Replay a log (any rate) through the core; write every estimate and the force bound.
    Estimate(host_sim::cli::estimate::EstimateArgs),
    /// Residual analysis: rank and add effect terms, judged on validation data.
    Residual(host_sim::cli::residual::ResidualArgs),
    /// Undeclared effects alone and in pairs on drawn plants: what the residual loop names.
    Undeclared(host_sim::cli::undeclared::UndeclaredArgs),
    /// The seed's experimental programme on the simulated prototype, with a report (default).
    Report(host_sim::cli::report::ReportArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // No output of the command may replace one of its inputs.
    host_sim::output::track_inputs();
    // Ctrl-C or kill: no temporary file left, a recording kept.
    if let Err(e) = host_sim::interrupt::install() {
        eprintln!("warning: no signal handling ({e}): Ctrl-C leaves temporary files behind");
    }
    let result: anyhow::Result<()> = match cli.command {
        None => host_sim::cli::report::run(host_sim::cli::report::ReportArgs::default()),
        Some(Command::Import(args)) => host_sim::cli::import::run(args),
        Some(Command::Ingest(args)) => host_sim::cli::ingest::run(args),
        Some(Command::Trace(args)) => host_sim::cli::trace::run(args),
        Some(Command::Pil(args)) => host_sim::cli::pil::run(args),
        Some(Command::Link(args)) => host_sim::cli::link::run(args),
        Some(Command::Simulate(a)) => host_sim::cli::simulate::run(a),
        Some(Command::Payload(a)) => host_sim::cli::payload::run(a),
        Some(Command::Excite(a)) => host_sim::cli::excite::run(a),
        Some(Command::Identify(a)) => host_sim::cli::identify::run(a),
        Some(Command::IdentifyWrist(a)) => host_sim::cli::wrist::run_identify(a),
        Some(Command::SimulateWrist(a)) => host_sim::cli::wrist::run_simulate(a),
        Some(Command::EstimateWrist(a)) => host_sim::cli::wrist::run_estimate(a),
        Some(Command::Residual(a)) => host_sim::cli::residual::run(a),
        Some(Command::Undeclared(a)) => host_sim::cli::undeclared::run(a),
        Some(Command::Estimate(a)) => host_sim::cli::estimate::run(a),
        Some(Command::Report(a)) => host_sim::cli::report::run(a),
        #[allow(unreachable_patterns)]
        Some(_) => Ok(()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
