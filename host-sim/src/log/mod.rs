//! The project's CSV log (DESIGN.md §2): one header row of column names that
//! carry their unit (`t_s`, `x2_m`, `phi_rad`, ...), then one row per control
//! tick. Extra columns are kept, in order; an empty cell means "not measured".
//!
//! * [`Log`] is columnar: `log.col("x2_m")` gives a `&[f64]`.
//! * [`Log::read`] validates against a [`Schema`] (required columns, minimum
//!   row count, strictly increasing time) and stops at the first bad cell
//!   with one [`LogError`] naming the file, the 1-based line and the column:
//!   `run.csv:17: column "x2_m": "abc" is not a number`.
//! * [`Log::write`] refuses a log with a NaN or infinite value before it
//!   touches the file system, then writes a temporary file in the target's
//!   directory and renames it over the target: a failed write leaves the old
//!   file as it was.
//! * A path ending in `.gz` is gunzipped on reading and gzipped on writing.
//! * Records are split and written by the `csv` crate: quoted cells and
//!   names (a spreadsheet's export), a BOM and CRLF line ends are read as
//!   the plain file; cells are trimmed.
//!
//! Numbers are written in Rust's shortest round-trip form, so a log read back
//! is bit-identical to the one written.

use std::path::Path;

/// Columns every project log must have (DESIGN.md §2).
pub const REQUIRED_COLUMNS: [&str; 5] = ["t_s", "x1_m", "x2_m", "phi_rad", "i_ref_a"];

/// The time column, checked for strictly increasing values.
pub const TIME_COLUMN: &str = "t_s";

/// Fewest data rows [`Schema::project`] accepts.
pub const DEFAULT_MIN_ROWS: usize = 10;

/// What a log must contain to be accepted by [`Log::read_with`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Schema {
    /// Columns that must be present and fully measured (no empty cell).
    pub required: Vec<String>,
    /// Fewest data rows accepted.
    pub min_rows: usize,
    /// Column that must be strictly increasing, if present (`None`: no check).
    pub time_column: Option<String>,
}

impl Schema {
    /// The project's log schema: [`REQUIRED_COLUMNS`], at least
    /// [`DEFAULT_MIN_ROWS`] rows, `t_s` strictly increasing.
    pub fn project() -> Self {
        Self::with_required(&REQUIRED_COLUMNS)
    }

    /// A schema with other required columns (e.g. an imported data set),
    /// [`DEFAULT_MIN_ROWS`] rows and `t_s` strictly increasing when present.
    pub fn with_required(required: &[&str]) -> Self {
        Self {
            required: required.iter().map(|s| (*s).to_owned()).collect(),
            min_rows: DEFAULT_MIN_ROWS,
            time_column: Some(TIME_COLUMN.to_owned()),
        }
    }

    /// Any well-formed CSV of finite numbers: nothing required, no row
    /// minimum, `t_s` still checked when present.
    pub fn any() -> Self {
        Self::with_required(&[]).min_rows(0)
    }

    /// The same schema with another row minimum.
    #[must_use]
    pub fn min_rows(mut self, min_rows: usize) -> Self {
        self.min_rows = min_rows;
        self
    }

    /// The same schema with another (or no) time column.
    #[must_use]
    pub fn time_column(mut self, name: Option<&str>) -> Self {
        self.time_column = name.map(str::to_owned);
        self
    }
}

impl Default for Schema {
    fn default() -> Self {
        Self::project()
    }
}

mod error;
mod read;
mod write;

pub use error::{
    quoted, toml_error, value_text, LogError, LogErrorKind, MAX_QUOTED_CHARS, MAX_TOML_CHARS,
};

/// One column: values (NaN where not measured) and, if any cell is not
/// measured, the mask of measured cells.
#[derive(Debug, Clone)]
struct Column {
    name: String,
    values: Vec<f64>,
    /// `None`: every cell measured.
    measured: Option<Vec<bool>>,
}

/// Equal names and, cell by cell, both not measured or both measured with
/// equal values (so the NaN of a missing cell does not make a column unequal
/// to itself).
impl PartialEq for Column {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
            && self.values.len() == other.values.len()
            && (0..self.values.len()).all(|r| match (self.is_measured(r), other.is_measured(r)) {
                (true, true) => self.values[r] == other.values[r],
                (false, false) => true,
                _ => false,
            })
    }
}

impl Column {
    fn is_measured(&self, row: usize) -> bool {
        self.measured.as_ref().is_none_or(|m| m[row])
    }

    fn push(&mut self, value: Option<f64>) {
        match value {
            Some(v) => {
                self.values.push(v);
                if let Some(m) = &mut self.measured {
                    m.push(true);
                }
            }
            None => {
                let n = self.values.len();
                self.values.push(f64::NAN);
                self.measured
                    .get_or_insert_with(|| vec![true; n])
                    .push(false);
            }
        }
    }

    fn from_options(name: &str, values: &[Option<f64>]) -> Self {
        let mut col = Self {
            name: name.to_owned(),
            values: Vec::with_capacity(values.len()),
            measured: None,
        };
        for v in values {
            col.push(*v);
        }
        col
    }
}

/// A columnar log: ordered, uniquely named columns of equal length.
///
/// Cells that are "not measured" read as NaN through [`Log::col`]; use
/// [`Log::col_opt`] or [`Log::is_measured`] to tell them apart, and
/// [`Log::col_required`] to insist on a fully measured column.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Log {
    cols: Vec<Column>,
    rows: usize,
}

fn check_name(name: &str) -> bool {
    !name.is_empty() && name.trim() == name && !name.contains([',', '"', '\n', '\r'])
}

fn is_gz(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"))
}

impl Log {
    /// An empty log (no column, no row).
    pub fn new() -> Self {
        Self::default()
    }

    /// A log with these columns and no row.
    ///
    /// # Errors
    /// A bad or repeated name.
    pub fn with_columns(names: &[&str]) -> Result<Self, LogError> {
        let mut log = Self::new();
        for name in names {
            log.set_col(name, Vec::new())?;
        }
        Ok(log)
    }

    /// The rows `range` of every column, as a log of their own.
    ///
    /// # Panics
    /// If `range` reaches past the last row.
    pub fn rows(&self, range: std::ops::Range<usize>) -> Log {
        let mut out = Log::new();
        for name in self.names() {
            let col = self.col_opt(name).unwrap_or_default();
            out.set_col_opt(name, &col[range.clone()])
                .expect("the names of a log are valid and distinct");
        }
        out
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows
    }

    /// No row.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// Column names, in file order.
    pub fn names(&self) -> Vec<&str> {
        self.cols.iter().map(|c| c.name.as_str()).collect()
    }

    /// Whether the log has this column.
    pub fn has(&self, name: &str) -> bool {
        self.index(name).is_some()
    }

    fn index(&self, name: &str) -> Option<usize> {
        self.cols.iter().position(|c| c.name == name)
    }

    /// Values of a column (NaN where not measured), `None` if absent.
    pub fn col(&self, name: &str) -> Option<&[f64]> {
        self.index(name).map(|i| self.cols[i].values.as_slice())
    }

    /// Values of a column that must exist and be measured on every row.
    ///
    /// # Errors
    /// [`LogErrorKind::UnknownColumn`], or [`LogErrorKind::NotMeasured`] with
    /// the 0-based row in the message's line field left empty (the log may
    /// not come from a file).
    pub fn col_required(&self, name: &str) -> Result<&[f64], LogError> {
        let i = self
            .index(name)
            .ok_or_else(|| LogError::new("log", LogErrorKind::UnknownColumn).in_column(name))?;
        let col = &self.cols[i];
        if col.measured.as_ref().is_some_and(|m| m.contains(&false)) {
            return Err(LogError::new("log", LogErrorKind::NotMeasured).in_column(name));
        }
        Ok(&col.values)
    }

    /// A column with "not measured" cells as `None`; `None` if absent.
    pub fn col_opt(&self, name: &str) -> Option<Vec<Option<f64>>> {
        let col = &self.cols[self.index(name)?];
        Some(
            (0..self.rows)
                .map(|r| col.is_measured(r).then(|| col.values[r]))
                .collect(),
        )
    }

    /// Whether a cell holds a measurement (`false` if the column is absent
    /// or the row out of range).
    pub fn is_measured(&self, name: &str, row: usize) -> bool {
        row < self.rows
            && self
                .index(name)
                .is_some_and(|i| self.cols[i].is_measured(row))
    }

    /// The time column `t_s`.
    ///
    /// # Errors
    /// As [`Log::col_required`].
    pub fn time_s(&self) -> Result<&[f64], LogError> {
        self.col_required(TIME_COLUMN)
    }

    /// Appends a row of measured values, one per column in order.
    ///
    /// # Errors
    /// [`LogErrorKind::LengthMismatch`] if the row length differs from the
    /// number of columns (nothing appended).
    pub fn push_row(&mut self, row: &[f64]) -> Result<(), LogError> {
        self.check_row_len(row.len())?;
        for (col, v) in self.cols.iter_mut().zip(row) {
            col.push(Some(*v));
        }
        self.rows += 1;
        Ok(())
    }

    /// Appends a row in which `None` means "not measured".
    ///
    /// # Errors
    /// As [`Log::push_row`].
    pub fn push_row_opt(&mut self, row: &[Option<f64>]) -> Result<(), LogError> {
        self.check_row_len(row.len())?;
        for (col, v) in self.cols.iter_mut().zip(row) {
            col.push(*v);
        }
        self.rows += 1;
        Ok(())
    }

    fn check_row_len(&self, found: usize) -> Result<(), LogError> {
        if found == self.cols.len() {
            Ok(())
        } else {
            Err(LogError::new(
                "log",
                LogErrorKind::LengthMismatch {
                    expected: self.cols.len(),
                    found,
                },
            ))
        }
    }

    /// Adds a fully measured column at the end, or replaces the values of an
    /// existing one in place. The first column of an empty log sets the
    /// number of rows.
    ///
    /// # Errors
    /// A bad name, or a length other than [`Log::len`].
    pub fn set_col(&mut self, name: &str, values: Vec<f64>) -> Result<(), LogError> {
        self.set_column(Column {
            name: name.to_owned(),
            values,
            measured: None,
        })
    }

    /// As [`Log::set_col`], with `None` meaning "not measured".
    ///
    /// # Errors
    /// As [`Log::set_col`].
    pub fn set_col_opt(&mut self, name: &str, values: &[Option<f64>]) -> Result<(), LogError> {
        self.set_column(Column::from_options(name, values))
    }

    fn set_column(&mut self, col: Column) -> Result<(), LogError> {
        if !check_name(&col.name) {
            return Err(LogError::new("log", LogErrorKind::BadName).in_column(col.name));
        }
        if self.cols.is_empty() {
            self.rows = col.values.len();
        } else if col.values.len() != self.rows {
            return Err(LogError::new(
                "log",
                LogErrorKind::LengthMismatch {
                    expected: self.rows,
                    found: col.values.len(),
                },
            )
            .in_column(col.name));
        }
        match self.index(&col.name) {
            Some(i) => self.cols[i] = col,
            None => self.cols.push(col),
        }
        Ok(())
    }

    /// Removes a column and returns its values (NaN where not measured).
    pub fn remove_col(&mut self, name: &str) -> Option<Vec<f64>> {
        let i = self.index(name)?;
        let col = self.cols.remove(i);
        if self.cols.is_empty() {
            self.rows = 0;
        }
        Some(col.values)
    }

    /// Checks the log against a schema: required columns present and fully
    /// measured, enough rows, time strictly increasing. Lines in the error
    /// are those the log would have when written (header = line 1).
    ///
    /// # Errors
    /// The first violation found.
    pub fn validate(&self, schema: &Schema, file: &str) -> Result<(), LogError> {
        self.validate_at(schema, file, line_of_row, 1)
    }

    /// `line_of(row)` maps a 0-based row to its file line; `header_line` is
    /// the header's line.
    fn validate_at(
        &self,
        schema: &Schema,
        file: &str,
        line_of: impl Fn(usize) -> usize,
        header_line: usize,
    ) -> Result<(), LogError> {
        for name in &schema.required {
            let Some(i) = self.index(name) else {
                return Err(LogError::new(file, LogErrorKind::MissingColumn)
                    .at_line(header_line)
                    .in_column(name.as_str()));
            };
            if let Some(m) = &self.cols[i].measured {
                if let Some(row) = m.iter().position(|x| !x) {
                    return Err(LogError::new(file, LogErrorKind::NotMeasured)
                        .at_line(line_of(row))
                        .in_column(name.as_str()));
                }
            }
        }
        if let Some(tname) = &schema.time_column {
            if let Some(i) = self.index(tname) {
                let col = &self.cols[i];
                let mut prev: Option<f64> = None;
                for (row, &t) in col.values.iter().enumerate() {
                    if !col.is_measured(row) {
                        continue;
                    }
                    if let Some(p) = prev {
                        // `partial_cmp` so that a NaN also fails.
                        if t.partial_cmp(&p) != Some(std::cmp::Ordering::Greater) {
                            return Err(LogError::new(
                                file,
                                LogErrorKind::NonIncreasingTime {
                                    prev_s: p,
                                    this_s: t,
                                },
                            )
                            .at_line(line_of(row))
                            .in_column(tname.as_str()));
                        }
                    }
                    prev = Some(t);
                }
            }
        }
        if self.rows < schema.min_rows {
            let last_line = if self.rows == 0 {
                header_line
            } else {
                line_of(self.rows - 1)
            };
            return Err(LogError::new(
                file,
                LogErrorKind::TooFewRows {
                    rows: self.rows,
                    min: schema.min_rows,
                },
            )
            .at_line(last_line));
        }
        Ok(())
    }
}

/// 1-based line of 0-based data row `row` of a log read from a file (the
/// header is line 1; see [`Log::read`] on blank lines).
pub fn line_of_row(row: usize) -> usize {
    row + 2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked() {
        assert!(check_name("x2_m"));
        assert!(!check_name(""));
        assert!(!check_name("a,b"));
        assert!(!check_name(" a"));
        assert!(!check_name("\"a\""));
    }
}
