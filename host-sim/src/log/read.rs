//! Reading a log: the `csv` crate splits the records, cells are checked
//! here, every error names the file, the line and the column.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

use super::{check_name, is_gz, line_of_row, Column, Log, LogError, LogErrorKind, Schema};

impl Log {
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
        crate::output::note_input(path);
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
            let spanning = rec.iter().find(|f| f.contains(['\n', '\r']));
            if let Some(cell) = spanning.filter(|_| more) {
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
        // One header field holding another separator, and a required
        // column missing: a semicolon- or tab-separated file (a
        // spreadsheet's export in some locales), which reads as one column.
        // (A one-column log may be named so; only a missing column says
        // the file is not one.)
        let separator = (rec.len() == 1)
            .then(|| [';', '\t'].into_iter().find(|c| rec[0].contains(*c)))
            .flatten();
        // Required columns are checked before the data so that a wrong file
        // is reported at its header, not at some cell.
        for req in &schema.required {
            if !log.has(req) {
                if let Some(sep) = separator {
                    return Err(
                        LogError::new(name, LogErrorKind::NotCommaSeparated(sep)).at_line(1)
                    );
                }
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
