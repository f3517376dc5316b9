//! Importers from measured data sets to the project's CSV log ([`crate::log`]).
//!
//! `host-sim import mrdlab IN.TXT[.gz] --out run.csv`
//!
//! ## MRDLab (University of Minnesota, da Vinci tool characterisation)
//!
//! A Maxon motor with a 35:1 gearhead turns the input spindle of a da Vinci
//! EndoWrist; the jaw angle and a resistive jaw torque are measured at the
//! distal end. 1 kHz, 20 s per run; see `tests/data/mrdlab/README.md` (ODbL /
//! DbCL) for the raw columns. [`import_mrdlab`] gives a log with exactly the
//! columns [`MRDLAB_COLUMNS`]:
//!
//! | column | raw | conversion |
//! |---|---|---|
//! | `t_s` | 1 | s, minus the first sample's time |
//! | `phi_rad` | 9 | motor shaft (before the gear), [`MOTOR_COUNTS_PER_REV`] |
//! | `spindle_rad` | 2 | gear output / tool input spindle, [`SPINDLE_COUNTS_PER_REV`], sign flipped |
//! | `i_meas_a` | 4 | A |
//! | `cmd` | 8 | drive command (-1..1), sign flipped |
//! | `tau_in_nm` | 3 | × [`FUTEK_NM_PER_COUNT`] |
//! | `theta_rad` | 5 | jaw, [`JAW_COUNTS_PER_REV`] |
//! | `tau_ext_nm` | 6 | × [`FUTEK_NM_PER_COUNT`], sign flipped |
//!
//! Angles are relative to the run's first sample; torques are as measured
//! (no offset removed).
//!
//! **Signs.** Everything is expressed in the motor's positive direction, as
//! the project's model (DESIGN.md §1) expects: positive current winds the
//! motor (`phi_rad`) positive, which turns the spindle and the jaw positive;
//! `tau_in_nm > 0` is the motor driving that way; `cmd` has the sign of the
//! current it asks for (measured: `i_meas_a ≈ 2.06 A · cmd − 0.020 A`, rms
//! residual 5.5 mA over the 12 runs); `tau_ext_nm > 0` opposes positive jaw
//! rotation (the load the motor must overcome: in the 100 % runs the mean
//! `tau_in_nm` and `tau_ext_nm` are both near +0.12 N·m). In the raw file the
//! spindle encoder, the distal torque and the command count the other way;
//! they are negated here, nothing else is.
//!
//! **Motor encoder scale.** The data set's README gives "4196·35 counts per
//! output rev"; the authors' own MATLAB (`CUIToMaxon = -4096/8192*35`,
//! "Maxon encoder 1024 ppi") uses 4096. Measured on the 12 runs in
//! `tests/data/mrdlab`:
//!
//! * a plain regression of raw column 9 on column 2 gives −17.70 … −17.82
//!   counts per spindle count, i.e. 4144 … 4170 counts per motor turn at
//!   35:1 — but this slope is inflated by the torsional compliance between
//!   motor and spindle (the input torque grows with the spindle angle);
//! * adding the input torque (compliance) and the direction of motion
//!   (backlash) as regressors gives −17.39 … −17.61, mean −17.502:
//!   4096 counts per motor turn with a 35:1 gear to within 0.6 %.
//!
//! So [`MOTOR_COUNTS_PER_REV`] is 4096 (a 1024-line encoder in quadrature)
//! and "4196" in the README is a typo. `tests/import_mrdlab.rs` re-measures
//! this ratio on every run.

use std::fmt;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use crate::log::{Log, LogError, LogErrorKind, Schema, DEFAULT_MIN_ROWS};

/// Back-end CUI encoder on the input spindle, counts per revolution.
pub const SPINDLE_COUNTS_PER_REV: f64 = 8192.0;
/// Back-end Maxon motor encoder, counts per *motor* revolution (measured; see
/// the module documentation).
pub const MOTOR_COUNTS_PER_REV: f64 = 4096.0;
/// Gearhead ratio between motor and spindle.
pub const GEAR_RATIO: f64 = 35.0;
/// Front-end Maxon encoder on the jaw, counts per revolution.
pub const JAW_COUNTS_PER_REV: f64 = 4000.0;
/// Futek torque sensors (input and distal), N·m per count.
pub const FUTEK_NM_PER_COUNT: f64 = 0.000_039_811;

/// Columns of an imported MRDLab log, in order.
pub const MRDLAB_COLUMNS: [&str; 8] = [
    "t_s",
    "phi_rad",
    "spindle_rad",
    "i_meas_a",
    "cmd",
    "tau_in_nm",
    "theta_rad",
    "tau_ext_nm",
];

/// Fields on a raw MRDLab data line.
pub const RAW_FIELDS: usize = 10;

/// Names of the raw columns, as error messages give them.
const RAW_NAMES: [&str; RAW_FIELDS] = [
    "1: time",
    "2: spindle encoder",
    "3: input torque",
    "4: motor current",
    "5: jaw encoder",
    "6: jaw torque",
    "7: front-end command",
    "8: back-end command",
    "9: motor encoder",
    "10: trajectory target",
];

/// The schema an imported MRDLab log satisfies: every column of
/// [`MRDLAB_COLUMNS`] required, [`DEFAULT_MIN_ROWS`], `t_s` increasing. Pass
/// it to [`Log::read_with`] to read back a converted run.
pub fn mrdlab_schema() -> Schema {
    Schema::with_required(&MRDLAB_COLUMNS)
}

/// What the run's file name and `%` header say about it. The header was
/// partly edited by hand during collection; the data take precedence.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct MrdlabMeta {
    /// File name as given.
    pub source: String,
    /// `X` of the file name `XY.TXT`: selects the input frequency.
    pub freq_index: Option<u8>,
    /// `Y` of the file name `XY.TXT`: selects the resistive torque level.
    pub torque_index: Option<u8>,
    /// Input sine frequency from the header, Hz.
    pub freq_hz: Option<f64>,
    /// Input sine amplitude from the header, degrees.
    pub amplitude_deg: Option<f64>,
    /// Resistive torque level from the header, percent.
    pub torque_percent: Option<f64>,
    /// Header lines, without the leading `%`.
    pub header: Vec<String>,
}

impl fmt::Display for MrdlabMeta {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.freq_hz {
            Some(v) => write!(f, "{v} Hz")?,
            None => write!(f, "? Hz")?,
        }
        if let Some(a) = self.amplitude_deg {
            write!(f, " ±{a}°")?;
        }
        match self.torque_percent {
            Some(v) => write!(f, ", {v} % torque"),
            None => write!(f, ", ? % torque"),
        }
    }
}

/// An imported run: the log and what is known about the run.
#[derive(Debug, Clone, PartialEq)]
pub struct MrdlabRun {
    /// The run in the project's units, columns [`MRDLAB_COLUMNS`].
    pub log: Log,
    /// File name and header information.
    pub meta: MrdlabMeta,
    /// The first data line's raw fields: the encoders' counts before the
    /// angles were rebased to the first sample.
    pub first_raw: [f64; RAW_FIELDS],
}

/// Zero of the angles of an imported MRDLab run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MrdlabZero {
    /// The encoders' own zero, common to all runs (default): the jaw angle
    /// from the jaw encoder's count, the spindle angle from the homing target
    /// (raw column 10 at the first sample).
    #[default]
    Encoder,
    /// Each run's first sample, as [`import_mrdlab`] gives them.
    FirstSample,
}

impl MrdlabRun {
    /// Put the jaw and spindle angles on `zero` (the import gives them on
    /// the first sample).
    ///
    /// Why [`MrdlabZero::Encoder`]: the jaw and spindle encoders were not
    /// reset between runs: every run starts with the spindle homed to the
    /// same count (within 3 of 8192) while the jaw rests up to 20 of 4000
    /// counts (1.8°) apart, the state the transmission's hysteresis was left
    /// in. Rebased, each run would carry its own offset of up to 1.8° that no
    /// input-side signal can explain.
    ///
    /// # Errors
    /// The log lacks `theta_rad` or `spindle_rad`.
    pub fn set_zero(&mut self, zero: MrdlabZero) -> Result<(), LogError> {
        if zero == MrdlabZero::FirstSample {
            return Ok(());
        }
        use std::f64::consts::TAU;
        let first = &self.first_raw;
        let jaw0 = first[4] * TAU / JAW_COUNTS_PER_REV;
        // The importer gives (first - raw) for the spindle (sign flipped)
        // and (raw - first) for the jaw.
        let spindle0 = (first[9] - first[1]) * TAU / SPINDLE_COUNTS_PER_REV;
        for (col, d) in [("theta_rad", jaw0), ("spindle_rad", spindle0)] {
            let v: Vec<f64> = self.log.col_required(col)?.iter().map(|x| x + d).collect();
            self.log.set_col(col, v)?;
        }
        Ok(())
    }
}

/// Whether `path` names a raw MRDLab run (`.TXT`, `.TXT.gz`, any case).
pub fn is_mrdlab_path(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    name.strip_suffix(".gz").unwrap_or(&name).ends_with(".txt")
}

/// Imports one MRDLab run (`.TXT`, or `.TXT.gz` gunzipped) as a log with the
/// columns [`MRDLAB_COLUMNS`].
///
/// # Errors
/// The file cannot be read, or a data line is not 10 finite numbers, time
/// does not increase, or there are fewer than [`DEFAULT_MIN_ROWS`] rows: one
/// error naming the file, the line and the raw column.
pub fn import_mrdlab(path: impl AsRef<Path>) -> Result<Log, LogError> {
    import_mrdlab_run(path).map(|run| run.log)
}

/// As [`import_mrdlab`], also returning the run's metadata.
///
/// # Errors
/// As [`import_mrdlab`].
pub fn import_mrdlab_run(path: impl AsRef<Path>) -> Result<MrdlabRun, LogError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    crate::output::note_input(path);
    let file =
        std::fs::File::open(path).map_err(|e| LogError::new(name.as_str(), LogErrorKind::Io(e)))?;
    let gz = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    if gz {
        read_mrdlab(flate2::read::MultiGzDecoder::new(file), &name)
    } else {
        read_mrdlab(file, &name)
    }
}

/// Imports an MRDLab run from a reader (already decompressed). `name` is
/// used in messages and, if its file name has the form `XY.TXT...`, for
/// [`MrdlabMeta::freq_index`] and [`MrdlabMeta::torque_index`].
///
/// One pass over the lines (header comments, data, blank lines), each check
/// next to the error it names; split, it would pass the line state around.
///
/// # Errors
/// As [`import_mrdlab`].
pub fn read_mrdlab(reader: impl Read, name: &str) -> Result<MrdlabRun, LogError> {
    let mut meta = meta_from_name(name);
    let mut reader = BufReader::new(reader);
    let mut buf = String::new();
    let mut line_no = 0usize;
    let mut raw: Vec<[f64; RAW_FIELDS]> = Vec::with_capacity(20_000);
    // 1-based line of each raw row, for messages about converted values.
    let mut lines: Vec<usize> = Vec::with_capacity(20_000);
    let mut blank_lines: Vec<usize> = Vec::new();
    let err = |line: usize, col: usize, kind: LogErrorKind| {
        LogError::new(name, kind)
            .at_line(line)
            .in_column(RAW_NAMES[col])
    };
    loop {
        buf.clear();
        let n = reader
            .read_line(&mut buf)
            .map_err(|e| LogError::new(name, LogErrorKind::Io(e)).at_line(line_no + 1))?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let text = buf.trim_end_matches(['\n', '\r']);
        if let Some(h) = text.strip_prefix('%') {
            meta.header.push(h.to_owned());
            continue;
        }
        if text.trim().is_empty() {
            // Ignored at the end of the file, an error before a data line.
            blank_lines.push(line_no);
            continue;
        }
        if let Some(&blank) = blank_lines.first() {
            return Err(err(
                blank,
                0,
                LogErrorKind::TooFewFields {
                    found: 0,
                    expected: RAW_FIELDS,
                },
            ));
        }
        let mut row = [0.0; RAW_FIELDS];
        let mut count = 0usize;
        for field in text.split(',') {
            if count == RAW_FIELDS {
                count += 1;
                break;
            }
            let cell = field.trim();
            row[count] = match cell.parse::<f64>() {
                Ok(v) if v.is_finite() => v,
                Ok(_) => {
                    return Err(err(
                        line_no,
                        count,
                        LogErrorKind::NotFinite(cell.to_owned()),
                    ))
                }
                Err(_) => {
                    return Err(err(
                        line_no,
                        count,
                        LogErrorKind::NotANumber(cell.to_owned()),
                    ))
                }
            };
            count += 1;
        }
        if count < RAW_FIELDS {
            return Err(err(
                line_no,
                count,
                LogErrorKind::TooFewFields {
                    found: count,
                    expected: RAW_FIELDS,
                },
            ));
        }
        if count > RAW_FIELDS {
            return Err(err(
                line_no,
                RAW_FIELDS - 1,
                LogErrorKind::TooManyFields {
                    found: text.split(',').count(),
                    expected: RAW_FIELDS,
                },
            ));
        }
        if let Some(prev) = raw.last() {
            if row[0] <= prev[0] {
                return Err(err(
                    line_no,
                    0,
                    LogErrorKind::NonIncreasingTime {
                        prev_s: prev[0],
                        this_s: row[0],
                    },
                ));
            }
        }
        raw.push(row);
        lines.push(line_no);
    }
    if raw.len() < DEFAULT_MIN_ROWS {
        return Err(LogError::new(
            name,
            LogErrorKind::TooFewRows {
                rows: raw.len(),
                min: DEFAULT_MIN_ROWS,
            },
        )
        .at_line(line_no.max(1)));
    }
    parse_header(&mut meta);
    let log = convert(&raw).map_err(|(row, col, kind)| err(lines[row], col, kind))?;
    Ok(MrdlabRun {
        log,
        meta,
        first_raw: raw[0],
    })
}

/// Time since the first sample, rounded to the nanosecond so that 1 kHz
/// stamps print short, or unrounded where samples are closer than that.
///
/// # Errors
/// The first row (0-based) whose time is not finite or not after the
/// previous one once rebased (times too large or too close for an `f64`).
fn rebased_time(raw: &[[f64; RAW_FIELDS]]) -> Result<Vec<f64>, (usize, LogErrorKind)> {
    let t0 = raw[0][0];
    let exact: Vec<f64> = raw.iter().map(|r| r[0] - t0).collect();
    let rounded: Vec<f64> = exact.iter().map(|t| (t * 1e9).round() / 1e9).collect();
    let first_bad =
        |t: &[f64]| (0..t.len()).find(|&k| !t[k].is_finite() || (k > 0 && t[k] <= t[k - 1]));
    if first_bad(&rounded).is_none() {
        return Ok(rounded);
    }
    match first_bad(&exact) {
        None => Ok(exact),
        Some(k) if !exact[k].is_finite() => Err((
            k,
            LogErrorKind::NotFinite(format!("{} s after the first sample", exact[k])),
        )),
        Some(k) => Err((
            k,
            LogErrorKind::NonIncreasingTime {
                prev_s: exact[k - 1],
                this_s: exact[k],
            },
        )),
    }
}

/// Raw rows (checked) to the project's columns.
///
/// # Errors
/// A converted value that is not finite or a time that does not increase
/// once rebased: (0-based raw row, raw column, what).
fn convert(raw: &[[f64; RAW_FIELDS]]) -> Result<Log, (usize, usize, LogErrorKind)> {
    use std::f64::consts::TAU;
    let first = raw[0];
    let col = |f: &dyn Fn(&[f64; RAW_FIELDS]) -> f64| raw.iter().map(f).collect::<Vec<f64>>();
    let t_s = rebased_time(raw).map_err(|(row, kind)| (row, 0, kind))?;
    let phi_rad = col(&|r| (r[8] - first[8]) * TAU / MOTOR_COUNTS_PER_REV);
    let spindle_rad = col(&|r| (first[1] - r[1]) * TAU / SPINDLE_COUNTS_PER_REV);
    let i_meas_a = col(&|r| r[3]);
    // `0.0 - x` rather than `-x`: a zero stays +0 and prints as `0`.
    let cmd = col(&|r| 0.0 - r[7]);
    let tau_in_nm = col(&|r| r[2] * FUTEK_NM_PER_COUNT);
    let theta_rad = col(&|r| (r[4] - first[4]) * TAU / JAW_COUNTS_PER_REV);
    let tau_ext_nm = col(&|r| (0.0 - r[5]) * FUTEK_NM_PER_COUNT);
    let mut log = Log::new();
    // Raw column of each converted one, for messages.
    let raw_col = [0, 8, 1, 3, 7, 2, 4, 5];
    for ((name, values), rc) in MRDLAB_COLUMNS
        .iter()
        .zip([
            t_s,
            phi_rad,
            spindle_rad,
            i_meas_a,
            cmd,
            tau_in_nm,
            theta_rad,
            tau_ext_nm,
        ])
        .zip(raw_col)
    {
        // Finite raw counts can still overflow once rebased and scaled.
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err((
                k,
                rc,
                LogErrorKind::NotFinite(format!("{} once converted to {name}", values[k])),
            ));
        }
        log.set_col(name, values).map_err(|e| {
            (
                0,
                rc,
                LogErrorKind::Io(std::io::Error::other(e.to_string())),
            )
        })?;
    }
    Ok(log)
}

/// `XY` from a file name such as `.../22.TXT.gz`.
fn meta_from_name(name: &str) -> MrdlabMeta {
    let file = Path::new(name)
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = file.split('.').next().unwrap_or("");
    let digits: Vec<u8> = stem
        .bytes()
        .filter(u8::is_ascii_digit)
        .map(|b| b - b'0')
        .collect();
    let (freq_index, torque_index) = if stem.len() == 2 && digits.len() == 2 {
        (Some(digits[0]), Some(digits[1]))
    } else {
        (None, None)
    };
    MrdlabMeta {
        source: name.to_owned(),
        freq_index,
        torque_index,
        ..MrdlabMeta::default()
    }
}

/// The number written just before `marker` in `text` (e.g. `0.30` in
/// `"a 0.30 Hz Sine"`).
fn number_before(text: &str, marker: &str) -> Option<f64> {
    let end = text.find(marker)?;
    let head = text[..end].trim_end();
    // The byte after the last character that cannot be part of a number
    // (that character may be several bytes long).
    let start = head
        .char_indices()
        .rev()
        .find(|&(_, c)| !is_number_char(c))
        .map_or(0, |(i, c)| i + c.len_utf8());
    head[start..].parse().ok()
}

fn is_number_char(c: char) -> bool {
    c.is_ascii_digit() || c == '.' || c == '-'
}

/// The number written just after `marker` in `text`.
fn number_after(text: &str, marker: &str) -> Option<f64> {
    let start = text.find(marker)? + marker.len();
    let tail = text[start..].trim_start();
    let end = tail
        .find(|c: char| !is_number_char(c))
        .unwrap_or(tail.len());
    tail[..end].parse().ok()
}

/// Frequency, amplitude and torque level from the header's prose line.
fn parse_header(meta: &mut MrdlabMeta) {
    for line in &meta.header {
        let lower = line.to_ascii_lowercase();
        if meta.freq_hz.is_none() {
            meta.freq_hz = number_before(&lower, " hz");
        }
        if meta.amplitude_deg.is_none() {
            meta.amplitude_deg = number_after(&lower, "amplitude of");
        }
        if meta.torque_percent.is_none() {
            meta.torque_percent = number_after(&lower, "torque of");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_numbers() {
        let line = "Used left spindle of tool number 5 Lot M10110805 915 with a 0.30 Hz Sine wave \
                    was implemented with and amplitude of 30.00 degrees, and a reaction torque of \
                    60.00 percent torque";
        let mut meta = meta_from_name("/x/25.TXT.gz");
        meta.header.push(line.to_owned());
        parse_header(&mut meta);
        assert_eq!(meta.freq_hz, Some(0.30));
        assert_eq!(meta.amplitude_deg, Some(30.0));
        assert_eq!(meta.torque_percent, Some(60.0));
        assert_eq!((meta.freq_index, meta.torque_index), (Some(2), Some(5)));
        assert_eq!(meta_from_name("run.TXT").freq_index, None);
    }

    #[test]
    fn header_numbers_after_non_ascii_text() {
        assert_eq!(number_before("sine at ≈0.30 hz", " hz"), Some(0.30));
        assert_eq!(number_before("±µ hz", " hz"), None);
        assert_eq!(number_before("é2 hz", " hz"), Some(2.0));
        assert_eq!(number_after("amplitude of ≈30 °", "amplitude of"), None);
        assert_eq!(number_after("amplitude of 30°", "amplitude of"), Some(30.0));
    }

    #[test]
    fn sub_nanosecond_times_are_kept_unrounded() {
        let mut raw = vec![[0.0; RAW_FIELDS]; 4];
        for (k, r) in raw.iter_mut().enumerate() {
            r[0] = 1.0 + k as f64 * 1e-10;
        }
        let t = rebased_time(&raw).unwrap();
        assert!(t.windows(2).all(|w| w[1] > w[0]), "{t:?}");
        raw[0][0] = -f64::MAX;
        raw[1][0] = f64::MAX;
        let (row, kind) = rebased_time(&raw).unwrap_err();
        assert_eq!(row, 1);
        assert!(matches!(kind, LogErrorKind::NotFinite(_)), "{kind:?}");
    }
}
