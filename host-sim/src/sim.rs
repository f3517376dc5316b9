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
//! controller starts in [`Mode::Idle`]: set a command before running, or the
//! drive stays off and the preload back-drives the motor.
//!
//! Recorders: [`LogRecorder`] (DESIGN.md's CSV columns plus estimates and
//! ground truth), [`RawTrace`] (raw counts and codes with the controller's
//! output, for replay on the firmware under QEMU), [`AngleErrors`] (tracking
//! and JAE errors), `Vec<TickRecord>`, [`FnRecorder`] and tuples of these.

use std::path::Path;

use cable_joint::{Command, Config, Controller, Fault, Mode, Output, RawSample};

use crate::log::Log;
use crate::plant::{Plant, PlantParams, PlantState, Tensions};
use crate::stats::{Acc, Summary};

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
    /// Current reference the drive received for the next period, A (the DAC
    /// code's value, 0 when disabled).
    pub drive_ref_a: f64,
    /// True plant state at the sample instant.
    pub state: PlantState,
    /// True tensions at the sample instant.
    pub tensions: Tensions,
    /// True torque constant at the sample instant, N·m/A.
    pub torque_constant_nm_a: f64,
    /// Applied external tip force at the sample instant, N.
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
            drive_ref_a,
            state,
            tensions,
            torque_constant_nm_a: self.plant.torque_constant_nm_a(),
            f_ext_n: self.force.at(t_s - self.force_start_s),
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

/// Columns of [`LogRecorder`]: DESIGN.md's CSV columns, the controller's
/// estimates, then the plant's ground truth (`*_true_*`) and tags.
///
/// * `f1_true_n`: cable 0 at the rope wheel, the motor's load `F_1` (what
///   `tension1_hat_n` estimates); `fw1_true_n`, `fw2_true_n`: cables 1 and 2;
///   `fs_true_n`: the return spring.
/// * `i_drive_ref_a`: the current the drive was told (DAC value, 0 when
///   disabled); `i_true_a`: the winding current.
/// * `mode`: [`Mode::code`]; `fault_code`: [`Fault::code_of`]; `phase`: the
///   scenario's phase tag.
pub const LOG_COLUMNS: [&str; 43] = [
    "t_s",
    "x1_m",
    "x2_m",
    "phi_rad",
    "i_ref_a",
    "i_meas_a",
    "theta_rad",
    "theta_ref_rad",
    "f_ext_n",
    "theta_hat_rad",
    "theta_motor_rad",
    "f_ext_hat_n",
    "f_ext_stretch_n",
    "f_ext_fused_n",
    "f_ext_lo_n",
    "f_ext_hi_n",
    "fusion_flags",
    "tension1_stretch_n",
    "tension1_hat_n",
    "tension1_model_n",
    "load_torque_nm",
    "x1_vel_m_s",
    "x2_vel_m_s",
    "x2_acc_m_s2",
    "phi_vel_rad_s",
    "motor_vel_ref_rad_s",
    "theta_true_rad",
    "theta_vel_true_rad_s",
    "phi_true_rad",
    "x1_true_m",
    "x2_true_m",
    "i_true_a",
    "i_drive_ref_a",
    "f1_true_n",
    "fw1_true_n",
    "fw2_true_n",
    "fs_true_n",
    "km_true_nm_a",
    "winding_true_c",
    "drift_true_a",
    "mode",
    "fault_code",
    "phase",
];

fn log_row(r: &TickRecord, magnetic_fitted: bool) -> [f64; 43] {
    let e = &r.output.est;
    let s = &r.state;
    let t = &r.tensions;
    let f = |v: f32| v as f64;
    [
        r.t_s,
        f(e.x1_m),
        f(e.x2_m),
        f(e.phi_rad),
        f(r.output.current_ref_a),
        f(e.i_meas_a),
        if magnetic_fitted {
            f(e.theta_mag_rad)
        } else {
            f64::NAN
        },
        f(e.theta_ref_rad),
        r.f_ext_n,
        f(e.theta_hat_rad),
        f(e.theta_motor_rad),
        f(e.f_ext_hat_n),
        f(e.f_ext_stretch_n),
        f(e.f_ext_fused_n),
        f(e.f_ext_lo_n),
        f(e.f_ext_hi_n),
        f64::from(e.fusion_flags),
        f(e.tension1_stretch_n),
        f(e.tension1_n),
        f(e.tension1_model_n),
        f(e.load_torque_nm),
        f(e.x1_vel_m_s),
        f(e.x2_vel_m_s),
        f(e.x2_acc_m_s2),
        f(e.phi_vel_rad_s),
        f(e.motor_vel_ref_rad_s),
        s.theta_rad,
        s.theta_vel_rad_s,
        s.phi_rad,
        s.x1_m,
        s.x2_m,
        s.current_a,
        r.drive_ref_a,
        t.rope_n,
        t.cable1_n,
        t.cable2_n,
        t.spring_n,
        r.torque_constant_nm_a,
        s.winding_c,
        s.drift_a,
        r.output.mode.code() as f64,
        Fault::code_of(r.output.fault) as f64,
        r.phase as f64,
    ]
}

/// A simple column table (names and rows; NaN = not measured), turned into
/// the project's [`Log`] by one function.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    /// Column names.
    pub names: Vec<&'static str>,
    /// Rows, one value per column.
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// As the project's CSV log: non-finite cells become "not measured".
    pub fn to_log(&self) -> anyhow::Result<Log> {
        let mut log = Log::with_columns(&self.names)?;
        let mut cells = Vec::with_capacity(self.names.len());
        for row in &self.rows {
            cells.clear();
            cells.extend(row.iter().map(|v| v.is_finite().then_some(*v)));
            log.push_row_opt(&cells)?;
        }
        Ok(log)
    }

    /// Write as CSV (atomically, through [`Log::write`]).
    pub fn write(&self, path: impl AsRef<Path>) -> anyhow::Result<()> {
        self.to_log()?.write(path.as_ref())?;
        Ok(())
    }

    /// Values of one column.
    pub fn col(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.names.iter().position(|n| *n == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

/// Records every tick as one row of [`LOG_COLUMNS`].
#[derive(Clone, Debug)]
pub struct LogRecorder {
    table: Table,
    magnetic_fitted: bool,
}

impl LogRecorder {
    /// Empty recorder. `magnetic_fitted`: write the magnetic encoder's angle
    /// in `theta_rad` (else the column is "not measured").
    pub fn new(magnetic_fitted: bool) -> Self {
        Self {
            table: Table {
                names: LOG_COLUMNS.to_vec(),
                rows: Vec::new(),
            },
            magnetic_fitted,
        }
    }

    /// The recorded table.
    pub fn table(&self) -> &Table {
        &self.table
    }

    /// Rows recorded.
    pub fn len(&self) -> usize {
        self.table.rows.len()
    }

    /// No row yet.
    pub fn is_empty(&self) -> bool {
        self.table.rows.is_empty()
    }

    /// As the project's log.
    pub fn to_log(&self) -> anyhow::Result<Log> {
        self.table.to_log()
    }

    /// Write the CSV log atomically.
    pub fn write(&self, path: impl AsRef<Path>) -> anyhow::Result<()> {
        self.table.write(path)
    }
}

impl Recorder for LogRecorder {
    fn record(&mut self, rec: &TickRecord) {
        self.table
            .rows
            .push(log_row(rec, self.magnetic_fitted).to_vec());
    }
}

/// One tick of a raw trace: the sample the board read and the controller's
/// answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawRecord {
    /// Time of the sample, s.
    pub t_s: f64,
    /// Raw counters and ADC code.
    pub raw: RawSample,
    /// The controller's output for this sample.
    pub output: Output,
}

/// Columns of [`RawTrace::to_table`]. The first row is the homing sample
/// (`homing` = 1, at `t_s` one period before the first tick, no outputs); a
/// replay homes the controller on it ([`Controller::set_origin`]) and then
/// steps through the other rows.
pub const RAW_COLUMNS: [&str; 15] = [
    "t_s",
    "homing",
    "grating1_count",
    "grating2_count",
    "motor_count",
    "magnetic_count",
    "adc_code",
    "dac_code",
    "drive_enable",
    "current_ref_a",
    "mode",
    "fault_code",
    "theta_hat_rad",
    "f_ext_hat_n",
    "tension1_hat_n",
];

/// Raw per-tick samples and outputs, for replaying the same inputs through
/// the firmware (e.g. under QEMU) and comparing its outputs bit for bit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawTrace {
    /// The sample the controller was homed on.
    pub origin: Option<RawSample>,
    /// The ticks, in order.
    pub records: Vec<RawRecord>,
}

impl RawTrace {
    /// Empty trace.
    pub fn new() -> Self {
        Self::default()
    }

    /// The raw samples only, in order.
    pub fn samples(&self) -> Vec<RawSample> {
        self.records.iter().map(|r| r.raw).collect()
    }

    /// As a table of [`RAW_COLUMNS`] (counts and codes as exact integers;
    /// the homing row first).
    pub fn to_table(&self) -> Table {
        let counts = |r: &RawSample| {
            [
                r.grating1.0 as f64,
                r.grating2.0 as f64,
                r.motor.0 as f64,
                r.magnetic.0 as f64,
                r.current.0 as f64,
            ]
        };
        let mut rows = Vec::with_capacity(self.records.len() + 1);
        if let Some(o) = &self.origin {
            let period = match self.records.as_slice() {
                [a, b, ..] => b.t_s - a.t_s,
                _ => 0.0,
            };
            let t0 = self.records.first().map_or(0.0, |r| r.t_s) - period;
            let mut row = vec![t0, 1.0];
            row.extend(counts(o));
            row.extend([f64::NAN; 8]);
            rows.push(row);
        }
        rows.extend(self.records.iter().map(|r| {
            let o = &r.output;
            vec![
                r.t_s,
                0.0,
                r.raw.grating1.0 as f64,
                r.raw.grating2.0 as f64,
                r.raw.motor.0 as f64,
                r.raw.magnetic.0 as f64,
                r.raw.current.0 as f64,
                o.dac.0 as f64,
                o.drive_enable as u8 as f64,
                o.current_ref_a as f64,
                o.mode.code() as f64,
                Fault::code_of(o.fault) as f64,
                o.est.theta_hat_rad as f64,
                o.est.f_ext_hat_n as f64,
                o.est.tension1_n as f64,
            ]
        }));
        Table {
            names: RAW_COLUMNS.to_vec(),
            rows,
        }
    }

    /// Write as CSV (atomically).
    pub fn write(&self, path: impl AsRef<Path>) -> anyhow::Result<()> {
        self.to_table().write(path)
    }
}

impl Recorder for RawTrace {
    fn record(&mut self, rec: &TickRecord) {
        self.origin.get_or_insert(rec.origin);
        self.records.push(RawRecord {
            t_s: rec.t_s,
            raw: rec.raw,
            output: rec.output,
        });
    }
}

/// Tracking error `theta_ref - theta_mag` (desired minus the quantized
/// magnetic encoder, as the seed measures it) and JAE error
/// `theta_hat - theta_mag`, over the ticks with the drive enabled, from
/// `start_s` on, optionally only in some phases.
#[derive(Clone, Debug, Default)]
pub struct AngleErrors {
    /// Ignore ticks before this time, s.
    pub start_s: f64,
    /// Only these phases (empty = all).
    pub phases: Vec<u32>,
    /// Track against the motor-implied angle instead of the magnetic encoder
    /// (motor decoupled from the joint); no JAE statistics then.
    pub against_motor: bool,
    tracking: Acc,
    jae: Acc,
}

impl AngleErrors {
    /// Statistics over every enabled tick from `start_s` on.
    pub fn new(start_s: f64) -> Self {
        Self {
            start_s,
            ..Self::default()
        }
    }

    /// Tracking error statistics (desired − magnetic encoder), degrees, if
    /// any tick counted.
    pub fn tracking(&self) -> Option<Summary> {
        self.tracking.degrees()
    }

    /// JAE error statistics (estimate − magnetic encoder), degrees, if any
    /// tick counted.
    pub fn jae(&self) -> Option<Summary> {
        self.jae.degrees()
    }
}

impl Recorder for AngleErrors {
    fn record(&mut self, rec: &TickRecord) {
        if rec.t_s < self.start_s
            || !rec.output.drive_enable
            || rec.output.mode == Mode::Idle
            || (!self.phases.is_empty() && !self.phases.contains(&rec.phase))
        {
            return;
        }
        let e = &rec.output.est;
        if self.against_motor {
            self.tracking
                .push((e.theta_ref_rad - e.theta_motor_rad) as f64);
        } else {
            self.tracking
                .push((e.theta_ref_rad - e.theta_mag_rad) as f64);
            self.jae.push((e.theta_hat_rad - e.theta_mag_rad) as f64);
        }
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
