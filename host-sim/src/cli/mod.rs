//! The command line: each subcommand's arguments, its run and its printing
//! live in a module here (every subcommand but `report`, which still owns
//! its arguments in [`crate::report`]), and the checks of numeric options
//! below are shared by every subcommand.
//!
//! Each numeric option names its range with one of these parsers
//! (`#[arg(allow_negative_numbers = true, long, value_parser =
//! cli::f64_in(0.0, 1.0))]`), so that `NaN`, `inf` or an out-of-range value,
//! a negative one included, is refused by the argument parser with a
//! message naming the option (without `allow_negative_numbers` clap takes
//! `-0.3` for an unknown flag `-0`):
//!
//! ```text
//! error: invalid value 'NaN' for '--min-gain <MIN_GAIN>': not a finite number
//! ```
//!
//! [`check_f64`] is the same check for a value that does not come from the
//! command line (a library caller filling an argument structure).

pub mod estimate;
pub mod excite;
pub mod identify;
pub mod import;
pub mod ingest;
pub mod link;
pub mod payload;
pub mod pil;
pub mod report;
pub mod residual;
pub mod simulate;
pub mod trace;
pub mod undeclared;
pub mod wrist;

use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// `path` as one word of a POSIX shell command, for the commands a tool
/// prints for its user to run next: as it is where it has only characters
/// a shell leaves alone, else in single quotes (a quote inside as `'\''`).
///
/// ```
/// use std::path::Path;
/// use host_sim::cli::shell_word;
/// assert_eq!(shell_word(Path::new("runs/w1.csv")), "runs/w1.csv");
/// assert_eq!(shell_word(Path::new("my run")), "'my run'");
/// assert_eq!(shell_word(Path::new("it's")), "'it'\\''s'");
/// ```
pub fn shell_word(path: &Path) -> String {
    let text = path.to_string_lossy();
    let plain = |c: char| c.is_ascii_alphanumeric() || "_-./,:=+@%".contains(c);
    if !text.is_empty() && text.chars().all(plain) {
        text.into_owned()
    } else {
        format!("'{}'", text.replace('\'', "'\\''"))
    }
}

/// Why a validation log must not be a fitted one.
const VALIDATION_UNSEEN: &str = "validation needs data the fit did not see";
/// Why a test log must not be a fitted one.
const TEST_UNSEEN: &str = "a test needs data the fit did not see";
/// Why a test log must not be a validation one.
const TEST_UNCHOSEN: &str = "a test needs data that chose no term";

/// Refuses a file given to validate or test that is also fitted, and a
/// test file that also validates: a model scored on data that fitted it
/// or chose its terms says nothing about data it has not seen. One file
/// under two spellings (`./a.csv`, `a.csv`, a link) is the same file; a
/// path that cannot be resolved is compared as written (reading it fails
/// later with its own error). A copy under another name is caught once
/// the logs are read ([`refuse_copies`]).
pub fn refuse_reused_files(
    fit: &[PathBuf],
    validate: &[PathBuf],
    test: &[PathBuf],
) -> anyhow::Result<()> {
    reused(
        fit,
        validate,
        "--validate",
        "a fitted log",
        VALIDATION_UNSEEN,
    )?;
    reused(fit, test, "--test", "a fitted log", TEST_UNSEEN)?;
    reused(validate, test, "--test", "a --validate log", TEST_UNCHOSEN)
}

/// A file of `given` that is also one of `used` (`what`), refused with `why`.
fn reused(
    used: &[PathBuf],
    given: &[PathBuf],
    flag: &str,
    what: &str,
    why: &str,
) -> anyhow::Result<()> {
    let resolved = |p: &Path| -> PathBuf { p.canonicalize().unwrap_or_else(|_| p.to_path_buf()) };
    let used: Vec<PathBuf> = used.iter().map(|p| resolved(p)).collect();
    for g in given {
        if used.contains(&resolved(g)) {
            anyhow::bail!("{flag} {} is also {what}: {why}", g.display());
        }
    }
    Ok(())
}

/// Refuses one run given under two names (a copy, the `.gz` and its
/// unpacked file), which the path checks ([`refuse_reused_files`]) let
/// through: a log fitted twice, a validation log holding a fitted log's
/// data, a test log holding a fitted or validation log's. Logs are `(name,
/// data)`; data are the same when every column is, row for row.
pub fn refuse_copies(
    fit: &[(&str, &crate::log::Log)],
    validate: &[(&str, &crate::log::Log)],
    test: &[(&str, &crate::log::Log)],
) -> anyhow::Result<()> {
    same_data(fit, fit, "--log", "fitted twice, it would weigh double")?;
    same_data(fit, validate, "--validate", VALIDATION_UNSEEN)?;
    same_data(fit, test, "--test", TEST_UNSEEN)?;
    same_data(validate, test, "--test", TEST_UNCHOSEN)
}

/// A log of `given` whose data are those of a log of `used`, or of an
/// earlier log of `given` when `used` is the same list, refused with `why`.
fn same_data(
    used: &[(&str, &crate::log::Log)],
    given: &[(&str, &crate::log::Log)],
    flag: &str,
    why: &str,
) -> anyhow::Result<()> {
    let same_list = std::ptr::eq(used, given);
    for (j, (name, log)) in given.iter().enumerate() {
        let earlier = if same_list { &used[..j] } else { used };
        if let Some((u, _)) = earlier.iter().find(|(_, l)| l == log) {
            anyhow::bail!(
                "{flag} {name} holds the same data as {u} (one run under two names?): {why}"
            );
        }
    }
    Ok(())
}

/// Parses a number and checks it: finite, `>= lo` (or `> lo` when
/// `lo_open`) and `<= hi`.
fn parse_in<T>(text: &str, lo: T, lo_open: bool, hi: T) -> Result<T, String>
where
    T: FromStr + PartialOrd + Copy + Display + Finite,
    T::Err: Display,
{
    let v: T = text.trim().parse().map_err(|e| format!("{e}"))?;
    // The value as the user wrote it (1e300 is not 301 digits), cut if long.
    let shown: String = text.trim().chars().take(40).collect();
    check(v, lo, lo_open, hi, &shown)
}

/// `v` finite and within the range; `shown` is how the message writes it.
fn check<T: PartialOrd + Copy + Display + Finite>(
    v: T,
    lo: T,
    lo_open: bool,
    hi: T,
    shown: &str,
) -> Result<T, String> {
    if !v.finite() {
        return Err("not a finite number".to_owned());
    }
    let above = if lo_open { v > lo } else { v >= lo };
    if above && v <= hi {
        Ok(v)
    } else {
        let open = if lo_open { "(" } else { "[" };
        let hi_text = hi.to_string();
        if hi_text.len() > 16 {
            // An upper end that only keeps the value finite (`f64::MAX`)
            // says nothing in 309 digits.
            let below = if lo_open { ">" } else { ">=" };
            Err(format!("{shown} must be {below} {lo}"))
        } else {
            Err(format!("{shown} is outside {open}{lo}, {hi_text}]"))
        }
    }
}

/// Numbers that may be NaN or infinite.
trait Finite {
    fn finite(&self) -> bool;
}

impl Finite for f64 {
    fn finite(&self) -> bool {
        self.is_finite()
    }
}

impl Finite for f32 {
    fn finite(&self) -> bool {
        self.is_finite()
    }
}

impl Finite for usize {
    fn finite(&self) -> bool {
        true
    }
}

/// Parser of an `f64` option in `[lo, hi]`, finite.
pub fn f64_in(
    lo: f64,
    hi: f64,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |s| parse_in(s, lo, false, hi)
}

/// Parser of an `f64` option in `(lo, hi]`, finite (a duration or a rate
/// that must be positive: `f64_above(0.0, ...)`).
pub fn f64_above(
    lo: f64,
    hi: f64,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |s| parse_in(s, lo, true, hi)
}

/// The name an option takes for `value` of a `clap::ValueEnum` (what
/// messages call it, not its Rust name).
pub fn value_name<T: clap::ValueEnum>(value: &T) -> String {
    value
        .to_possible_value()
        .map_or_else(String::new, |v| v.get_name().to_owned())
}

/// Parser of an `f32` option in `[lo, hi]`, finite.
pub fn f32_in(
    lo: f32,
    hi: f32,
) -> impl Fn(&str) -> Result<f32, String> + Clone + Send + Sync + 'static {
    move |s| parse_in(s, lo, false, hi)
}

/// Parser of an `f32` option in `(lo, hi]`, finite.
pub fn f32_above(
    lo: f32,
    hi: f32,
) -> impl Fn(&str) -> Result<f32, String> + Clone + Send + Sync + 'static {
    move |s| parse_in(s, lo, true, hi)
}

/// Parser of a `usize` option in `[lo, hi]`.
pub fn usize_in(
    lo: usize,
    hi: usize,
) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |s| parse_in(s, lo, false, hi)
}

/// [`f64_in`]'s check for a value that did not come from the command line;
/// the error names `option`.
///
/// ```
/// use host_sim::cli::check_f64;
/// assert!(check_f64("--holdout", 0.3, 0.0, 0.95).is_ok());
/// let e = check_f64("--holdout", f64::NAN, 0.0, 0.95).unwrap_err();
/// assert_eq!(e.to_string(), "--holdout: not a finite number");
/// ```
///
/// # Errors
/// `v` is NaN, infinite or outside `[lo, hi]`.
pub fn check_f64(option: &str, v: f64, lo: f64, hi: f64) -> anyhow::Result<f64> {
    let shown = if v.abs() >= 1e6 || (v != 0.0 && v.abs() < 1e-4) {
        format!("{v:e}")
    } else {
        format!("{v}")
    };
    check(v, lo, false, hi, &shown).map_err(|e| anyhow::anyhow!("{option}: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsers_refuse_non_finite_and_out_of_range_values() {
        let p = f64_in(0.0, 1.0);
        assert_eq!(p("0.5"), Ok(0.5));
        assert_eq!(p("0"), Ok(0.0));
        assert_eq!(p("1"), Ok(1.0));
        for bad in ["NaN", "inf", "-inf"] {
            assert_eq!(p(bad), Err("not a finite number".to_owned()), "{bad}");
        }
        assert_eq!(p("1e9"), Err("1e9 is outside [0, 1]".to_owned()));
        assert_eq!(p("1e300"), Err("1e300 is outside [0, 1]".to_owned()));
        assert_eq!(
            check_f64("--x", f64::MAX, 0.0, 1.0)
                .unwrap_err()
                .to_string(),
            "--x: 1.7976931348623157e308 is outside [0, 1]"
        );
        assert!(p("abc").is_err());
        let q = f64_above(0.0, 10.0);
        assert_eq!(q("0"), Err("0 is outside (0, 10]".to_owned()));
        assert_eq!(q("1.4e-45"), Ok(1.4e-45));
        assert_eq!(
            f64_above(0.0, f64::MAX)("-1"),
            Err("-1 must be > 0".to_owned())
        );
        assert!(f32_above(0.0, 1.0)("NaN").is_err());
        assert_eq!(usize_in(1, 4)("0"), Err("0 is outside [1, 4]".to_owned()));
        assert_eq!(usize_in(1, 4)("4"), Ok(4));
    }
}
