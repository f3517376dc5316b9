//! Property tests of every parser of the project (issue 10, item 5): the
//! CSV log, the TOML configurations, MRDLab, the KUKA wrist files, the
//! defmt telemetry text and the firmware's sensor trace.
//!
//! Each parser gets (a) arbitrary bytes, (b) a real or generated valid
//! input with a few random edits (a cell, a line, a byte), and (c) where a
//! writer exists, generated data written and read back. The oracles (what
//! must hold) are in `fuzz_support/`, shared with the coverage-guided
//! targets in `host-sim/fuzz/` (see `docs/fuzzing.md`). Every file under
//! `tests/data/fuzz/<target>/` (inputs that once failed) is replayed too.
//!
//! The runs are deterministic (a fixed seed) so that CI is repeatable;
//! `PROPTEST_RNG_SEED=<n>` explores other inputs and `PROPTEST_CASES`
//! overrides the case counts below.

mod fuzz_support;

use std::path::PathBuf;

use cable_joint::board::TraceSample;
use cable_joint::telemetry::{
    Inputs, OriginRecord, Record, StartRecord, TickRecord, MAX_RECORD_LEN,
};
use cable_joint::units::{AdcCode, DacCode, GratingCount, MagneticCount, MotorCount};
use cable_joint::{Config, RawSample};
use fuzz_support as oracle;
use host_sim::ingest::parse_stream;
use host_sim::log::{Log, LogErrorKind, Schema, REQUIRED_COLUMNS};
use host_sim::plant::PlantParams;
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};

/// Cases per property for the cheap parsers (in-memory, one pass).
const CASES: u32 = 256;
/// Cases per property for the parsers that go through files (TOML, KUKA)
/// or replay a trace through the firmware logic.
const CASES_SLOW: u32 = 128;

fn cases(n: u32) -> ProptestConfig {
    ProptestConfig {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(n),
        // A failure is kept as a regression test in tests/data/fuzz/, not
        // in proptest's own files.
        failure_persistence: None,
        rng_seed: match std::env::var("PROPTEST_RNG_SEED") {
            Ok(v) => RngSeed::Fixed(v.parse().expect("PROPTEST_RNG_SEED is a number")),
            Err(_) => RngSeed::Fixed(10),
        },
        ..ProptestConfig::default()
    }
}

// --- Inputs ----------------------------------------------------------------

/// Arbitrary bytes.
fn bytes() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(any::<u8>(), 0..1024)
}

/// Text made of the pieces a parser looks at (separators, numbers, special
/// values, markers, line breaks, non-ASCII), so that it gets past the first
/// check more often than random bytes do.
fn texty(pieces: &'static [&'static str]) -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(
        prop_oneof![
            4 => prop::sample::select(pieces).prop_map(|s| s.as_bytes().to_vec()),
            2 => prop::sample::select(COMMON_PIECES).prop_map(|s| s.as_bytes().to_vec()),
            1 => any::<f64>().prop_map(|v| v.to_string().into_bytes()),
            1 => any::<i64>().prop_map(|v| v.to_string().into_bytes()),
            1 => "\\PC{0,6}".prop_map(String::into_bytes),
        ],
        0..64,
    )
    .prop_map(|v| v.concat())
}

const COMMON_PIECES: &[&str] = &[
    ",", ",", "\n", "\n", "\r\n", " ", "", "0", "1", "-1", "0.5", "1e308", "-1e308", "1e-320",
    "nan", "NaN", "inf", "-inf", "+", "-", ".", "e", "E", "\u{feff}", "é", "≈", "µ", "\t", "\"",
    "#", "=", "[", "]", "%",
];

const CSV_PIECES: &[&str] = &[
    "t_s",
    "x1_m",
    "x2_m",
    "phi_rad",
    "i_ref_a",
    "theta_rad",
    "t",
    "0.001",
    "0.002",
    "1,2,3,4,5",
];

const TOML_PIECES: &[&str] = &[
    "[",
    "]",
    "[[",
    "]]",
    "control_rate_hz",
    "jae",
    "cascade",
    "dob",
    "limits",
    "scales",
    "fusion",
    "stretch",
    " = ",
    "\"",
    "'",
    "'''",
    "true",
    "false",
    "2000.0",
    "1e30",
    "-0.0",
    "{",
    "}",
    "inf",
    "+inf",
    "nan",
    "0x10",
    "1_000",
    "1979-05-27T07:32:00Z",
    "[slider1]",
    "mass_kg",
    "[effects.creep]",
    "tau_s",
];

const MRDLAB_PIECES: &[&str] = &[
    "%",
    "% a 0.30 Hz sine",
    "amplitude of ",
    "torque of ",
    " hz",
    "0.001,",
    "1,2,3,4,5,6,7,8,9,10",
    "0,0,0,0,0,0,0,0,0,0",
    "99999999999",
    "1e300",
];

const DEFMT_PIECES: &[&str] = &[
    "tlm [",
    "tlm ",
    "]",
    "0x",
    "0xff",
    "255",
    "256",
    "1",
    "2",
    "3",
    ", ",
    "INFO ",
    "0.000123 ",
    "└─ src/bin/firmware.rs:42",
    "tlm []",
    "tlm [1, 1, 0, 0, 250, 68, 1, 0, 0, 0]",
];

/// One edit of a valid input.
#[derive(Clone, Debug)]
enum Edit {
    /// Replace the `cell`-th comma-separated field of a line.
    Cell {
        line: usize,
        cell: usize,
        text: String,
    },
    /// Replace what follows `=` on a line (TOML).
    Value {
        line: usize,
        text: String,
    },
    DeleteLine(usize),
    DuplicateLine(usize),
    SwapLines(usize, usize),
    InsertLine {
        line: usize,
        text: String,
    },
    InsertBytes {
        at: usize,
        bytes: Vec<u8>,
    },
    FlipByte {
        at: usize,
        xor: u8,
    },
    Truncate(usize),
}

fn cell_text() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(COMMON_PIECES).prop_map(str::to_owned),
        any::<f64>().prop_map(|v| v.to_string()),
        any::<f32>().prop_map(|v| format!("{v:e}")),
        any::<i64>().prop_map(|v| v.to_string()),
        "\\PC{0,12}",
    ]
}

fn edit() -> impl Strategy<Value = Edit> {
    let ix = 0..10_000usize;
    prop_oneof![
        4 => (ix.clone(), 0..32usize, cell_text())
            .prop_map(|(line, cell, text)| Edit::Cell { line, cell, text }),
        2 => (ix.clone(), cell_text()).prop_map(|(line, text)| Edit::Value { line, text }),
        1 => ix.clone().prop_map(Edit::DeleteLine),
        1 => ix.clone().prop_map(Edit::DuplicateLine),
        1 => (ix.clone(), ix.clone()).prop_map(|(a, b)| Edit::SwapLines(a, b)),
        1 => (ix.clone(), cell_text()).prop_map(|(line, text)| Edit::InsertLine { line, text }),
        1 => (ix.clone(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(at, bytes)| Edit::InsertBytes { at, bytes }),
        1 => (ix.clone(), 1..=255u8).prop_map(|(at, xor)| Edit::FlipByte { at, xor }),
        1 => ix.prop_map(Edit::Truncate),
    ]
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    prop::collection::vec(edit(), 1..4)
}

/// `text` with the edits applied (indices taken modulo the current size).
fn apply(text: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut data = text.to_vec();
    for e in edits {
        let mut lines: Vec<Vec<u8>> = data.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
        let n = lines.len();
        match e {
            Edit::Cell { line, cell, text } => {
                let l = &mut lines[line % n];
                let mut cells: Vec<Vec<u8>> = l.split(|&b| b == b',').map(<[u8]>::to_vec).collect();
                let c = cell % cells.len();
                cells[c] = text.clone().into_bytes();
                *l = cells.join(&b","[..]);
            }
            Edit::Value { line, text } => {
                let l = &mut lines[line % n];
                if let Some(eq) = l.iter().position(|&b| b == b'=') {
                    l.truncate(eq + 1);
                    l.push(b' ');
                    l.extend_from_slice(text.as_bytes());
                }
            }
            Edit::DeleteLine(i) => {
                lines.remove(i % n);
            }
            Edit::DuplicateLine(i) => {
                let l = lines[i % n].clone();
                lines.insert(i % n, l);
            }
            Edit::SwapLines(a, b) => lines.swap(a % n, b % n),
            Edit::InsertLine { line, text } => lines.insert(line % (n + 1), text.clone().into()),
            Edit::InsertBytes { at, bytes } => {
                let at = at % (data.len() + 1);
                data.splice(at..at, bytes.iter().copied());
                continue;
            }
            Edit::FlipByte { at, xor } => {
                if !data.is_empty() {
                    let at = at % data.len();
                    data[at] ^= xor;
                }
                continue;
            }
            Edit::Truncate(at) => {
                data.truncate(at % (data.len() + 1));
                continue;
            }
        }
        data = lines.join(&b"\n"[..]);
    }
    data
}

/// First 1-based line where `edited` differs from `original`, capped at the
/// edited input's last line (a deleted tail is "seen" there).
fn first_changed_line(original: &[u8], edited: &[u8]) -> Option<usize> {
    // What follows the last line break is a line only if it is not empty.
    let lines = |d: &[u8]| -> Vec<Vec<u8>> {
        let mut v: Vec<Vec<u8>> = d.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
        if v.last().is_some_and(Vec::is_empty) {
            v.pop();
        }
        v
    };
    let (a, b) = (lines(original), lines(edited));
    let first = (0..a.len().max(b.len())).find(|&i| a.get(i) != b.get(i))?;
    Some((first + 1).min(oracle::line_count(edited)))
}

/// An error found in an edited input is never reported before the first
/// edited line: the unchanged lines above it were valid.
fn assert_error_not_before_edit(line: Option<usize>, original: &[u8], edited: &[u8], msg: &str) {
    if let (Some(line), Some(first)) = (line, first_changed_line(original, edited)) {
        assert!(
            line >= first,
            "error at line {line}, first edit at line {first}: {msg}"
        );
    }
}

// --- Valid inputs ------------------------------------------------------------

/// A small project log as `Log::write` writes it: the required columns, an
/// optional column with a gap, 12 rows.
fn project_log_text() -> Vec<u8> {
    let mut names: Vec<&str> = REQUIRED_COLUMNS.to_vec();
    names.push("theta_rad");
    let mut log = Log::with_columns(&names).unwrap();
    for k in 0..12 {
        let t = k as f64 * 5e-4;
        let theta = (k != 5).then_some(0.01 * k as f64);
        log.push_row_opt(&[
            Some(t),
            Some(1e-4 * k as f64),
            Some(-2e-4 * k as f64),
            Some(0.3 * k as f64),
            Some(0.05),
            theta,
        ])
        .unwrap();
    }
    let mut out = Vec::new();
    log.write_to(&mut out, "sample").unwrap();
    out
}

/// Header and the first data lines of a real MRDLab run.
fn mrdlab_head() -> Vec<u8> {
    use std::io::Read as _;
    let path = oracle::host_sim_dir().join("tests/data/mrdlab/22.TXT.gz");
    let mut text = String::new();
    flate2::read::MultiGzDecoder::new(std::fs::File::open(path).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    let mut out = String::new();
    let mut data = 0;
    for line in text.lines() {
        if !line.starts_with('%') {
            data += 1;
            if data > 20 {
                break;
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out.into_bytes()
}

fn default_config_toml() -> Vec<u8> {
    toml::to_string(&Config::default()).unwrap().into_bytes()
}

fn plant_toml() -> Vec<u8> {
    PlantParams::default()
        .to_toml_string()
        .unwrap()
        .into_bytes()
}

fn raw_sample() -> impl Strategy<Value = RawSample> {
    (
        any::<i32>(),
        any::<i32>(),
        any::<u16>(),
        any::<u16>(),
        any::<u16>(),
    )
        .prop_map(|(g1, g2, m, mg, adc)| RawSample {
            grating1: GratingCount(g1),
            grating2: GratingCount(g2),
            motor: MotorCount(m),
            magnetic: MagneticCount(mg),
            current: AdcCode(adc),
        })
}

fn f32_bits() -> impl Strategy<Value = f32> {
    prop_oneof![any::<f32>(), any::<u32>().prop_map(f32::from_bits)]
}

fn tick_record() -> impl Strategy<Value = TickRecord> {
    (
        (any::<u32>(), raw_sample(), any::<u8>(), any::<u16>()),
        prop::array::uniform8(f32_bits()),
        (any::<[u8; 2]>(), any::<bool>(), any::<u8>(), any::<u32>()),
        any::<[u16; 4]>(),
    )
        .prop_map(
            |((tick, raw, inputs, dac), f, (mf, de, phase, cycles), st)| TickRecord {
                tick,
                raw,
                inputs: Inputs(inputs),
                dac: DacCode(dac),
                current_ref_a: f[0],
                current_applied_a: f[7],
                theta_ref_rad: f[1],
                theta_hat_rad: f[2],
                f_ext_hat_n: f[3],
                f_ext_fused_n: f[4],
                f_ext_lo_n: f[5],
                f_ext_hi_n: f[6],
                mode: mf[0],
                fault: mf[1],
                drive_enable: de,
                phase,
                cycles,
                stage_cycles: st,
            },
        )
}

fn record() -> impl Strategy<Value = Record> {
    prop_oneof![
        1 => (f32_bits(), any::<u32>()).prop_map(|(control_rate_hz, decimation)| {
            Record::Start(StartRecord {
                version: cable_joint::telemetry::FORMAT_VERSION,
                control_rate_hz,
                decimation,
            })
        }),
        1 => (any::<u32>(), raw_sample())
            .prop_map(|(tick, raw)| Record::Origin(OriginRecord { tick, raw })),
        4 => tick_record().prop_map(Record::Tick),
    ]
}

/// A decoded defmt line for `record`, as defmt-print prints `{=[u8]}` or
/// `{=[u8]:x}`, after a timestamp and level as probe-rs prints them.
fn defmt_line(record: &Record, hex: bool, prefix: &str) -> String {
    let mut buf = [0u8; MAX_RECORD_LEN];
    let items: Vec<String> = record
        .encode(&mut buf)
        .iter()
        .map(|b| {
            if hex {
                format!("{b:#04x}")
            } else {
                b.to_string()
            }
        })
        .collect();
    format!("{prefix}tlm [{}]", items.join(", "))
}

const LOG_LINES: &[&str] = &[
    "INFO  boot",
    "└─ firmware::app::init @ src/bin/firmware.rs:120",
    "WARN  telemetry dropped 3 records",
    "",
    "tlm is not a record without its bracket",
];

/// A telemetry stream as text, with the records it holds.
fn defmt_stream() -> impl Strategy<Value = (Vec<Record>, String)> {
    prop::collection::vec(
        (
            record(),
            any::<bool>(),
            prop::sample::select(&["", "0.000123 INFO  ", "[INFO ] "][..]),
            prop::option::of(prop::sample::select(LOG_LINES)),
        ),
        0..24,
    )
    .prop_map(|items| {
        let mut text = String::new();
        let mut records = Vec::new();
        for (rec, hex, prefix, log_line) in items {
            if let Some(l) = log_line {
                text.push_str(l);
                text.push('\n');
            }
            text.push_str(&defmt_line(&rec, hex, prefix));
            text.push('\n');
            records.push(rec);
        }
        (records, text)
    })
}

fn encoded(r: &Record) -> Vec<u8> {
    let mut buf = [0u8; MAX_RECORD_LEN];
    r.encode(&mut buf).to_vec()
}

/// The first 120 samples of the trace the QEMU firmware replays.
fn firmware_trace_head() -> Vec<u8> {
    let path = oracle::host_sim_dir().join("../firmware/trace.bin");
    let bytes = std::fs::read(&path).unwrap();
    let t = cable_joint::board::Trace::parse(&bytes).unwrap();
    let samples: Vec<TraceSample> = t.iter().take(120).collect();
    oracle::trace_bytes(t.control_rate_hz(), &samples)
}

// --- Seeds and regression corpus -----------------------------------------------

/// Writes the seed corpora of the coverage-guided targets
/// (`host-sim/fuzz/seeds/<target>/`) from the project's test data and from
/// generated records: `cargo test -p host-sim --test fuzz_parsers --
/// --ignored write_seeds`.
#[test]
#[ignore = "regenerates host-sim/fuzz/seeds"]
fn write_seeds() {
    let root = oracle::host_sim_dir().join("fuzz/seeds");
    let put = |target: &str, name: &str, data: &[u8]| {
        let dir = root.join(target);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(name), data).unwrap();
    };
    put("csv_log", "project_log.csv", &project_log_text());
    put(
        "csv_log",
        "kuka_calibration.csv",
        &oracle::kuka_head(oracle::KUKA_FILES[3]),
    );
    put(
        "csv_log",
        "kuka_wrench.csv",
        &oracle::kuka_head(oracle::KUKA_FILES[0]),
    );
    put("config_toml", "default.toml", &default_config_toml());
    put("config_toml", "plant.toml", &plant_toml());
    put("mrdlab", "22_head.TXT", &mrdlab_head());
    for (k, f) in oracle::KUKA_FILES.iter().enumerate() {
        let mut data = vec![k as u8];
        data.extend(oracle::kuka_head(f));
        put("kuka", &format!("{k}_{f}"), &data);
    }
    // A short closed-loop run of the firmware logic as its telemetry text.
    let opts = host_sim::trace::TraceOptions {
        duration_s: 0.06,
        relax_s: 0.05,
        ..Default::default()
    };
    let rec = host_sim::trace::record(PlantParams::default(), &opts).unwrap();
    let mut text = String::from("INFO  boot\n");
    for (k, r) in rec.telemetry().iter().take(16).enumerate() {
        let prefix = format!("{:.6} INFO  ", k as f64 * 5e-4);
        text.push_str(&defmt_line(r, k % 2 == 1, &prefix));
        text.push('\n');
    }
    put("defmt_text", "firmware_run.txt", text.as_bytes());
    put("trace", "firmware_trace_head.bin", &firmware_trace_head());
    // The same samples in the form the target's second half reads: the
    // rate, then whole samples.
    let head = firmware_trace_head();
    let mut raw = head[8..12].to_vec();
    raw.extend_from_slice(&head[16..16 + 17 * 60]);
    put("trace", "rate_and_samples.bin", &raw);
}

// --- Regression corpus ---------------------------------------------------------

fn regression_dir(target: &str) -> PathBuf {
    oracle::host_sim_dir().join("tests/data/fuzz").join(target)
}

#[test]
fn kept_crashes_and_seeds_do_not_fail() {
    let mut kept = 0;
    for (target, check) in oracle::TARGETS {
        let n = oracle::replay_dir(&regression_dir(target), check);
        let seeds = oracle::replay_dir(
            &oracle::host_sim_dir().join("fuzz/seeds").join(target),
            check,
        );
        assert!(seeds > 0, "no seed for {target}");
        eprintln!("{target}: {n} kept inputs, {seeds} seeds replayed");
        kept += n;
    }
    // `replay_dir` reads nothing from a directory it cannot list: the two
    // kept KUKA crashes (`tests/data/fuzz/kuka/`) prove the corpus was read.
    assert!(kept >= 2, "{kept} kept inputs replayed");
}

/// The two KUKA inputs the property tests found (kept in
/// `tests/data/fuzz/kuka/`), with the messages they now give: the file,
/// the line and the column (the noise overflow, a cell of -1e200 N, is
/// refused as beyond any sensor's range before the column's statistic
/// could overflow).
#[test]
fn kuka_overflows_are_errors_naming_the_file_the_column_and_a_rows_line() {
    let dir = tempfile::tempdir().unwrap();
    for f in oracle::KUKA_FILES {
        std::fs::write(dir.path().join(f), oracle::kuka_head(f)).unwrap();
    }
    let kept = |name: &str| std::fs::read(regression_dir("kuka").join(name)).unwrap()[1..].to_vec();

    let noise = dir.path().join(oracle::KUKA_FILES[4]);
    std::fs::write(&noise, kept("noise_overflow")).unwrap();
    let msg = format!(
        "{:#}",
        host_sim::payload::steady_state_noise(&noise).unwrap_err()
    );
    assert!(
        msg.starts_with(&format!(
            "{}: line 2: column \"fz\" = -1e200 N is beyond any sensor's range",
            noise.display()
        )),
        "{msg}"
    );

    let wrench = dir.path().join(oracle::KUKA_FILES[0]);
    std::fs::write(&wrench, kept("time_rebase_collapses")).unwrap();
    let msg = format!(
        "{:#}",
        host_sim::payload::load_run(dir.path(), "1-baseline").unwrap_err()
    );
    assert!(
        msg.starts_with(&format!("{}:4: column \"t\": ", wrench.display())),
        "{msg}"
    );
    assert!(msg.len() < 300, "{msg}");
}

/// A huge value in a configuration file is not copied into the message
/// (the `toml` crate's own message repeats the whole line): every loader
/// names the file, the line and the key, in a few hundred bytes.
#[test]
fn config_errors_do_not_copy_a_huge_value() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.toml");
    for text in [
        format!("[jae]\nc_pos_rad_m = \"{}\"\n", "9".repeat(100_000)),
        format!("[jae]\nc_pos_rad_m = {}\n", "x".repeat(100_000)),
    ] {
        std::fs::write(&path, &text).unwrap();
        let errors = [host_sim::io::config::load_config(&path).unwrap_err()];
        for e in errors {
            let msg = format!("{e:#}");
            assert!(msg.len() < 500, "{} bytes: {}", msg.len(), &msg[..500]);
            assert!(msg.contains(&path.display().to_string()), "{msg}");
            assert!(msg.contains("c_pos_rad_m"), "{msg}");
        }
        let msg = format!("{:#}", PlantParams::from_toml_str(&text).unwrap_err());
        assert!(msg.len() < 500, "{} bytes", msg.len());
    }
}

// --- CSV log -------------------------------------------------------------------

fn log_name() -> impl Strategy<Value = String> {
    prop_oneof![
        "[a-z_][a-z0-9_]{0,10}",
        "\\PC{1,6}".prop_filter("a valid name", |n| Log::with_columns(&[n]).is_ok()),
    ]
}

fn finite_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        prop::sample::select(&[0.0, -0.0, f64::MIN_POSITIVE, 5e-324, f64::MAX, -f64::MAX][..]),
        (-1e6..1e6f64),
    ]
}

/// A log with 1..6 uniquely named columns and 0..20 rows, some cells not
/// measured.
fn any_log() -> impl Strategy<Value = Log> {
    (prop::collection::hash_set(log_name(), 1..6), 0..20usize).prop_flat_map(|(names, rows)| {
        let names: Vec<String> = names.into_iter().collect();
        let ncols = names.len();
        prop::collection::vec(
            prop::collection::vec(prop::option::weighted(0.9, finite_f64()), ncols),
            rows,
        )
        .prop_map(move |rows| {
            let refs: Vec<&str> = names.iter().map(String::as_str).collect();
            let mut log = Log::with_columns(&refs).unwrap();
            for r in rows {
                log.push_row_opt(&r).unwrap();
            }
            log
        })
    })
}

proptest! {
    #![proptest_config(cases(CASES))]

    /// The link's frame reader on any byte stream (line noise, a host of
    /// another version): never a panic, and a frame that decodes re-encodes
    /// to the same message.
    #[test]
    fn link_frames_any_bytes(data in bytes()) {
        use cable_joint::link::{decode, encode, Down, FrameReader, Pushed, MAX_WIRE_LEN};
        let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
        for &b in &data {
            if let Pushed::Frame(n) = reader.push(b) {
                if let Ok((seq, msg)) = decode::<Down>(reader.frame(), n) {
                    let mut out = [0u8; MAX_WIRE_LEN];
                    let mut again = encode(&msg, seq, &mut out).expect("re-encodes").to_vec();
                    let len = again.len() - 1;
                    let (seq2, msg2): (u8, Down) = decode(&mut again, len).expect("decodes");
                    prop_assert_eq!((seq2, msg2), (seq, msg));
                }
            }
        }
    }

    #[test]
    fn csv_log_any_bytes(data in bytes()) {
        oracle::csv_log(&data);
    }

    #[test]
    fn csv_log_texty(data in texty(CSV_PIECES)) {
        oracle::csv_log(&data);
    }

    #[test]
    fn csv_log_edited_project_log(e in edits()) {
        let original = project_log_text();
        let data = apply(&original, &e);
        oracle::csv_log(&data);
        if let Err(err) = Log::from_reader(data.as_slice(), "run.csv", &Schema::project()) {
            assert_error_not_before_edit(err.line, &original, &data, &err.to_string());
        }
    }

    #[test]
    fn csv_log_edited_kuka_file(e in edits(), file in 0..5usize) {
        let original = oracle::kuka_head(oracle::KUKA_FILES[file]);
        let data = apply(&original, &e);
        oracle::csv_log(&data);
        if let Err(err) = Log::from_reader(data.as_slice(), "k.csv", &Schema::any()) {
            assert_error_not_before_edit(err.line, &original, &data, &err.to_string());
        }
    }

    /// Any log written is read back with the same names, rows and bits.
    /// The one log that cannot round-trip (one column, last row not
    /// measured: a blank line) is refused before a byte is written.
    #[test]
    fn csv_log_write_read_round_trip(log in any_log()) {
        let mut text = Vec::new();
        let names = log.names();
        if names.len() == 1 && !log.is_empty() && !log.is_measured(names[0], log.len() - 1) {
            let err = log.write_to(&mut text, "rt.csv").unwrap_err();
            assert!(matches!(err.kind, LogErrorKind::UnmeasuredLastRow), "{err}");
            assert!(text.is_empty(), "nothing written");
            return Ok(());
        }
        log.write_to(&mut text, "rt.csv").unwrap();
        let schema = Schema::any().time_column(None);
        let back = Log::from_reader(text.as_slice(), "rt.csv", &schema).unwrap_or_else(|e| {
            panic!("{e}\n{}", String::from_utf8_lossy(&text))
        });
        oracle::assert_same_log(&log, &back);
    }

    // --- MRDLab --------------------------------------------------------------

    #[test]
    fn mrdlab_any_bytes(data in bytes()) {
        oracle::mrdlab(&data);
    }

    #[test]
    fn mrdlab_texty(data in texty(MRDLAB_PIECES)) {
        oracle::mrdlab(&data);
    }

    #[test]
    fn mrdlab_edited_real_run(e in edits()) {
        let original = mrdlab_head();
        let data = apply(&original, &e);
        oracle::mrdlab(&data);
        if let Err(err) = host_sim::import::read_mrdlab(data.as_slice(), "22.TXT") {
            assert_error_not_before_edit(err.line, &original, &data, &err.to_string());
        }
    }

    /// Any text in the `%` header (non-ASCII included) next to the markers
    /// the importer looks for.
    #[test]
    fn mrdlab_header_text(header in prop::collection::vec(
        ("\\PC{0,8}", prop::sample::select(&[" hz", "amplitude of", "torque of", "Hz"][..]),
         "\\PC{0,8}"),
        1..4,
    )) {
        let mut data: Vec<u8> = Vec::new();
        for (a, marker, b) in &header {
            data.extend_from_slice(format!("%{a}{marker}{b}\n").as_bytes());
        }
        let body = mrdlab_head();
        data.extend_from_slice(&body);
        oracle::mrdlab(&data);
        let run = host_sim::import::read_mrdlab(data.as_slice(), "22.TXT").unwrap();
        for v in [run.meta.freq_hz, run.meta.amplitude_deg, run.meta.torque_percent]
            .into_iter()
            .flatten()
        {
            prop_assert!(!v.is_nan());
        }
    }

    // --- defmt text ------------------------------------------------------------

    #[test]
    fn defmt_any_bytes(data in bytes()) {
        oracle::defmt_text(&data);
    }

    #[test]
    fn defmt_texty(data in texty(DEFMT_PIECES)) {
        oracle::defmt_text(&data);
    }

    /// Records printed as defmt-print prints them are read back, byte for
    /// byte, whatever lies around them; a tick record with a NaN or infinite
    /// value (which the firmware never sends) is an error naming its line.
    #[test]
    fn defmt_records_round_trip((records, text) in defmt_stream()) {
        let corrupt = records.iter().position(|r| match r {
            Record::Tick(t) => [
                t.current_ref_a, t.current_applied_a, t.theta_ref_rad, t.theta_hat_rad,
                t.f_ext_hat_n, t.f_ext_fused_n, t.f_ext_lo_n, t.f_ext_hi_n,
            ]
            .iter()
            .any(|v| !v.is_finite()),
            _ => false,
        });
        if let Some(k) = corrupt {
            let err = parse_stream(text.as_bytes(), "run.txt").unwrap_err().to_string();
            let Record::Tick(t) = &records[k] else { unreachable!() };
            prop_assert!(err.starts_with("run.txt:"), "{}", err);
            prop_assert!(err.contains(&format!("tick {}:", t.tick)), "{}", err);
            prop_assert!(err.contains("corrupt"), "{}", err);
            return Ok(());
        }
        let back = parse_stream(text.as_bytes(), "run.txt").unwrap();
        let a: Vec<Vec<u8>> = records.iter().map(encoded).collect();
        let b: Vec<Vec<u8>> = back.iter().map(encoded).collect();
        prop_assert_eq!(a, b);
        oracle::defmt_text(text.as_bytes());
    }

    #[test]
    fn defmt_edited_stream((_, text) in defmt_stream(), e in edits()) {
        let original = text.into_bytes();
        let data = apply(&original, &e);
        oracle::defmt_text(&data);
    }
}

proptest! {
    #![proptest_config(cases(CASES_SLOW))]

    // --- TOML configuration ----------------------------------------------------

    #[test]
    fn config_any_bytes(data in bytes()) {
        oracle::config_toml(&data);
    }

    #[test]
    fn config_texty(data in texty(TOML_PIECES)) {
        oracle::config_toml(&data);
    }

    #[test]
    fn config_edited_default(e in edits()) {
        oracle::config_toml(&apply(&default_config_toml(), &e));
    }

    #[test]
    fn config_edited_plant(e in edits()) {
        oracle::config_toml(&apply(&plant_toml(), &e));
    }

    // --- KUKA ------------------------------------------------------------------

    #[test]
    fn kuka_any_bytes(file in 0..5u8, data in bytes()) {
        let mut input = vec![file];
        input.extend_from_slice(&data);
        oracle::kuka(&input);
    }

    #[test]
    fn kuka_edited_real_file(file in 0..5u8, e in edits()) {
        let mut input = vec![file];
        input.extend(apply(&oracle::kuka_head(oracle::KUKA_FILES[usize::from(file)]), &e));
        oracle::kuka(&input);
    }

    // --- Trace -------------------------------------------------------------------

    #[test]
    fn trace_any_bytes(data in prop::collection::vec(any::<u8>(), 0..4096)) {
        oracle::trace(&data);
    }

    /// The recorded firmware trace with bytes changed, inserted or cut, as
    /// it is and with its header's count mended.
    #[test]
    fn trace_edited_firmware_trace(e in prop::collection::vec(edit(), 1..6)) {
        let data = apply(&firmware_trace_head(), &e);
        oracle::trace(&data);
        let mut mended = data.clone();
        if mended.len() >= 16 {
            let count = ((mended.len() - 16) / 17) as u32;
            mended.truncate(16 + 17 * count as usize);
            mended[12..16].copy_from_slice(&count.to_le_bytes());
            oracle::trace(&mended);
        }
    }
}
