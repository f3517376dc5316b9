//! Writing a log: checked first, then atomically through
//! [`crate::output`], numbers in their shortest round-trip form.

use std::fmt;
use std::io::{self, Write};
use std::path::Path;

use super::{is_gz, line_of_row, Log, LogError, LogErrorKind};
use crate::output::{OutputError, Outputs};

/// Formats a finite value so that parsing it gives the same bits back.
fn fmt_value(out: &mut String, v: f64) {
    use fmt::Write as _;
    let a = v.abs();
    // `{}` never uses an exponent; switch to `{:e}` for very small or large
    // magnitudes. Both are Rust's shortest round-trip representations.
    if a == 0.0 || (1e-5..1e16).contains(&a) {
        let _ = write!(out, "{v}");
    } else {
        let _ = write!(out, "{v:e}");
    }
}

impl Log {
    /// Checks that the log can be written: at least one column, and every
    /// measured value finite. Lines are those of the file to be written.
    fn check_writable(&self, file: &str) -> Result<(), LogError> {
        if self.cols.is_empty() {
            return Err(LogError::new(file, LogErrorKind::EmptyFile));
        }
        if let ([only], Some(last)) = (self.cols.as_slice(), self.rows.checked_sub(1)) {
            if !only.is_measured(last) {
                return Err(LogError::new(file, LogErrorKind::UnmeasuredLastRow)
                    .at_line(line_of_row(last))
                    .in_column(only.name.as_str()));
            }
        }
        for col in &self.cols {
            for (row, v) in col.values.iter().enumerate() {
                if col.is_measured(row) && !v.is_finite() {
                    return Err(LogError::new(file, LogErrorKind::NotFinite(format!("{v}")))
                        .at_line(line_of_row(row))
                        .in_column(col.name.as_str()));
                }
            }
        }
        Ok(())
    }

    /// Writes the log as CSV to any writer (not atomic; see [`Log::write`]).
    ///
    /// # Errors
    /// A NaN or infinite value (before anything is written), or an I/O error.
    pub fn write_to(&self, w: impl Write, name: &str) -> Result<(), LogError> {
        self.check_writable(name)?;
        self.write_unchecked(w).map_err(|e| LogError::io(name, e))
    }

    fn write_unchecked(&self, w: impl Write) -> io::Result<()> {
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .terminator(csv::Terminator::Any(b'\n'))
            .from_writer(w);
        w.write_record(self.cols.iter().map(|c| c.name.as_str()))?;
        let mut cells = vec![String::new(); self.cols.len()];
        for row in 0..self.rows {
            for (cell, col) in cells.iter_mut().zip(&self.cols) {
                cell.clear();
                if col.is_measured(row) {
                    fmt_value(cell, col.values[row]);
                }
            }
            w.write_record(&cells)?;
        }
        w.flush()
    }

    /// Writes the log atomically through [`crate::output`]: checked first
    /// (nothing is created if a value is NaN or infinite), then written to a
    /// temporary file in the target's directory and renamed over the target.
    /// A path ending in `.gz` is gzipped. A new file gets mode 0644 (Unix); a
    /// replaced file keeps its permissions; a target that is not a regular
    /// file is refused.
    ///
    /// # Errors
    /// A NaN or infinite value, or an I/O error; the target is then untouched
    /// and no temporary file is left behind.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), LogError> {
        let mut out = Outputs::new();
        self.stage(&mut out, path)?;
        out.commit().map_err(output_err)?;
        Ok(())
    }

    /// Stages the log as one of a command's outputs (written with the
    /// others by [`Outputs::commit`], all or none); checked as
    /// [`Log::write`].
    ///
    /// # Errors
    /// As [`Log::write`].
    pub fn stage(&self, out: &mut Outputs, path: impl AsRef<Path>) -> Result<(), LogError> {
        let path = path.as_ref();
        self.check_writable(&path.display().to_string())?;
        let gz = is_gz(path);
        out.with_writer(path, |w| {
            if gz {
                let mut enc = flate2::write::GzEncoder::new(w, flate2::Compression::default());
                self.write_unchecked(&mut enc)?;
                enc.finish().map(drop)
            } else {
                self.write_unchecked(w)
            }
        })
        .map_err(output_err)
    }
}

fn output_err(e: OutputError) -> LogError {
    LogError::new(e.path.display().to_string(), LogErrorKind::Io(e.error))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_format_round_trips() {
        for v in [
            0.0,
            -0.0,
            1.0,
            0.1,
            -2.5e-7,
            1e-300,
            123_456.789,
            1e17,
            f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            std::f64::consts::PI,
        ] {
            let mut s = String::new();
            fmt_value(&mut s, v);
            let back: f64 = s.parse().unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v} -> {s}");
            assert!(s.len() < 30, "{v} printed as {s}");
        }
    }
}
