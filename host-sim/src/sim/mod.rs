//! Closed-loop runner: the plant and the core's [`Controller`], tick by tick.
//!
//! Per control tick (default 2 kHz):
//!
//! 1. [`Plant::sample`] gives the raw sample the board would read (quantized
//!    counters, noisy ADC code);
//! 2. [`Controller::step`] — the same code the firmware runs — turns it into
//!    an [`Output`];
//! 3. the drive receives the DAC code's current (0 when `drive_enable` is
//!    low);
//! 4. the tick is handed to a [`Recorder`];
//! 5. the plant integrates one control period in whole sub-steps, with the
//!    external force profile evaluated at every sub-step.
//!
//! At construction the plant rests at the origin holding the preload, and the
//! controller is homed on the first sample ([`Controller::set_origin`]). The
//! controller starts in [`Mode::Idle`](cable_joint::Mode::Idle): set a command before running, or the
//! drive stays off and the preload back-drives the motor.
//!
//! Recorders: [`LogRecorder`] (DESIGN.md's CSV columns plus estimates and
//! ground truth), [`RawTrace`] (raw counts and codes with the controller's
//! output, for replay on the firmware under QEMU), [`AngleErrors`] (tracking
//! and JAE errors), `Vec<TickRecord>`, [`FnRecorder`] and tuples of these.

use cable_joint::{Command, Config, Controller, Output, RawSample};

use crate::plant::{Plant, PlantParams, PlantState, Tensions, TipObject};

mod record;
pub use record::{
    recorded_every, AngleErrors, LogRecorder, RawRecord, RawTrace, Table, LOG_COLUMNS, RAW_COLUMNS,
};

/// External tip force over time, N (> 0 opposes positive rotation). Time is
/// counted from the moment the profile is set ([`Sim::set_external_force`]).
#[derive(Clone, Debug, PartialEq)]
pub enum ForceProfile {
    /// A constant force.
    Constant(f64),
    /// Linear ramp from `from_n` to `to_n` over `duration_s`, held after.
    Ramp {
        /// Force at the start, N.
        from_n: f64,
        /// Force at the end and after, N.
        to_n: f64,
        /// Ramp duration, s.
        duration_s: f64,
    },
    /// Piecewise linear through `(t_s, f_n)` points (sorted by time), held
    /// before the first and after the last.
    Points(Vec<(f64, f64)>),
}

impl ForceProfile {
    /// Force at `t_s` seconds after the profile was set.
    pub fn at(&self, t_s: f64) -> f64 {
        match self {
            ForceProfile::Constant(f) => *f,
            ForceProfile::Ramp {
                from_n,
                to_n,
                duration_s,
            } => {
                if *duration_s <= 0.0 || t_s >= *duration_s {
                    *to_n
                } else if t_s <= 0.0 {
                    *from_n
                } else {
                    from_n + (to_n - from_n) * t_s / duration_s
                }
            }
            ForceProfile::Points(pts) => {
                let Some(&(t0, f0)) = pts.first() else {
                    return 0.0;
                };
                if t_s <= t0 {
                    return f0;
                }
                for w in pts.windows(2) {
                    let ((ta, fa), (tb, fb)) = (w[0], w[1]);
                    if t_s <= tb {
                        return if tb > ta {
                            fa + (fb - fa) * (t_s - ta) / (tb - ta)
                        } else {
                            fb
                        };
                    }
                }
                pts.last().map_or(0.0, |p| p.1)
            }
        }
    }
}

impl From<f64> for ForceProfile {
    fn from(f: f64) -> Self {
        ForceProfile::Constant(f)
    }
}

/// Everything about one control tick: what the board read, what the
/// controller answered, and the plant's true state at the sample instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickRecord {
    /// Tick number since the start.
    pub tick: u64,
    /// Time of the sample, s.
    pub t_s: f64,
    /// The raw sample the controller received.
    pub raw: RawSample,
    /// The controller's output.
    pub output: Output,
    /// The DOB's and the stretch's intervals the fusion combined this tick
    /// ([`cable_joint::fusion::Sources`]).
    pub sources: cable_joint::fusion::Sources,
    /// Current reference the drive received for the next period, A (the DAC
    /// code's value, 0 when disabled).
    pub drive_ref_a: f64,
    /// True plant state at the sample instant.
    pub state: PlantState,
    /// True tensions at the sample instant.
    pub tensions: Tensions,
    /// True torque constant at the sample instant, N·m/A.
    pub torque_constant_nm_a: f64,
    /// True external tip force at the sample instant (the applied profile
    /// and an object's push), N.
    pub f_ext_n: f64,
    /// Phase tag set by the scenario ([`Sim::set_phase`]).
    pub phase: u32,
    /// The sample the controller was homed on ([`Sim::origin_sample`]).
    pub origin: RawSample,
}

/// Receives every tick of a run.
pub trait Recorder {
    /// Called once per control tick, after the controller's step.
    fn record(&mut self, rec: &TickRecord);
}

/// Records nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NullRecorder;

impl Recorder for NullRecorder {
    fn record(&mut self, _rec: &TickRecord) {}
}

impl Recorder for Vec<TickRecord> {
    fn record(&mut self, rec: &TickRecord) {
        self.push(*rec);
    }
}

/// Wraps a closure as a recorder.
pub struct FnRecorder<F: FnMut(&TickRecord)>(pub F);

impl<F: FnMut(&TickRecord)> Recorder for FnRecorder<F> {
    fn record(&mut self, rec: &TickRecord) {
        (self.0)(rec)
    }
}

impl<R: Recorder + ?Sized> Recorder for &mut R {
    fn record(&mut self, rec: &TickRecord) {
        (**self).record(rec)
    }
}

impl<A: Recorder, B: Recorder> Recorder for (A, B) {
    fn record(&mut self, rec: &TickRecord) {
        self.0.record(rec);
        self.1.record(rec);
    }
}

impl<A: Recorder, B: Recorder, C: Recorder> Recorder for (A, B, C) {
    fn record(&mut self, rec: &TickRecord) {
        self.0.record(rec);
        self.1.record(rec);
        self.2.record(rec);
    }
}

/// Plant and controller in closed loop.
pub struct Sim {
    plant: Plant,
    controller: Controller,
    force: ForceProfile,
    force_start_s: f64,
    tick: u64,
    period_s: f64,
    substeps: usize,
    output: Output,
    raw: RawSample,
    origin: RawSample,
    phase: u32,
}

impl Sim {
    /// Plant at rest holding the preload, controller homed on the first
    /// sample and idle. The plant's step is rounded up to a whole number of
    /// sub-steps per control period. `seed` drives all noise.
    ///
    /// With the motor decoupled from the cable (`plant.motor_decoupled`)
    /// cable 1 is not held by the motor, so the controller's slack check is
    /// switched off.
    pub fn new(plant: PlantParams, config: Config, seed: u64) -> anyhow::Result<Self> {
        let mut config = config;
        if plant.motor_decoupled {
            config.limits.min_tension_fraction = 0.0;
        }
        let controller = Controller::new(config).map_err(|e| anyhow::anyhow!("controller: {e}"))?;
        let control_hz = config.control_rate_hz as f64;
        let period_s = 1.0 / control_hz;
        let mut plant = plant;
        let substeps = (plant.integration.step_hz / control_hz - 1e-9)
            .ceil()
            .max(1.0) as usize;
        plant.integration.step_hz = substeps as f64 * control_hz;
        let mut plant = Plant::new(plant, seed)?;
        let mut controller = controller;
        let raw = plant.sample();
        controller.set_origin(&raw);
        Ok(Self {
            plant,
            controller,
            force: ForceProfile::Constant(0.0),
            force_start_s: 0.0,
            tick: 0,
            period_s,
            substeps,
            output: Output::default(),
            raw,
            origin: raw,
            phase: 0,
        })
    }

    /// Start a new command (its trajectory time starts at the next tick).
    pub fn set_command(&mut self, command: Command) {
        self.controller.set_command(command);
    }

    /// The command in force.
    pub fn command(&self) -> Command {
        self.controller.command()
    }

    /// Apply an external tip force profile from now on (its time starts now).
    pub fn set_external_force(&mut self, profile: impl Into<ForceProfile>) {
        self.force = profile.into();
        self.force_start_s = self.time_s();
    }

    /// Mass hanging from the tip (adds `m l_e²` to the joint inertia), kg.
    pub fn set_tip_mass(&mut self, mass_kg: f64) {
        self.plant.set_tip_mass(mass_kg);
    }

    /// An object at the tip from now on, or none ([`Plant::set_object`]):
    /// its push is part of the true external force the ticks record.
    pub fn set_object(&mut self, object: Option<TipObject>) {
        self.plant.set_object(object);
    }

    /// Tag recorded with every following tick (scenario phase).
    pub fn set_phase(&mut self, phase: u32) {
        self.phase = phase;
    }

    /// Time of the next tick, s.
    pub fn time_s(&self) -> f64 {
        self.tick as f64 * self.period_s
    }

    /// Control period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Plant sub-steps per control period.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// Ticks run so far.
    pub fn ticks(&self) -> u64 {
        self.tick
    }

    /// The latest controller output.
    pub fn output(&self) -> &Output {
        &self.output
    }

    /// The latest raw sample.
    pub fn raw(&self) -> &RawSample {
        &self.raw
    }

    /// The sample the controller was homed on at construction
    /// ([`Controller::set_origin`]); a replay starts by homing on it.
    pub fn origin_sample(&self) -> &RawSample {
        &self.origin
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, mutable (set up a state, change the tip mass, ...).
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    /// The controller.
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// The controller, mutable (new configuration, fault injection, ...).
    pub fn controller_mut(&mut self) -> &mut Controller {
        &mut self.controller
    }

    /// One control tick; returns its record (also given to `rec`).
    pub fn step<R: Recorder + ?Sized>(&mut self, rec: &mut R) -> TickRecord {
        let t_s = self.time_s();
        let raw = self.plant.sample();
        let state = *self.plant.state();
        let tensions = self.plant.tensions();
        let output = self.controller.step(&raw);
        let drive_ref_a = if output.drive_enable {
            self.plant.params().sensors.scales.dac_a(output.dac) as f64
        } else {
            0.0
        };
        let record = TickRecord {
            tick: self.tick,
            t_s,
            raw,
            output,
            sources: self.controller.fusion_sources(),
            drive_ref_a,
            state,
            tensions,
            torque_constant_nm_a: self.plant.torque_constant_nm_a(),
            f_ext_n: self.force.at(t_s - self.force_start_s) + self.plant.contact_force_n(),
            phase: self.phase,
            origin: self.origin,
        };
        rec.record(&record);
        self.plant.set_current_command(drive_ref_a);
        let dt = self.period_s / self.substeps as f64;
        for k in 0..self.substeps {
            let t = t_s + k as f64 * dt - self.force_start_s;
            self.plant.set_external_force(self.force.at(t));
            self.plant.step();
        }
        self.raw = raw;
        self.output = output;
        self.tick += 1;
        record
    }

    /// Run for `seconds` (rounded to whole ticks); returns the last output.
    pub fn run_for<R: Recorder + ?Sized>(&mut self, seconds: f64, rec: &mut R) -> Output {
        let n = (seconds / self.period_s).round().max(0.0) as u64;
        for _ in 0..n {
            self.step(rec);
        }
        self.output
    }
}

/// Most control ticks one simulated run records: 500 s at 2 kHz. The whole
/// log is kept in memory (about 0.4 kB a tick, twice while it is written).
pub const MAX_TICKS: f64 = 1e6;

/// `duration_s` at `rate_hz` is at most [`MAX_TICKS`] control ticks; the
/// error names `what` (the option that set the duration) and the limit.
pub fn check_ticks(what: &str, duration_s: f64, rate_hz: f64) -> anyhow::Result<()> {
    let ticks = duration_s * rate_hz;
    anyhow::ensure!(
        ticks <= MAX_TICKS,
        "{what}: {duration_s} s is {ticks:.3e} control ticks at {rate_hz} Hz; one run records \
         at most {MAX_TICKS:.0} ticks ({} s at this rate), all kept in memory",
        MAX_TICKS / rate_hz
    );
    Ok(())
}

/// Convenience: one command for `seconds` from rest; returns the records.
pub fn run_command(
    plant: PlantParams,
    config: Config,
    seed: u64,
    command: Command,
    seconds: f64,
) -> anyhow::Result<Vec<TickRecord>> {
    let mut sim = Sim::new(plant, config, seed)?;
    sim.set_command(command);
    let mut recs = Vec::new();
    sim.run_for(seconds, &mut recs);
    Ok(recs)
}
