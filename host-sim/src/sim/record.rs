//! Recorders of a simulated run: the CSV log ([`LogRecorder`]), the raw
//! per-tick trace for replay on the firmware ([`RawTrace`]) and the
//! tracking and JAE errors ([`AngleErrors`]).

use std::path::Path;

use cable_joint::{Fault, Mode, Output, RawSample};

use super::{Recorder, TickRecord};
use crate::log::Log;
use crate::stats::{Acc, Summary};

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

/// What a board streaming a record every `every`-th control tick would
/// have written of `log` (a row a tick, as [`LogRecorder`] writes it): the
/// CSV log's measured columns (`t_s` to `f_ext_n`), the estimates the
/// firmware's records carry ([`crate::ingest::ONBOARD_COLUMNS`], computed
/// on line every tick) when `log` has them, the `tick` column, and with `applied_mean`
/// the mean current reference over the ticks since the record before
/// (`i_applied_a`, telemetry format 3; without it, what a format-2 board
/// sent: one sampled current a record). For tests and studies of
/// decimated recordings.
pub fn recorded_every(log: &Log, every: usize, applied_mean: bool) -> anyhow::Result<Log> {
    anyhow::ensure!(
        every >= 1,
        "a record every {every} ticks: must be at least 1"
    );
    let mut names = LOG_COLUMNS[..9].to_vec();
    names.extend(crate::ingest::ONBOARD_COLUMNS.iter().filter(|n| log.has(n)));
    let mut cols = names.clone();
    cols.push("tick");
    if applied_mean {
        cols.push("i_applied_a");
    }
    let columns = names
        .iter()
        .map(|n| log.col_required(n))
        .collect::<Result<Vec<_>, _>>()?;
    let i_ref = log.col_required("i_ref_a")?;
    let mut out = Log::with_columns(&cols)?;
    for k in (0..log.len()).step_by(every) {
        let mut row: Vec<f64> = columns.iter().map(|c| c[k]).collect();
        row.push(k as f64);
        if applied_mean {
            let from = k.saturating_sub(every);
            let mean = match k - from {
                0 => 0.0,
                n => i_ref[from..k].iter().sum::<f64>() / n as f64,
            };
            row.push(mean);
        }
        out.push_row(&row)?;
    }
    Ok(out)
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
/// replay homes the controller on it ([`Controller::set_origin`](cable_joint::Controller::set_origin)) and then
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_every_third_tick_carries_its_tick_and_the_mean_current_since_the_record_before() {
        let names = &LOG_COLUMNS[..9];
        let mut log = Log::with_columns(names).unwrap();
        for k in 0..10 {
            let mut row = vec![0.0; names.len()];
            row[0] = k as f64 * 1e-3;
            row[4] = k as f64; // i_ref_a
            log.push_row(&row).unwrap();
        }
        assert_eq!(names[4], "i_ref_a");
        let r = recorded_every(&log, 3, true).unwrap();
        assert_eq!(r.col("tick").unwrap(), [0.0, 3.0, 6.0, 9.0]);
        let t: Vec<f64> = [0, 3, 6, 9].map(|k| k as f64 * 1e-3).to_vec();
        assert_eq!(r.col("t_s").unwrap(), t);
        assert_eq!(r.col("i_ref_a").unwrap(), [0.0, 3.0, 6.0, 9.0]);
        // The ticks from the record before up to this one: (0+1+2)/3, ...
        assert_eq!(r.col("i_applied_a").unwrap(), [0.0, 1.0, 4.0, 7.0]);
        let sampled = recorded_every(&log, 3, false).unwrap();
        assert!(sampled.col("i_applied_a").is_none() && sampled.len() == 4);
        assert!(recorded_every(&log, 0, true).is_err());
    }
}
