//! What can go wrong with a log, and where: [`LogError`].

use std::fmt;
use std::io;

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
    /// The header is one field that holds another separator (`;` or a tab)
    /// and a required column is missing: the file is not comma-separated.
    NotCommaSeparated(char),
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

    pub(super) fn io(file: &str, e: io::Error) -> Self {
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

/// A number for a message: as written below a million, in exponent form
/// above (a corrupt cell's 1e300 is not printed with its 301 digits).
///
/// ```
/// use host_sim::log::value_text;
/// assert_eq!(value_text(-6000.0), "-6000");
/// assert_eq!(value_text(1e300), "1e300");
/// ```
pub fn value_text(v: f64) -> String {
    if v.abs() < 1e6 {
        format!("{v}")
    } else {
        format!("{v:e}")
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
            LogErrorKind::NotCommaSeparated(sep) => write!(
                f,
                "the header is one field with {} in it: the file must be comma-separated \
                 (`,` between fields, `.` as the decimal point)",
                if *sep == '\t' {
                    "tabs".to_owned()
                } else {
                    format!("`{sep}`")
                }
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
