//! Oracles shared by the property tests (`tests/fuzz_parsers.rs`) and the
//! coverage-guided targets (`fuzz/fuzz_targets/*.rs`, which include this
//! file with `#[path]`): each takes raw bytes, runs one parser on them and
//! panics when a property fails. A panic inside the parser is a failure too.
//!
//! Properties common to every parser:
//!
//! * no panic, whatever the bytes;
//! * an error names the input (file name as given) and, where the parser
//!   reads lines, a line that exists; its message stays short, whatever the
//!   size of the offending cell;
//! * what is accepted satisfies the parser's documented guarantees (schema,
//!   finite values, strictly increasing time) and survives a write and a
//!   read back unchanged where a writer exists.
//!
//! Parsers that only read paths get the bytes through a file in a scratch
//! directory of the calling thread (removed when the thread ends), in
//! `$TMPDIR`: `run.sh` points it at `/dev/shm`, where rewriting a file does
//! not wait for the disk.

#![allow(dead_code)] // each target uses one oracle

use std::cell::RefCell;
use std::fmt::Display;
use std::path::{Path, PathBuf};

use cable_joint::board::{trace::trace_header, Program};
use cable_joint::board::{ControlLoop, Harness, Request, Trace, TraceSample};
use cable_joint::telemetry::{Record, MAX_RECORD_LEN};
use cable_joint::Config;
use host_sim::cli::import::summary;
use host_sim::import::{mrdlab_schema, read_mrdlab};
use host_sim::ingest::{columns, cycle_stats, parse_stream, to_log, LogOptions};
use host_sim::log::{Log, LogError, Schema};
use host_sim::payload;
use host_sim::plant::PlantParams;

/// Name the in-memory parsers are given, so messages can be checked for it.
pub const CSV_NAME: &str = "fuzz.csv";
/// Name of an MRDLab input (a run's file name has the form `XY.TXT`).
pub const MRDLAB_NAME: &str = "fuzz/22.TXT";
/// Name of a defmt text input.
pub const DEFMT_NAME: &str = "fuzz.txt";

/// Longest message accepted for an error about a small input: cells and
/// names are quoted cut short ([`host_sim::log::quoted`]), so a message never
/// grows with the input.
pub const MAX_MESSAGE_BYTES: usize = 1200;

/// Most trace samples replayed through the firmware logic per input.
pub const MAX_REPLAY_TICKS: usize = 400;

/// `host-sim/`, from the test crate or from the fuzz crate beneath it.
pub fn host_sim_dir() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    if here.join("tests/data").is_dir() {
        here.to_path_buf()
    } else {
        here.parent()
            .expect("fuzz crate under host-sim/")
            .to_path_buf()
    }
}

thread_local! {
    static SCRATCH: RefCell<Option<tempfile::TempDir>> = const { RefCell::new(None) };
}

/// This thread's scratch directory.
fn scratch() -> PathBuf {
    SCRATCH.with(|s| {
        s.borrow_mut()
            .get_or_insert_with(|| tempfile::tempdir().expect("scratch directory"))
            .path()
            .to_path_buf()
    })
}

fn write(path: &Path, data: &[u8]) {
    std::fs::write(path, data).unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
}

/// Lines in `data` as an editor counts them (a last line without `\n`
/// counts), at least 1.
pub fn line_count(data: &[u8]) -> usize {
    let newlines = data.iter().filter(|&&b| b == b'\n').count();
    let tail = usize::from(!data.is_empty() && *data.last().unwrap() != b'\n');
    (newlines + tail).max(1)
}

/// The message names `name` first and is short.
fn check_message(msg: &str, name: &str) {
    assert!(
        msg.starts_with(name),
        "message does not start with the input's name {name:?}: {msg}"
    );
    assert!(
        msg.len() <= MAX_MESSAGE_BYTES,
        "message of {} bytes: {}…",
        msg.len(),
        &msg[..msg.char_indices().nth(200).map_or(msg.len(), |(i, _)| i)]
    );
}

/// A [`LogError`] from reading `data`: names the file and an existing line.
fn check_log_error(e: &LogError, name: &str, data: &[u8]) {
    let msg = e.to_string();
    check_message(&msg, name);
    assert_eq!(e.file, name, "{msg}");
    let line = e.line.unwrap_or_else(|| panic!("no line in {msg}"));
    assert!(
        (1..=line_count(data)).contains(&line),
        "line {line} of a {}-line input: {msg}",
        line_count(data)
    );
}

/// Every measured value finite, `schema` satisfied, and the log equal, bit
/// for bit, to itself written and read back.
pub fn check_log_accepted(log: &Log, schema: &Schema, name: &str) {
    for n in log.names() {
        for (row, v) in log.col_opt(n).unwrap().into_iter().enumerate() {
            if let Some(v) = v {
                assert!(v.is_finite(), "{name}: {n}[{row}] = {v} accepted");
            }
        }
    }
    if let Err(e) = log.validate(schema, name) {
        panic!("accepted log fails its own schema: {e}");
    }
    let mut text = Vec::new();
    log.write_to(&mut text, name)
        .unwrap_or_else(|e| panic!("accepted log cannot be written: {e}"));
    let back = Log::from_reader(text.as_slice(), name, schema).unwrap_or_else(|e| {
        panic!(
            "accepted log written and read back is refused: {e}\n{}",
            String::from_utf8_lossy(&text)
        )
    });
    assert_same_log(log, &back);
}

/// Same names, same rows, same measured cells, same bits.
pub fn assert_same_log(a: &Log, b: &Log) {
    assert_eq!(a.names(), b.names(), "column names");
    assert_eq!(a.len(), b.len(), "rows");
    for n in a.names() {
        let bits = |l: &Log| -> Vec<Option<u64>> {
            l.col_opt(n)
                .unwrap()
                .into_iter()
                .map(|v| v.map(f64::to_bits))
                .collect()
        };
        assert_eq!(bits(a), bits(b), "column {n}");
    }
}

// --- CSV log -------------------------------------------------------------

/// The project's CSV log reader ([`Log::from_reader`]) under three schemas.
pub fn csv_log(data: &[u8]) {
    for schema in [
        Schema::any(),
        Schema::project(),
        Schema::with_required(&["t"]).min_rows(2),
    ] {
        match Log::from_reader(data, CSV_NAME, &schema) {
            Ok(log) => check_log_accepted(&log, &schema, CSV_NAME),
            Err(e) => check_log_error(&e, CSV_NAME, data),
        }
    }
}

// --- TOML configuration --------------------------------------------------

/// Every float in a TOML value is finite.
fn assert_finite_toml(v: &toml::Value, path: &str, file: &str) {
    match v {
        toml::Value::Float(f) => assert!(f.is_finite(), "{file}: {path} = {f} accepted"),
        toml::Value::Table(t) => {
            for (k, v) in t {
                assert_finite_toml(v, &format!("{path}.{k}"), file);
            }
        }
        toml::Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                assert_finite_toml(v, &format!("{path}[{i}]"), file);
            }
        }
        _ => {}
    }
}

/// A configuration accepted by a loader: valid, finite, and equal to itself
/// written as `io::config::write_config` writes it (`io::config::to_toml`,
/// here without the fsync that would slow the fuzzer down) and loaded back.
fn check_config_accepted(c: &Config, loader: &str, dir: &Path) {
    if let Err(e) = c.validate() {
        panic!("{loader} accepted a configuration that validate() refuses: {e}");
    }
    let value = toml::Value::try_from(c).expect("a Config serializes");
    assert_finite_toml(&value, "", loader);
    let back = dir.join("back.toml");
    let text = host_sim::io::config::to_toml(c)
        .unwrap_or_else(|e| panic!("{loader}: accepted configuration cannot be written: {e}"));
    write(&back, text.as_bytes());
    let again = host_sim::io::config::load_config(&back)
        .unwrap_or_else(|e| panic!("{loader}: configuration written and loaded back: {e:#}"));
    assert_eq!(&again, c, "{loader}: written and loaded back");
}

fn check_config_error(e: &impl Display, path: &Path, loader: &str) {
    let msg = e.to_string();
    let shown = path.display().to_string();
    assert!(
        msg.contains(&shown),
        "{loader}: message does not name {shown}: {msg}"
    );
    assert!(
        msg.len() <= MAX_MESSAGE_BYTES + shown.len(),
        "{loader}: message of {} bytes",
        msg.len()
    );
}

/// The configuration loader every command uses ([`host_sim::io::config`])
/// and the plant parameters' parser on the same file.
pub fn config_toml(data: &[u8]) {
    let dir = scratch();
    let path = dir.join("config.toml");
    write(&path, data);
    let loader = "io::config::load_config";
    match host_sim::io::config::load_config(&path) {
        Ok(c) => check_config_accepted(&c, loader, &dir),
        Err(e) => check_config_error(&format!("{e:#}"), &path, loader),
    }
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(p) = PlantParams::from_toml_str(text) {
            // `validate` may refuse it (the callers check); it must not panic.
            let _ = p.validate();
            let written = p.to_toml_string().expect("plant parameters serialize");
            let back = PlantParams::from_toml_str(&written)
                .unwrap_or_else(|e| panic!("plant parameters written and read back: {e:#}"));
            assert_eq!(
                back.to_toml_string().unwrap(),
                written,
                "plant parameters written and read back"
            );
        }
    }
}

// --- MRDLab --------------------------------------------------------------

/// The MRDLab importer ([`read_mrdlab`]): an accepted run satisfies
/// [`mrdlab_schema`] and reads back, as the project's own log, unchanged.
pub fn mrdlab(data: &[u8]) {
    match read_mrdlab(data, MRDLAB_NAME) {
        Ok(run) => {
            check_log_accepted(&run.log, &mrdlab_schema(), MRDLAB_NAME);
            let _ = summary(&run);
            let _ = run.meta.to_string();
        }
        Err(e) => check_log_error(&e, MRDLAB_NAME, data),
    }
}

// --- KUKA wrist data set ---------------------------------------------------

/// The KUKA files, in the order of the selector byte of [`kuka`].
pub const KUKA_FILES: [&str; 5] = [
    "1-baseline_wrench.csv",
    "1-baseline_accel.csv",
    "1-baseline_orientations.csv",
    "0-calibration_fts-accel.csv",
    "0-steady-state_wrench.csv",
];

/// Lines of each real file kept as the valid neighbours of a fuzzed one.
const KUKA_HEAD_LINES: usize = 40;

thread_local! {
    static KUKA_HEADS: RefCell<Vec<(String, Vec<u8>)>> = const { RefCell::new(Vec::new()) };
}

/// The first [`KUKA_HEAD_LINES`] lines of a file of the data set (read once
/// per thread).
pub fn kuka_head(file: &str) -> Vec<u8> {
    KUKA_HEADS.with(|h| {
        let mut h = h.borrow_mut();
        if let Some((_, head)) = h.iter().find(|(f, _)| f == file) {
            return head.clone();
        }
        let head = read_kuka_head(file);
        h.push((file.to_owned(), head.clone()));
        head
    })
}

fn read_kuka_head(file: &str) -> Vec<u8> {
    let path = host_sim_dir().join("tests/data/kuka-wrist").join(file);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    let mut out = String::new();
    for line in text.lines().take(KUKA_HEAD_LINES) {
        out.push_str(line);
        out.push('\n');
    }
    out.into_bytes()
}

fn check_stream<const N: usize>(s: &payload::Stream<N>, what: &str) {
    assert_eq!(s.t_s.len(), s.v.len(), "{what}: times and values");
    assert!(s.len() >= 10, "{what}: {} samples accepted", s.len());
    for (k, t) in s.t_s.iter().enumerate() {
        assert!(t.is_finite(), "{what}: t_s[{k}] = {t:e}");
        if k > 0 {
            assert!(
                *t > s.t_s[k - 1],
                "{what}: t_s[{k}] = {t:e} after {:e} (accepted, not increasing)",
                s.t_s[k - 1]
            );
        }
    }
    for (k, v) in s.v.iter().enumerate() {
        assert!(v.iter().all(|x| x.is_finite()), "{what}: v[{k}] = {v:?}");
    }
}

/// The KUKA readers ([`payload::load_run`], [`payload::load_static_poses`],
/// [`payload::steady_state_noise`]). The first byte picks which of
/// [`KUKA_FILES`] the rest replaces; the others are the heads of the real
/// files.
pub fn kuka(data: &[u8]) {
    let Some((&selector, content)) = data.split_first() else {
        return;
    };
    let which = usize::from(selector) % KUKA_FILES.len();
    let dir = scratch().join("kuka");
    if !dir.is_dir() {
        std::fs::create_dir_all(&dir).expect("kuka scratch");
        for f in KUKA_FILES {
            write(&dir.join(f), &kuka_head(f));
        }
    }
    let path = dir.join(KUKA_FILES[which]);
    write(&path, content);
    let shown = path.display().to_string();
    let check_err = |e: anyhow::Error| {
        let msg = format!("{e:#}");
        assert!(msg.contains(&shown), "message does not name {shown}: {msg}");
        assert!(msg.len() <= MAX_MESSAGE_BYTES + shown.len(), "{msg}");
    };
    let result = match which {
        0..=2 => payload::load_run(&dir, "1-baseline").map(|run| {
            check_stream(&run.wrench, "wrench");
            check_stream(&run.accel_g, "accel");
            check_stream(&run.orient, "orientations");
        }),
        3 => payload::load_static_poses(&path).map(|p| {
            let n = p.wrench.len();
            assert!(n >= 6, "{n} poses accepted");
            assert_eq!(p.accel_g.len(), n);
            assert_eq!(p.gravity_m_s2.len(), n);
            assert_eq!(p.orient.len(), n);
        }),
        _ => payload::steady_state_noise(&path).map(|sd| {
            assert!(
                sd.iter().all(|s| s.is_finite() && *s >= 0.0),
                "noise {sd:?} accepted"
            );
        }),
    };
    // Restore the real file for the next input.
    write(&path, &kuka_head(KUKA_FILES[which]));
    if let Err(e) = result {
        check_err(e);
    }
}

// --- defmt text (telemetry) ------------------------------------------------

/// `record` encoded, decoded and encoded again gives the same bytes.
fn check_record_round_trip(record: &Record) {
    let mut a = [0u8; MAX_RECORD_LEN];
    let mut b = [0u8; MAX_RECORD_LEN];
    let bytes = record.encode(&mut a).to_vec();
    let again = Record::decode(&bytes).unwrap_or_else(|e| panic!("{record:?} re-decoded: {e}"));
    assert_eq!(again.encode(&mut b), bytes.as_slice(), "{record:?}");
}

/// `host-sim ingest`'s reader ([`parse_stream`]) and converter ([`to_log`]):
/// an error names the file and the line; an accepted stream converts to a
/// log with one row per tick record and the documented columns, which reads
/// back as a project log when every value is finite.
pub fn defmt_text(data: &[u8]) {
    let records = match parse_stream(data, DEFMT_NAME) {
        Ok(r) => r,
        Err(e) => {
            let msg = format!("{e:#}");
            check_message(&msg, DEFMT_NAME);
            let line: usize = msg[DEFMT_NAME.len() + 1..]
                .split(':')
                .next()
                .and_then(|l| l.parse().ok())
                .unwrap_or_else(|| panic!("no line in {msg}"));
            assert!((1..=line_count(data)).contains(&line), "{msg}");
            return;
        }
    };
    for r in &records {
        check_record_round_trip(r);
    }
    let ticks: Vec<_> = records
        .iter()
        .filter_map(|r| match r {
            Record::Tick(t) => Some(*t),
            _ => None,
        })
        .collect();
    let _ = cycle_stats(&ticks);
    for magnetic in [false, true] {
        let opts = LogOptions {
            magnetic,
            ..LogOptions::default()
        };
        let Ok(log) = to_log(&records, &Config::default(), &opts) else {
            continue;
        };
        assert_eq!(log.len(), ticks.len(), "one row per tick record");
        assert_eq!(log.names(), columns(&opts));
        // A non-finite value is refused at parse, naming its input line, so
        // what reaches the log can always be written.
        check_log_accepted(&log, &Schema::project().min_rows(0), DEFMT_NAME);
    }
}

// --- firmware sensor trace -------------------------------------------------

/// The trace as [`Trace::parse`] read it: header length and samples agree
/// with the bytes.
fn check_trace(t: &Trace, data: &[u8]) {
    assert_eq!(16 + 17 * t.len(), data.len(), "length");
    let samples: Vec<TraceSample> = t.iter().collect();
    assert_eq!(samples.len(), t.len(), "every sample readable");
    assert_eq!(t.get(t.len()), None, "nothing after the last sample");
    for (k, s) in samples.iter().enumerate() {
        assert_eq!(&s.to_bytes()[..15], &data[16 + 17 * k..16 + 17 * k + 15]);
    }
}

/// The bytes of a trace with these samples.
pub fn trace_bytes(rate_hz: f32, samples: &[TraceSample]) -> Vec<u8> {
    let mut v = trace_header(rate_hz, samples.len() as u32, 0).to_vec();
    for s in samples {
        v.extend_from_slice(&s.to_bytes());
    }
    v
}

/// Replays up to [`MAX_REPLAY_TICKS`] samples through the firmware's tasks
/// ([`Harness`]) running the default program: no panic, and the drive off
/// whenever a fault is latched.
pub fn replay(t: &Trace) {
    let control = ControlLoop::new(t.config(), 1).expect("firmware configuration");
    let mut h = Harness::new(control);
    for (k, s) in t.iter().take(MAX_REPLAY_TICKS).enumerate() {
        let req = (k == 0).then_some(Request::Program(Program::default()));
        let o = h.tick(&s, req);
        if o.output.fault.is_some() {
            assert!(
                !o.output.drive_enable && !h.drive_enabled(),
                "tick {k}: fault {:?} with the drive on",
                o.output.fault
            );
        }
        assert!(
            o.output.current_ref_a.is_finite(),
            "tick {k}: current {}",
            o.output.current_ref_a
        );
    }
}

/// The firmware's trace parser ([`Trace::parse`]) on the bytes as they are,
/// then on a valid trace built from them (the first four bytes are the
/// rate, the rest whole samples), replayed through the firmware logic.
pub fn trace(data: &[u8]) {
    match Trace::parse(data) {
        Ok(t) => check_trace(&t, data),
        Err(e) => assert!(!e.to_string().is_empty()),
    }
    if data.len() < 4 {
        return;
    }
    let rate = f32::from_le_bytes([data[0], data[1], data[2], data[3]]);
    let samples: Vec<TraceSample> = data[4..]
        .chunks_exact(17)
        .map(|c| TraceSample::from_bytes(c.try_into().unwrap()))
        .collect();
    let bytes = trace_bytes(rate, &samples);
    let t = Trace::parse(&bytes).unwrap_or_else(|e| panic!("a built trace is refused: {e}"));
    assert_eq!(t.control_rate_hz().to_bits(), rate.to_bits());
    assert_eq!(t.iter().collect::<Vec<_>>(), samples, "samples round trip");
    check_trace(&t, &bytes);
    replay(&t);
}

/// A parser's oracle: panics when a property fails on these bytes.
pub type Oracle = fn(&[u8]);

/// Every fuzz target, by name (the directory of its seeds and kept crashes).
pub const TARGETS: [(&str, Oracle); 6] = [
    ("csv_log", csv_log),
    ("config_toml", config_toml),
    ("mrdlab", mrdlab),
    ("kuka", kuka),
    ("defmt_text", defmt_text),
    ("trace", trace),
];

/// Runs `oracle` on every file of `dir` (kept crashes or seeds; `*.md`
/// skipped); the number of files run.
///
/// # Panics
/// After all files ran, naming every file that failed.
pub fn replay_dir(dir: &Path, oracle: Oracle) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut files: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
    files.sort();
    files.retain(|f| f.is_file() && f.extension().is_none_or(|e| e != "md"));
    let failed: Vec<String> = files
        .iter()
        .filter(|f| {
            let data = std::fs::read(f).unwrap();
            std::panic::catch_unwind(|| oracle(&data)).is_err()
        })
        .map(|f| f.display().to_string())
        .collect();
    assert!(failed.is_empty(), "inputs that fail: {failed:#?}");
    files.len()
}
