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

use std::fmt;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::Path;

use crate::output::{OutputError, Outputs};

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

/// What went wrong; see [`LogError`] for where.
#[derive(Debug)]
#[non_exhaustive]
pub enum LogErrorKind {
    /// Reading or writing the file failed.
    Io(io::Error),
    /// The file has no header line.
    EmptyFile,
    /// A header field is empty, or a name contains a comma, quote or line break.
    BadName,
    /// The same column name appears twice.
    DuplicateColumn,
    /// A required column is absent.
    MissingColumn,
    /// A column asked for does not exist.
    UnknownColumn,
    /// A cell is not a number.
    NotANumber(String),
    /// A cell is NaN or infinite (written as text, or a value about to be written).
    NotFinite(String),
    /// An empty cell ("not measured") in a required column.
    NotMeasured,
    /// A one-column log whose last row is not measured: its CSV would end in
    /// blank lines, which a reader cannot tell from trailing blank lines.
    UnmeasuredLastRow,
    /// Time does not increase strictly from the previous row.
    NonIncreasingTime {
        /// Time on the previous row, s.
        prev_s: f64,
        /// Time on this row, s.
        this_s: f64,
    },
    /// Fewer data rows than the schema's minimum.
    TooFewRows {
        /// Data rows found.
        rows: usize,
        /// Schema minimum.
        min: usize,
    },
    /// A row has fewer fields than the header (the column is the first missing one).
    TooFewFields {
        /// Fields found on the row.
        found: usize,
        /// Fields in the header.
        expected: usize,
    },
    /// A row has more fields than the header (the column is the last one).
    TooManyFields {
        /// Fields found on the row.
        found: usize,
        /// Fields in the header.
        expected: usize,
    },
    /// A column or row given to the log has the wrong length.
    LengthMismatch {
        /// Length the log needs.
        expected: usize,
        /// Length given.
        found: usize,
    },
}

/// One error about one log: where (file, 1-based line, column) and what.
///
/// `Display` gives `file:line: column "name": what`, leaving out the parts
/// that do not apply.
#[derive(Debug)]
pub struct LogError {
    /// File (or stream) name as given by the caller.
    pub file: String,
    /// 1-based line in the file (the header is the first line of a plain log).
    pub line: Option<usize>,
    /// Column name.
    pub column: Option<String>,
    /// What went wrong.
    pub kind: LogErrorKind,
}

impl LogError {
    /// An error of `kind` about `file` (no line, no column yet).
    pub fn new(file: impl Into<String>, kind: LogErrorKind) -> Self {
        Self {
            file: file.into(),
            line: None,
            column: None,
            kind,
        }
    }

    /// The same error at a line.
    #[must_use]
    pub fn at_line(mut self, line: usize) -> Self {
        self.line = Some(line);
        self
    }

    /// The same error about a column.
    #[must_use]
    pub fn in_column(mut self, column: impl Into<String>) -> Self {
        self.column = Some(column.into());
        self
    }

    fn io(file: &str, e: io::Error) -> Self {
        Self::new(file, LogErrorKind::Io(e))
    }
}

/// Most characters of a cell or a column name that a message quotes.
pub const MAX_QUOTED_CHARS: usize = 40;

/// `text` for a message: quoted, cut after [`MAX_QUOTED_CHARS`] characters
/// with an ellipsis and its length, so a huge cell never floods the terminal.
///
/// ```
/// use host_sim::log::quoted;
/// assert_eq!(quoted("abc"), "\"abc\"");
/// assert_eq!(quoted(&"x".repeat(5000)), format!("\"{}…\" (5000 bytes)", "x".repeat(40)));
/// ```
pub fn quoted(text: &str) -> String {
    match text.char_indices().nth(MAX_QUOTED_CHARS) {
        None => format!("{text:?}"),
        Some((cut, _)) => format!("\"{}…\" ({} bytes)", text[..cut].escape_debug(), text.len()),
    }
}

/// Most characters of a TOML error's message, and of the line it quotes,
/// that [`toml_error`] keeps.
pub const MAX_TOML_CHARS: usize = 160;

/// `text` cut after `max` characters, with an ellipsis.
fn cut(text: &str, max: usize) -> String {
    match text.char_indices().nth(max) {
        None => text.to_owned(),
        Some((at, _)) => format!("{}…", &text[..at]),
    }
}

/// Each line of `text` cut after [`MAX_TOML_CHARS`], joined with `; `.
fn cut_lines(text: &str) -> String {
    let lines: Vec<String> = text
        .trim_end()
        .lines()
        .map(|l| cut(l, MAX_TOML_CHARS))
        .collect();
    lines.join("; ")
}

/// A TOML error about `text` as `line L, column C: what (in `the line`)`:
/// the `toml` crate's own message repeats the whole offending line, so a
/// huge value would flood the terminal; here the message and the line are
/// cut after [`MAX_TOML_CHARS`] characters.
///
/// ```
/// use host_sim::log::toml_error;
/// let text = format!("[jae]\nc_pos_rad_m = \"{}\"\n", "9".repeat(100_000));
/// let e = toml::from_str::<cable_joint::Config>(&text).unwrap_err();
/// let msg = toml_error(&text, &e);
/// assert!(msg.starts_with("line 2, column 15: "), "{msg}");
/// assert!(msg.contains("c_pos_rad_m"), "{msg}");
/// assert!(msg.len() < 400, "{msg}");
/// ```
pub fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let Some(before) = e.span().and_then(|s| text.get(..s.start)) else {
        // No place in `text` (an error from a merged `toml::Value`): the
        // message alone, which then names the key.
        return cut_lines(&e.to_string());
    };
    let what = cut_lines(e.message());
    let line = before.matches('\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[start..].chars().count() + 1;
    let source = text[start..].lines().next().unwrap_or("").trim_end();
    format!(
        "line {line}, column {column}: {what} (in `{}`)",
        cut(source, MAX_TOML_CHARS)
    )
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        write!(f, ": ")?;
        if let Some(col) = &self.column {
            write!(f, "column {}: ", quoted(col))?;
        }
        match &self.kind {
            LogErrorKind::Io(e) => write!(f, "{e}"),
            LogErrorKind::EmptyFile => write!(f, "no header line (empty file)"),
            LogErrorKind::BadName => write!(
                f,
                "bad column name (empty, or contains a comma, quote or line break)"
            ),
            LogErrorKind::DuplicateColumn => write!(f, "column name appears twice"),
            LogErrorKind::MissingColumn => write!(f, "required column is missing"),
            LogErrorKind::UnknownColumn => write!(f, "no such column"),
            LogErrorKind::NotANumber(text) => write!(f, "{} is not a number", quoted(text)),
            LogErrorKind::NotFinite(text) => {
                write!(f, "{} is not a finite number", quoted(text))
            }
            LogErrorKind::NotMeasured => {
                write!(f, "empty cell (not measured) in a required column")
            }
            LogErrorKind::UnmeasuredLastRow => write!(
                f,
                "the last row of a one-column log is not measured; as CSV it would be a \
                 blank line, read back as no row at all (drop the row or add a column)"
            ),
            LogErrorKind::NonIncreasingTime { prev_s, this_s } => write!(
                f,
                "time does not increase: {this_s} s after {prev_s} s on the previous row"
            ),
            LogErrorKind::TooFewRows { rows, min } => {
                write!(f, "{rows} data rows, at least {min} needed")
            }
            LogErrorKind::TooFewFields { found, expected } => write!(
                f,
                "row has {found} fields, the header has {expected} (row cut short?)"
            ),
            LogErrorKind::TooManyFields { found, expected } => {
                write!(f, "row has {found} fields, the header has {expected}")
            }
            LogErrorKind::LengthMismatch { expected, found } => {
                write!(f, "length {found}, the log has {expected} rows")
            }
        }
    }
}

/// The I/O error, if any, is part of the message (not a `source`), so that
/// an error chain prints it once.
impl std::error::Error for LogError {}

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

    /// Reads a project log ([`Schema::project`]); `.gz` is gunzipped.
    ///
    /// # Errors
    /// The first problem found, naming file, line and column.
    pub fn read(path: impl AsRef<Path>) -> Result<Self, LogError> {
        Self::read_with(path, &Schema::project())
    }

    /// Reads a log that must satisfy `schema`; `.gz` is gunzipped.
    ///
    /// # Errors
    /// The first problem found, naming file, line and column.
    pub fn read_with(path: impl AsRef<Path>, schema: &Schema) -> Result<Self, LogError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let file = File::open(path).map_err(|e| LogError::io(&name, e))?;
        if is_gz(path) {
            Self::from_reader(flate2::read::MultiGzDecoder::new(file), &name, schema)
        } else {
            Self::from_reader(file, &name, schema)
        }
    }

    /// Reads a log from any reader; `name` is used in error messages.
    ///
    /// # Errors
    /// The first problem found, naming `name`, line and column.
    pub fn from_reader(reader: impl Read, name: &str, schema: &Schema) -> Result<Self, LogError> {
        // The `csv` crate splits the records (quoted fields, CRLF, a BOM);
        // cells are trimmed and checked here.
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .from_reader(MarkLineEnds::new(reader));
        let mut rec = csv::StringRecord::new();
        let read = |rdr: &mut csv::Reader<_>, rec: &mut csv::StringRecord, next_line: usize| {
            let more = rdr
                .read_record(rec)
                .map_err(|e| csv_error(name, e, next_line))?;
            let line = rec.position().map_or(next_line, |p| p.line() as usize);
            // A cell spanning lines would shift every later line number.
            if more && rec.iter().any(|f| f.contains(['\n', '\r'])) {
                let cell = rec.iter().find(|f| f.contains(['\n', '\r'])).unwrap_or("");
                return Err(
                    LogError::new(name, LogErrorKind::NotANumber(cell.to_owned())).at_line(line),
                );
            }
            Ok::<_, LogError>(more.then_some(line))
        };

        // Header: the first line.
        let header_line = read(&mut rdr, &mut rec, 1)?;
        let blank = |rec: &csv::StringRecord| rec.len() == 1 && rec[0].trim().is_empty();
        if header_line != Some(1) || blank(&rec) {
            return Err(LogError::new(name, LogErrorKind::EmptyFile).at_line(1));
        }
        let mut log = Self::new();
        for (i, field) in rec.iter().enumerate() {
            let field = if i == 0 {
                field.strip_prefix('\u{feff}').unwrap_or(field)
            } else {
                field
            };
            let field = field.trim();
            if !check_name(field) {
                return Err(LogError::new(name, LogErrorKind::BadName)
                    .at_line(1)
                    .in_column(field));
            }
            if log.has(field) {
                return Err(LogError::new(name, LogErrorKind::DuplicateColumn)
                    .at_line(1)
                    .in_column(field));
            }
            log.cols.push(Column {
                name: field.to_owned(),
                values: Vec::new(),
                measured: None,
            });
        }
        // Required columns are checked before the data so that a wrong file
        // is reported at its header, not at some cell.
        for req in &schema.required {
            if !log.has(req) {
                return Err(LogError::new(name, LogErrorKind::MissingColumn)
                    .at_line(1)
                    .in_column(req.as_str()));
            }
        }
        let required: Vec<bool> = log
            .cols
            .iter()
            .map(|c| schema.required.contains(&c.name))
            .collect();

        let time_col = schema.time_column.as_deref().and_then(|t| log.index(t));
        let mut prev_t: Option<f64> = None;
        let mut check_time = |log: &Self, line: usize| -> Result<(), LogError> {
            let Some(i) = time_col else { return Ok(()) };
            let col = &log.cols[i];
            let row = log.rows - 1;
            if !col.is_measured(row) {
                return Ok(());
            }
            let t = col.values[row];
            if let Some(p) = prev_t {
                if t <= p {
                    return Err(LogError::new(
                        name,
                        LogErrorKind::NonIncreasingTime {
                            prev_s: p,
                            this_s: t,
                        },
                    )
                    .at_line(line)
                    .in_column(col.name.as_str()));
                }
            }
            prev_t = Some(t);
            Ok(())
        };

        // Data. Blank lines are kept pending: at the end of the file they are
        // ignored, before another row they are rows (of one empty cell), so
        // data row `k` (0-based) is always on line `k + 2`.
        let mut pending_blank: Vec<usize> = Vec::new();
        let mut next_line = 2usize;
        let blank_row = csv::StringRecord::from(vec![""]);
        while let Some(line) = read(&mut rdr, &mut rec, next_line)? {
            next_line = line + 1;
            if blank(&rec) {
                pending_blank.push(line);
                continue;
            }
            for blank_line in std::mem::take(&mut pending_blank) {
                log.parse_row(name, blank_line, &blank_row, &required)?;
                check_time(&log, blank_line)?;
            }
            log.parse_row(name, line, &rec, &required)?;
            check_time(&log, line)?;
        }
        log.validate_at(schema, name, line_of_row, 1)?;
        Ok(log)
    }

    fn parse_row(
        &mut self,
        file: &str,
        line: usize,
        fields: &csv::StringRecord,
        required: &[bool],
    ) -> Result<(), LogError> {
        let ncols = self.cols.len();
        if fields.len() == 1 && fields[0].trim().is_empty() && ncols > 1 {
            return Err(LogError::new(
                file,
                LogErrorKind::TooFewFields {
                    found: 0,
                    expected: ncols,
                },
            )
            .at_line(line)
            .in_column(self.cols[0].name.as_str()));
        }
        let mut count = 0usize;
        let mut parsed: Vec<Option<f64>> = Vec::with_capacity(ncols);
        for field in fields {
            count += 1;
            if count > ncols {
                continue;
            }
            let col = count - 1;
            let cell = field.trim();
            if cell.is_empty() {
                if required[col] {
                    return Err(LogError::new(file, LogErrorKind::NotMeasured)
                        .at_line(line)
                        .in_column(self.cols[col].name.as_str()));
                }
                parsed.push(None);
                continue;
            }
            match cell.parse::<f64>() {
                Ok(v) if v.is_finite() => parsed.push(Some(v)),
                Ok(_) => {
                    return Err(
                        LogError::new(file, LogErrorKind::NotFinite(cell.to_owned()))
                            .at_line(line)
                            .in_column(self.cols[col].name.as_str()),
                    )
                }
                Err(_) => {
                    return Err(
                        LogError::new(file, LogErrorKind::NotANumber(cell.to_owned()))
                            .at_line(line)
                            .in_column(self.cols[col].name.as_str()),
                    )
                }
            }
        }
        if count < ncols {
            return Err(LogError::new(
                file,
                LogErrorKind::TooFewFields {
                    found: count,
                    expected: ncols,
                },
            )
            .at_line(line)
            .in_column(self.cols[count].name.as_str()));
        }
        if count > ncols {
            return Err(LogError::new(
                file,
                LogErrorKind::TooManyFields {
                    found: count,
                    expected: ncols,
                },
            )
            .at_line(line)
            .in_column(self.cols[ncols - 1].name.as_str()));
        }
        for (c, v) in self.cols.iter_mut().zip(parsed) {
            c.push(v);
        }
        self.rows += 1;
        Ok(())
    }

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

/// A reader that ends every line with a space and a bare `\n`. The `csv`
/// crate skips empty lines and, after a CRLF, numbers the next record from
/// the line before; with every line break a plain ` \n`, a blank line is a
/// record of one blank cell (cells are trimmed), so blank lines keep their
/// meaning (see [`Log::read`]) and every record's line number is its
/// line's. A carriage return not followed by `\n` is kept (after a space).
struct MarkLineEnds<R> {
    inner: R,
    buf: Vec<u8>,
    pos: usize,
    /// A carriage return was read and not yet written.
    pending_cr: bool,
    done: bool,
}

impl<R> MarkLineEnds<R> {
    fn new(inner: R) -> Self {
        Self {
            inner,
            buf: Vec::new(),
            pos: 0,
            pending_cr: false,
            done: false,
        }
    }
}

impl<R: Read> Read for MarkLineEnds<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        while self.pos == self.buf.len() && !self.done {
            let mut raw = [0u8; 8192];
            let n = self.inner.read(&mut raw)?;
            self.buf.clear();
            self.pos = 0;
            if n == 0 {
                self.done = true;
                if std::mem::take(&mut self.pending_cr) {
                    self.buf.extend_from_slice(b" \r");
                }
            }
            for &b in &raw[..n] {
                if std::mem::take(&mut self.pending_cr) && b != b'\n' {
                    self.buf.extend_from_slice(b" \r");
                }
                match b {
                    b'\r' => self.pending_cr = true,
                    b'\n' => self.buf.extend_from_slice(b" \n"),
                    _ => self.buf.push(b),
                }
            }
        }
        let k = out.len().min(self.buf.len() - self.pos);
        out[..k].copy_from_slice(&self.buf[self.pos..self.pos + k]);
        self.pos += k;
        Ok(k)
    }
}

/// A reading error of the `csv` crate as the log's error: I/O or text that
/// is not UTF-8, at the line it was found on.
fn csv_error(name: &str, e: csv::Error, next_line: usize) -> LogError {
    let line = e.position().map_or(next_line, |p| p.line() as usize);
    let kind = match e.into_kind() {
        csv::ErrorKind::Io(io) => LogErrorKind::Io(io),
        other => LogErrorKind::Io(io::Error::new(
            io::ErrorKind::InvalidData,
            match other {
                csv::ErrorKind::Utf8 { .. } => "stream did not contain valid UTF-8".to_owned(),
                other => format!("{other:?}"),
            },
        )),
    };
    LogError::new(name, kind).at_line(line)
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

    #[test]
    fn names_are_checked() {
        assert!(check_name("x2_m"));
        assert!(!check_name(""));
        assert!(!check_name("a,b"));
        assert!(!check_name(" a"));
        assert!(!check_name("\"a\""));
    }
}
