//! `host-sim residual` end to end: a simulated prototype log and imported
//! MRDLab runs through the command line, the JSON and plots it writes, and
//! the configuration it writes replayed through the core (the estimate the
//! firmware would compute equals the model the tool reported).

use std::path::{Path, PathBuf};
use std::process::Command;

use cable_joint::Config;
use host_sim::derive::derive;
use host_sim::io::config::load_config;
use host_sim::log::Log;
use host_sim::plant::PlantParams;
use host_sim::scenario::{self, ScenarioOptions};
use host_sim::sim::LogRecorder;
use serde_json::Value;

const MRDLAB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/mrdlab");

fn host_sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
}

fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().expect("host-sim runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "host-sim failed: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

fn read_json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).expect("json written")).expect("valid JSON")
}

/// A simulated calibration run (0.5 Hz sine, motor-encoder loop, magnetic
/// encoder fitted), written as a project CSV log.
fn sim_log(dir: &Path) -> (PathBuf, Log) {
    let mut rec = LogRecorder::new(true);
    scenario::run(
        "track-motor",
        PlantParams::default(),
        scenario::tuned_gains(&Config::default()),
        None,
        &ScenarioOptions::default(),
        &mut rec,
    )
    .expect("simulation runs");
    let log = rec.to_log().expect("log");
    let path = dir.join("run.csv");
    log.write(&path).expect("log written");
    (path, log)
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x * x;
        n += 1;
    }
    (s / n as f64).sqrt()
}

/// Rows the tool validated on with `--holdout 0.3 --decimate 4`.
fn validation_rows(n: usize) -> impl Iterator<Item = usize> {
    let cut = (0.7 * n as f64).round() as usize;
    (cut..n).step_by(4)
}

#[test]
fn simulated_log_jae_and_tension_configs_run_in_the_core() {
    let dir = tempfile::tempdir().unwrap();
    let (path, log) = sim_log(dir.path());
    let d = dir.path();
    let base = d.join("base.toml");
    std::fs::write(
        &base,
        toml::to_string(&scenario::tuned_gains(&Config::default())).unwrap(),
    )
    .unwrap();

    // JAE: JSON, plots, configuration.
    let stdout = run_ok(host_sim().args([
        "residual",
        "--log",
        path.to_str().unwrap(),
        "--model",
        "jae",
        "--decimate",
        "4",
        "--config",
        base.to_str().unwrap(),
        "--json",
        d.join("jae.json").to_str().unwrap(),
        "--plots",
        d.join("plots").to_str().unwrap(),
        "--config-out",
        d.join("jae.toml").to_str().unwrap(),
    ]));
    assert!(
        stdout.contains("baseline") && stdout.contains("final"),
        "{stdout}"
    );
    let j = read_json(&d.join("jae.json"));
    let before = j["before_rmse"].as_f64().expect("before_rmse");
    let after = j["after_rmse"].as_f64().expect("after_rmse");
    let effects = j["effects"].as_array().expect("effects list");
    assert!(after <= before, "after {after} > before {before}");
    for e in effects {
        assert!(e["name"].is_string() && e["meaning"].is_string(), "{e}");
        assert!(e["val_rmse"].as_f64().unwrap() < before);
    }
    assert_eq!(j["target"], "theta_rad");
    for f in ["residual_time.svg", "residual_time.png"] {
        let bytes = std::fs::read(d.join("plots").join(f)).expect("plot written");
        assert!(bytes.len() > 1000, "{f}: {} bytes", bytes.len());
    }
    let png = std::fs::read(d.join("plots/residual_time.png")).unwrap();
    assert_eq!(&png[..4], b"\x89PNG", "PNG signature");
    let svg = std::fs::read_to_string(d.join("plots/residual_time.svg")).unwrap();
    assert!(
        svg.contains("<svg") && svg.contains("residual"),
        "SVG with text"
    );

    // The written configuration, replayed through the core: its JAE estimate
    // has the error the tool reported for the final model.
    let cfg = load_config(d.join("jae.toml")).expect("config-out is a valid configuration");
    assert_eq!(cfg.jae.added.len as usize, effects.len());
    let replay = derive(&log, &cfg).unwrap();
    let th = log.col("theta_rad").unwrap();
    let hat = replay.col("theta_hat_rad").unwrap();
    let core = rms(validation_rows(log.len()).map(|k| th[k] - hat[k]));
    assert!(
        (core - after).abs() <= 0.01 * after,
        "core's JAE with the written config: RMSE {core:.6e} rad vs reported {after:.6e} rad"
    );

    // Tension model, continuing from the JAE config.
    run_ok(host_sim().args([
        "residual",
        "--log",
        path.to_str().unwrap(),
        "--model",
        "tension",
        "--decimate",
        "4",
        "--config",
        d.join("jae.toml").to_str().unwrap(),
        "--json",
        d.join("tension.json").to_str().unwrap(),
        "--config-out",
        d.join("tension.toml").to_str().unwrap(),
    ]));
    let t = read_json(&d.join("tension.json"));
    let after = t["after_rmse"].as_f64().unwrap();
    assert!(after < t["before_rmse"].as_f64().unwrap());
    let cfg = load_config(d.join("tension.toml")).unwrap();
    assert_eq!(
        cfg.jae,
        load_config(d.join("jae.toml")).unwrap().jae,
        "JAE kept"
    );
    let replay = derive(&log, &cfg).unwrap();
    let hat = replay.col("tension1_hat_n").unwrap();
    let model = replay.col("tension1_model_n").unwrap();
    let core = rms(validation_rows(log.len()).map(|k| hat[k] - model[k]));
    assert!(
        (core - after).abs() <= 0.01 * after,
        "core's tension model with the written config: RMSE {core:.5} N vs reported {after:.5} N"
    );
}

#[test]
fn mrdlab_runs_are_imported_and_validated_on_other_runs() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("angle.json");
    let f = |n: &str| format!("{MRDLAB}/{n}.TXT.gz");
    let stdout = run_ok(host_sim().args([
        "residual",
        "--log",
        &f("00"),
        &f("09"),
        &f("40"),
        &f("49"),
        "--validate",
        &f("22"),
        &f("25"),
        "--target",
        "theta_rad",
        "--decimate",
        "10",
        "--json",
        json.to_str().unwrap(),
    ]));
    assert!(stdout.contains("22.TXT.gz"), "{stdout}");
    let j = read_json(&json);
    let before = j["before_rmse"].as_f64().unwrap();
    let after = j["after_rmse"].as_f64().unwrap();
    assert!(
        after < 0.7 * before,
        "angle RMSE {:.3}° -> {:.3}°",
        before.to_degrees(),
        after.to_degrees()
    );
    assert!(!j["effects"].as_array().unwrap().is_empty());
    // Default inputs: the input side only (no jaw torque, no input torque
    // sensor, no jaw angle).
    let names: Vec<&str> = j["baseline"]["coefs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["phi_rad", "spindle_rad", "i_meas_a", "cmd", "const"]
    );
    assert_eq!(j["validate_logs"].as_array().unwrap().len(), 2);
    assert_eq!(j["runs"].as_array().unwrap().len(), 2, "per-run errors");
}

#[test]
fn bad_requests_fail_with_one_clear_message() {
    let f = format!("{MRDLAB}/00.TXT.gz");
    let out = host_sim()
        .args(["residual", "--log", &f, "--target", "nope"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nope") && err.contains("00.TXT.gz"), "{err}");

    let out = host_sim()
        .args([
            "residual",
            "--log",
            &f,
            "--target",
            "theta_rad",
            "--config-out",
            "x.toml",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--config-out"));

    // A project model on a log without the columns it needs.
    let out = host_sim()
        .args(["residual", "--log", &f, "--model", "jae"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("x1_m"));
}

/// A log kept at a row every 10th tick by a logger without the firmware's
/// tick counter: `residual --ticks-per-row 10` fits and validates it as the
/// board's recording of the same run (tick column kept), value for value.
/// Without the option the rows are taken for ticks of a 10× slower loop,
/// and the fit differs; on an MRDLab run the option is refused.
#[test]
fn ticks_per_row_fits_a_log_without_a_tick_column_as_the_recording() {
    let dir = tempfile::tempdir().unwrap();
    let (_, log) = sim_log(dir.path());
    let mut tenth = host_sim::sim::recorded_every(&log, 10, true).expect("a decimated recording");
    let (board, foreign) = (dir.path().join("board"), dir.path().join("foreign"));
    std::fs::create_dir_all(&board).unwrap();
    std::fs::create_dir_all(&foreign).unwrap();
    tenth.write(board.join("run.csv")).unwrap();
    tenth.remove_col("tick").unwrap();
    tenth.write(foreign.join("run.csv")).unwrap();
    let fit = |d: &Path, extra: &[&str], json: &str| -> (Value, String) {
        let out = host_sim()
            .args([
                "residual",
                "--model",
                "tension",
                "--max-terms",
                "2",
                "--log",
            ])
            .arg(d.join("run.csv"))
            .args(extra)
            .arg("--json")
            .arg(dir.path().join(json))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        (read_json(&dir.path().join(json)), stderr)
    };
    let (recording, _) = fit(&board, &[], "board.json");
    let (rebuilt, stderr) = fit(&foreign, &["--ticks-per-row", "10"], "rebuilt.json");
    assert!(
        stderr.contains("residual:") && stderr.contains("a row every 10 control ticks"),
        "{stderr}"
    );
    assert_eq!(rebuilt["before_rmse"], recording["before_rmse"]);
    assert_eq!(rebuilt["after_rmse"], recording["after_rmse"]);
    assert_eq!(rebuilt["effects"], recording["effects"]);
    let (rows, _) = fit(&foreign, &[], "rows.json");
    assert_ne!(
        rows["before_rmse"], recording["before_rmse"],
        "rows taken for ticks fit as the recording: the option would not matter"
    );

    let out = host_sim()
        .args([
            "residual",
            "--model",
            "jae",
            "--ticks-per-row",
            "10",
            "--log",
        ])
        .arg(format!("{MRDLAB}/00.TXT.gz"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("00.TXT.gz") && err.contains("--ticks-per-row 10") && err.contains("MRDLab"),
        "{err}"
    );
}
