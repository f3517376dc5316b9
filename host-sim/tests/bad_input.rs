//! The host tools on bad input and bad output paths, through the command
//! line: each case is a clear error (or a warning) naming the file, the line
//! and the option, a non-zero exit, and nothing half-written.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn host_sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
}

fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("host-sim runs")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs `cmd`, which must succeed; returns its stderr.
fn run_ok(cmd: &mut Command) -> String {
    let out = run(cmd);
    assert!(
        out.status.success(),
        "host-sim failed: {}\n{}",
        stderr(&out),
        String::from_utf8_lossy(&out.stdout)
    );
    stderr(&out)
}

/// Runs `cmd`, which must fail; returns its stderr.
fn run_err(cmd: &mut Command) -> String {
    let out = run(cmd);
    assert!(
        !out.status.success(),
        "host-sim succeeded: {}\n{}",
        stderr(&out),
        String::from_utf8_lossy(&out.stdout)
    );
    stderr(&out)
}

/// A simulated run of `scenario` (`seconds` long, tuned gains) written by
/// `host-sim simulate` to `dir/name`.
fn simulated(dir: &Path, scenario: &str, seconds: f64, name: &str) -> PathBuf {
    simulated_with(dir, scenario, seconds, name, &[])
}

/// [`simulated`] with more `simulate` arguments (`--seed N`: another run of
/// the scenario).
fn simulated_with(dir: &Path, scenario: &str, seconds: f64, name: &str, extra: &[&str]) -> PathBuf {
    let path = dir.join(name);
    run_ok(
        host_sim()
            .args(["simulate", "--tuned-gains", "--scenario", scenario])
            .arg("--duration")
            .arg(seconds.to_string())
            .args(extra)
            .arg("--out")
            .arg(&path),
    );
    path
}

#[cfg(unix)]
fn mode(p: &Path) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p).unwrap().permissions().mode() & 0o777
}

fn dir_entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

// --- Outputs -------------------------------------------------------------

#[test]
fn residual_writes_neither_output_when_one_cannot_be_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = simulated(d, "track-motor", 3.0, "run.csv");
    let config = d.join("c.toml");
    std::fs::write(&config, "# old\n").unwrap();
    let json = d.join("nodir").join("x.json");
    let err = run_err(
        host_sim()
            .args(["residual", "--model", "jae", "--log"])
            .arg(&log)
            .arg("--config-out")
            .arg(&config)
            .arg("--json")
            .arg(&json),
    );
    assert!(err.contains(&json.display().to_string()), "{err}");
    assert_eq!(std::fs::read_to_string(&config).unwrap(), "# old\n");
    assert_eq!(dir_entries(d), ["c.toml", "run.csv"]);
}

/// An output directory that is a file is refused with that reason (not
/// the system's "File exists"), before the command's work (the report's
/// minutes), and the file is left as it was.
/// An output named as one of the command's own inputs (by the same path,
/// another spelling of it, or a hard link) is refused before anything is
/// written, and the input is kept byte for byte: a log, a configuration,
/// a telemetry stream and a measured run.
#[test]
fn an_output_that_is_one_of_the_commands_inputs_is_refused_and_the_input_kept() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulated(dir.path(), "jae-ident", 3.0, "run.csv");
    let config = dir.path().join("c.toml");
    run_ok(
        host_sim()
            .args(["identify", "--procedure", "jae", "--log"])
            .arg(&log)
            .arg("--config-out")
            .arg(&config),
    );
    let stream = dir.path().join("tlm.txt");
    std::fs::write(&stream, telemetry_text(2000.0, 20)).unwrap();
    let measured = dir.path().join("00.TXT");
    let t_s: Vec<f64> = (0..20).map(|k| f64::from(k) * 1e-3).collect();
    std::fs::write(&measured, mrdlab_text(&["run"], &t_s)).unwrap();
    let linked = dir.path().join("linked.csv");
    std::fs::hard_link(&log, &linked).unwrap();
    let respelled = dir.path().join(".").join("run.csv");
    // Each command as its words (the temporary paths have no spaces).
    let (l, c, s, m) = (
        log.display(),
        config.display(),
        stream.display(),
        measured.display(),
    );
    let cases: Vec<(String, &Path)> = vec![
        (format!("estimate --log {l} --out {l}"), &log),
        (
            format!("estimate --log {l} --out {}", respelled.display()),
            &log,
        ),
        (
            format!("estimate --log {l} --out {}", linked.display()),
            &log,
        ),
        (
            format!("estimate --log {l} --config {c} --out {c}"),
            &config,
        ),
        (
            format!("identify --procedure jae --log {l} --config-out {l}"),
            &log,
        ),
        (format!("ingest {s} --out {s}"), &stream),
        (format!("import mrdlab {m} --out {m}"), &measured),
    ];
    for (args, input) in &cases {
        let before = std::fs::read(input).unwrap();
        let listing = dir_entries(dir.path());
        let err = run_err(host_sim().args(args.split(' ')));
        assert!(
            err.contains("is also an input of this command"),
            "{args:?}: {err}"
        );
        assert_eq!(
            std::fs::read(input).unwrap(),
            before,
            "{args:?} changed its input"
        );
        assert_eq!(
            dir_entries(dir.path()),
            listing,
            "{args:?} left a file behind"
        );
    }
}

#[test]
fn an_output_directory_that_is_a_file_is_refused_with_that_reason() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("out");
    std::fs::write(&file, "keep\n").unwrap();
    for cmd in [
        &["report", "--quiet", "--out"][..],
        &["undeclared", "--out"][..],
    ] {
        let err = run_err(host_sim().args(cmd).arg(&file));
        assert!(
            err.contains("exists and is not a directory"),
            "{cmd:?}: {err}"
        );
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep\n");
}

/// A validation log that is also fitted (here under another spelling of
/// its path, then as a copy under another name) is refused by `residual`
/// and `identify`: a model scored on its own data says nothing about data
/// it has not seen (`identify` per model: a log fitted for the JAE may
/// validate B_m). Nothing written.
#[test]
fn validating_on_a_fitted_log_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = simulated(d, "track-motor", 3.0, "run.csv");
    let other = simulated(d, "track-motor", 3.0, "other.csv");
    let twin = d.join(".").join("run.csv");
    let config = d.join("c.toml");
    // `command` with each (flag, file) and `--config-out`: its error.
    let refused = |command: &[&str], roles: &[(&str, &Path)]| -> String {
        let mut cmd = host_sim();
        cmd.args(command);
        for (flag, file) in roles {
            cmd.arg(flag).arg(file);
        }
        run_err(cmd.arg("--config-out").arg(&config))
    };
    let residual = ["residual", "--model", "jae"];
    let identify = ["identify", "--procedure", "jae"];
    let err = refused(
        &residual,
        &[("--log", &log), ("--log", &other), ("--validate", &twin)],
    );
    assert!(err.contains("is also a fitted log"), "{err}");
    let err = refused(&identify, &[("--log", &log), ("--validate", &twin)]);
    assert!(err.contains("is also a fitted log"), "{err}");
    assert!(!config.exists(), "nothing written");
    // A test log must have been neither fitted nor used to choose a term.
    let third = simulated(d, "track-motor", 3.0, "third.csv");
    for (used, what) in [
        (&twin, "is also a fitted log"),
        (&other, "is also a --validate log"),
    ] {
        let err = refused(
            &residual,
            &[
                ("--log", &log),
                ("--validate", &other),
                ("--test", &third),
                ("--test", used),
            ],
        );
        assert!(err.contains(what) && err.contains("--test"), "{err}");
        assert!(!config.exists(), "nothing written");
    }
    // The same run under another name (a copy) passes the path checks; its
    // data do not, in any role.
    let copy = d.join("copy.csv");
    std::fs::copy(&log, &copy).unwrap();
    let fresh = simulated_with(d, "track-motor", 3.0, "fresh.csv", &["--seed", "99"]);
    for (roles, what) in [
        (
            ["--log", "--validate", "--test"],
            "--validate copy.csv holds the same data as run.csv",
        ),
        (
            ["--log", "--test", "--validate"],
            "--test copy.csv holds the same data as run.csv",
        ),
        (
            ["--validate", "--test", "--log"],
            "--test copy.csv holds the same data as run.csv",
        ),
    ] {
        let files = [log.as_path(), copy.as_path(), fresh.as_path()];
        let given: Vec<(&str, &Path)> = roles.into_iter().zip(files).collect();
        let err = refused(&residual, &given);
        assert!(err.contains(what), "{what}: {err}");
        assert!(!config.exists(), "nothing written");
    }
    let err = refused(
        &residual,
        &[("--log", &log), ("--log", &copy), ("--validate", &fresh)],
    );
    assert!(
        err.contains("--log copy.csv holds the same data as run.csv"),
        "{err}"
    );
    assert!(err.contains("fitted twice"), "{err}");
    let err = refused(&identify, &[("--log", &log), ("--validate", &copy)]);
    assert!(err.contains("holds the same data as"), "{err}");
    assert!(!config.exists(), "nothing written");
}

/// `host-sim residual ... | head`: the reader of standard output goes away
/// before the command has printed its table. The command still writes
/// every file it was asked for and exits as it would have; it does not
/// panic on the closed pipe (as `println!` does) before writing them.
#[test]
fn a_reader_that_goes_away_does_not_cost_the_commands_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = simulated(d, "track-motor", 3.0, "run.csv");
    let (config, json) = (d.join("c.toml"), d.join("r.json"));
    let mut child = host_sim()
        .args(["residual", "--model", "jae", "--log"])
        .arg(&log)
        .arg("--config-out")
        .arg(&config)
        .arg("--json")
        .arg(&json)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("host-sim runs");
    // Close the only read end before the command writes anything.
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("host-sim ends");
    let err = stderr(&out);
    assert!(out.status.success(), "exit {:?}: {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
    assert!(config.is_file() && json.is_file(), "{:?}", dir_entries(d));
    let text = std::fs::read_to_string(&json).unwrap();
    assert!(text.trim_end().ends_with('}'), "a whole JSON report");
}

#[cfg(unix)]
#[test]
fn outputs_refuse_a_fifo_and_new_files_are_mode_0644() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = d.join("pipe.csv");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let err = run_err(
        host_sim()
            .args(["simulate", "--scenario", "track-motor", "--duration", "0.5"])
            .arg("--out")
            .arg(&fifo),
    );
    assert!(
        err.contains(&fifo.display().to_string()) && err.contains("FIFO"),
        "{err}"
    );
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());

    let log = simulated(d, "track-motor", 3.0, "run.csv");
    let config = d.join("c.toml");
    let json = d.join("r.json");
    run_ok(
        host_sim()
            .args(["residual", "--model", "jae", "--log"])
            .arg(&log)
            .arg("--config-out")
            .arg(&config)
            .arg("--json")
            .arg(&json),
    );
    for p in [&log, &config, &json] {
        assert_eq!(mode(p), 0o644, "{}", p.display());
    }
}

// --- import --------------------------------------------------------------

/// A synthetic MRDLab run: `header` lines (without `%`), then one data line
/// per time in `t_s` (every other field a small count).
fn mrdlab_text(header: &[&str], t_s: &[f64]) -> String {
    let mut s = String::new();
    for h in header {
        s.push_str(&format!("%{h}\n"));
    }
    for (k, t) in t_s.iter().enumerate() {
        s.push_str(&format!("{t:e},{k},0.5,0.1,{k},0.2,0,0.1,{},0\n", 3 * k));
    }
    s
}

fn import(input: &Path, out: &Path) -> Output {
    run(host_sim()
        .args(["import", "mrdlab"])
        .arg(input)
        .arg("--out")
        .arg(out))
}

#[test]
fn import_reads_a_header_with_non_ascii_text_before_a_number() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("22.TXT");
    let t: Vec<f64> = (0..20).map(|k| k as f64 * 1e-3).collect();
    let header = ["input sine at ≈0.30 Hz, amplitude of ±30.00 degrees"];
    std::fs::write(&input, mrdlab_text(&header, &t)).unwrap();
    let out = import(&input, &dir.path().join("o.csv"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stdout.contains("(0.3 Hz"), "{stdout}");
}

#[test]
fn import_writes_sub_nanosecond_times_its_reader_accepts() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("run.TXT");
    let t: Vec<f64> = (0..20).map(|k| 5.0 + k as f64 * 2e-10).collect();
    std::fs::write(&input, mrdlab_text(&[], &t)).unwrap();
    let csv = dir.path().join("o.csv");
    let out = import(&input, &csv);
    assert!(out.status.success(), "{}", stderr(&out));
    let back = host_sim::log::Log::read_with(&csv, &host_sim::import::mrdlab_schema())
        .expect("the reader accepts what import wrote");
    assert_eq!(back.len(), 20);
}

#[test]
fn import_errors_name_the_input_file_and_line_not_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("run.TXT");
    let t: Vec<f64> = (0..20).map(|k| k as f64 * 1e-3).collect();
    // A finite first motor count that makes the next ones overflow once
    // rebased and scaled to radians.
    let text = mrdlab_text(&["a header line"], &t).replacen(",0,0\n", ",-1.7e308,0\n", 1);
    std::fs::write(&input, text).unwrap();
    let csv = dir.path().join("o.csv");
    let out = import(&input, &csv);
    assert!(!out.status.success());
    let err = stderr(&out);
    // The second data row is on line 3 of the input.
    assert!(
        err.contains(&format!(
            "{}:3: column \"9: motor encoder\"",
            input.display()
        )),
        "{err}"
    );
    assert!(!err.contains("o.csv"), "{err}");
    assert!(!csv.exists());
}

#[test]
fn a_huge_cell_is_not_copied_into_the_message() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("run.TXT");
    let t: Vec<f64> = (0..20).map(|k| k as f64 * 1e-3).collect();
    let huge = "9".repeat(1_000_000) + "x";
    let text = mrdlab_text(&[], &t).replacen("0.5,", &format!("{huge},"), 1);
    std::fs::write(&input, text).unwrap();
    let out = import(&input, &dir.path().join("o.csv"));
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.len() < 400, "{} bytes of stderr", err.len());
    assert!(err.contains("…\" (1000001 bytes) is not a number"), "{err}");
    assert!(
        err.contains("run.TXT:1: column \"3: input torque\""),
        "{err}"
    );
}

// --- Durations, rates and numeric options --------------------------------

#[test]
fn simulate_and_trace_refuse_a_duration_beyond_the_tick_limit_or_too_short_for_a_log() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let err = run_err(
        host_sim()
            .args([
                "simulate",
                "--scenario",
                "track-motor",
                "--duration",
                "1e12",
            ])
            .arg("--out")
            .arg(&csv),
    );
    assert!(
        err.contains("--duration 1000000000000") && err.contains("at most 1000000 ticks"),
        "{err}"
    );
    let err = run_err(
        host_sim()
            .args([
                "simulate",
                "--scenario",
                "loading",
                "--duration-scale",
                "1e6",
            ])
            .arg("--out")
            .arg(&csv),
    );
    assert!(
        err.contains("--duration-scale") && err.contains("at most 1000000 ticks"),
        "{err}"
    );
    // Too short for a log the other commands read: refused, naming the
    // option, however short (down to a duration that scales to nothing).
    for (opt, value, says) in [
        ("--duration", "1e-9", "a log needs at least 10 rows"),
        ("--duration", "5e-324", "too short a part of the scenario's"),
        ("--duration-scale", "1e-9", "a log needs at least 10 rows"),
    ] {
        let err = run_err(
            host_sim()
                .args(["simulate", "--scenario", "track-jae", opt, value])
                .arg("--out")
                .arg(&csv),
        );
        assert!(
            err.contains(opt) && err.contains(says),
            "{opt} {value}: {err}"
        );
    }
    let bin = dir.path().join("trace.bin");
    for opt in ["--duration-s", "--relax-s"] {
        let err = run_err(host_sim().args(["trace", opt, "1e12", "--out"]).arg(&bin));
        assert!(
            err.contains(opt) && err.contains("at most 1000000 ticks"),
            "{err}"
        );
    }
    assert!(dir_entries(dir.path()).is_empty());
}

/// A decoded defmt text: a start record at `rate_hz`, then `ticks` tick
/// records.
fn telemetry_text(rate_hz: f32, ticks: u32) -> String {
    use cable_joint::telemetry::{Record, StartRecord, TickRecord, FORMAT_VERSION, MAX_RECORD_LEN};
    let mut records = vec![Record::Start(StartRecord {
        version: FORMAT_VERSION,
        control_rate_hz: rate_hz,
        decimation: 1,
    })];
    records.extend((1..=ticks).map(|k| {
        Record::Tick(TickRecord {
            tick: k,
            ..Default::default()
        })
    }));
    let mut text = String::from("INFO  firmware up\n");
    for r in &records {
        let mut buf = [0u8; MAX_RECORD_LEN];
        let bytes: Vec<String> = r.encode(&mut buf).iter().map(|b| b.to_string()).collect();
        text.push_str(&format!("0.000500 INFO  tlm [{}]\n", bytes.join(", ")));
    }
    text
}

#[test]
fn ingest_refuses_an_impossible_rate_and_a_log_too_short_to_read() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("tlm.txt");
    let csv = dir.path().join("run.csv");
    std::fs::write(&input, telemetry_text(1.4e-45, 20)).unwrap();
    let err = run_err(host_sim().arg("ingest").arg(&input).arg("--out").arg(&csv));
    assert!(
        err.contains(&format!("{}: ", input.display()))
            && err.contains("control rate of 0.000000000000000000000000000000000000000000001 Hz")
            && err.contains("between 100 and 20000 Hz"),
        "{err}"
    );
    std::fs::write(&input, telemetry_text(2000.0, 1)).unwrap();
    let err = run_err(host_sim().arg("ingest").arg(&input).arg("--out").arg(&csv));
    assert!(
        err.contains(&format!("{}: 1 tick records", input.display())),
        "{err}"
    );
    assert!(!csv.exists());
    // The same stream, long enough, is a log the other commands read.
    std::fs::write(&input, telemetry_text(2000.0, 20)).unwrap();
    run_ok(host_sim().arg("ingest").arg(&input).arg("--out").arg(&csv));
    assert_eq!(host_sim::log::Log::read(&csv).unwrap().len(), 20);
}

/// A stream out of order or restarted is refused naming the line of the
/// record where it goes wrong.
#[test]
fn ingest_names_the_line_of_a_tick_out_of_order_and_of_a_second_start() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("tlm.txt");
    let csv = dir.path().join("run.csv");
    // Line 1 a message, line 2 the start record, lines 3 to 22 ticks 1 to 20.
    let text = telemetry_text(2000.0, 20);
    let mut lines: Vec<&str> = text.lines().collect();
    // Tick 10 (line 12) moved after tick 15: line 17.
    let late = lines.remove(11);
    lines.insert(16, late);
    std::fs::write(&input, lines.join("\n") + "\n").unwrap();
    let err = run_err(host_sim().arg("ingest").arg(&input).arg("--out").arg(&csv));
    assert!(
        err.contains(&format!(
            "{}: line 17: tick 10 after tick 15",
            input.display()
        )),
        "{err}"
    );
    let restarted = format!("{text}{}\n", text.lines().nth(1).unwrap());
    std::fs::write(&input, restarted).unwrap();
    let err = run_err(host_sim().arg("ingest").arg(&input).arg("--out").arg(&csv));
    assert!(
        err.contains(&format!(
            "{}: line 23: a second start record",
            input.display()
        )),
        "{err}"
    );
    assert!(!csv.exists());
    // From standard input (`-`), the same line and the stream named as
    // such in every message.
    let piped = |text: &str| {
        let mut child = host_sim()
            .args(["ingest", "-", "--out"])
            .arg(&csv)
            .stdin(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        child
            .stdin
            .take()
            .unwrap()
            .write_all(text.as_bytes())
            .unwrap();
        let out = child.wait_with_output().unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = piped(&(lines.join("\n") + "\n"));
    assert!(
        err.contains("standard input: line 17: tick 10 after tick 15"),
        "{err}"
    );
    let err = piped("no record here\n");
    assert!(err.contains("standard input: no telemetry record"), "{err}");
    assert!(!csv.exists());
}

#[test]
fn every_numeric_option_refuses_non_finite_and_out_of_range_values() {
    // (subcommand and its required arguments, option, a bad finite value)
    let cases: &[(&[&str], &str, &str)] = &[
        (&["simulate", "--scenario", "loading"], "--angle-deg", "1e9"),
        (&["simulate", "--scenario", "loading"], "--mass-g", "-5"),
        (&["simulate", "--scenario", "loading"], "--duration", "-1"),
        (
            &["simulate", "--scenario", "loading"],
            "--duration-scale",
            "0",
        ),
        (&["trace"], "--duration-s", "0"),
        (&["trace"], "--relax-s", "-1"),
        (&["trace"], "--load-n", "1e9"),
        (&["trace"], "--load-at-s", "-1"),
        (&["trace"], "--drive-fault-at-s", "1e300"),
        (
            &[
                "identify",
                "--procedure",
                "jae",
                "--log",
                "a.csv",
                "--config-out",
                "c.toml",
            ],
            "--skip-start-s",
            "-1",
        ),
        (
            &[
                "identify",
                "--procedure",
                "jae",
                "--log",
                "a.csv",
                "--config-out",
                "c.toml",
            ],
            "--min-joint-vel-rad-s",
            "-1",
        ),
        (
            &[
                "identify",
                "--procedure",
                "jae",
                "--log",
                "a.csv",
                "--config-out",
                "c.toml",
            ],
            "--holdoff-s",
            "-1",
        ),
        (
            &[
                "identify",
                "--procedure",
                "jae",
                "--log",
                "a.csv",
                "--config-out",
                "c.toml",
            ],
            "--max-pct-sigma",
            "0",
        ),
        (
            &[
                "identify",
                "--procedure",
                "jae",
                "--log",
                "a.csv",
                "--config-out",
                "c.toml",
            ],
            "--post-filter-hz",
            "1e9",
        ),
        (
            &["residual", "--model", "jae", "--log", "a.csv"],
            "--holdout",
            "1",
        ),
        (
            &["residual", "--model", "jae", "--log", "a.csv"],
            "--min-gain",
            "2",
        ),
        (
            &["residual", "--model", "jae", "--log", "a.csv"],
            "--t-max",
            "0",
        ),
        (
            &["residual", "--model", "jae", "--log", "a.csv"],
            "--settle",
            "-1",
        ),
        (&["report"], "--duration-scale", "0"),
        (&["payload"], "--accel-lag-ms", "1e9"),
        (&["payload"], "--lowpass-hz", "1e9"),
        (&["payload"], "--creep-taus", "0"),
        (&["payload"], "--tare-s", "-1"),
        (&["payload"], "--creep-taus", "-5"),
        (&["link", "--scenario", "jae-ident"], "--start-at", "-1"),
        (&["report", "--draws", "1-2"], "--draw-rate-hz", "-5"),
        (&["simulate-wrist", "--out", "w"], "--grasp", "-2"),
        (
            &["simulate-wrist", "--out", "w", "--grasp", "2"],
            "--object-stiffness",
            "-5",
        ),
        (
            &[
                "estimate-wrist",
                "--run",
                "w",
                "--jaw-open-deg",
                "20",
                "--out",
                "f.csv",
            ],
            "--gravity",
            "-200",
        ),
    ];
    for (cmd, opt, bad) in cases {
        for value in ["NaN", "inf", bad] {
            let err = run_err(host_sim().args(*cmd).arg(format!("{opt}={value}")));
            assert!(
                err.contains(&format!("invalid value '{value}' for '{opt}")),
                "{cmd:?} {opt} {value}: {err}"
            );
        }
        // A negative value after a space reaches the option's own range
        // check too (clap would take `-0.3` for an unknown flag `-0`).
        if bad.starts_with('-') {
            let err = run_err(host_sim().args(*cmd).args([opt, bad]));
            assert!(
                err.contains(&format!("invalid value '{bad}' for '{opt}")),
                "{cmd:?} {opt} {bad}: {err}"
            );
        }
    }
    // Integer options: out of range (a non-number is refused by the parser).
    for (opt, bad) in [
        ("--max-terms", "99"),
        ("--patience", "1e9"),
        ("--decimate", "0"),
    ] {
        let err = run_err(
            host_sim()
                .args(["residual", "--model", "jae", "--log", "a.csv"])
                .args([opt, bad]),
        );
        assert!(
            err.contains(&format!("invalid value '{bad}' for '{opt}")),
            "{opt}: {err}"
        );
    }
}

// --- Rows left out ---------------------------------------------------------

/// `log` with column `col` set to `value` (`None`: not measured) on data
/// row `row`, written to `dir/name`.
fn with_cell(log: &Path, col: &str, row: usize, value: Option<f64>, name: &str) -> PathBuf {
    let mut l = host_sim::log::Log::read(log).unwrap();
    let mut c = l.col_opt(col).unwrap();
    c[row] = value;
    l.set_col_opt(col, &c).unwrap();
    let path = log.with_file_name(name);
    l.write(&path).unwrap();
    path
}

/// Rows the fit named `model` reports on stdout (`model: N rows, ...`).
fn fit_rows(stdout: &str, model: &str) -> usize {
    let line = stdout
        .lines()
        .find(|l| l.starts_with(model))
        .unwrap_or_else(|| panic!("no `{model}` line in {stdout}"));
    line[model.len()..]
        .trim_start_matches(|c: char| !c.is_ascii_digit())
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

fn identify(log: &Path, procedure: &str) -> Output {
    let out = run(host_sim()
        .args(["identify", "--procedure", procedure, "--log"])
        .arg(log)
        .arg("--config-out")
        .arg(log.with_extension("toml")));
    assert!(out.status.success(), "{}", stderr(&out));
    out
}

#[test]
fn identify_leaves_out_one_row_for_an_empty_theta_rad_cell_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path(), "jae-ident", 3.0, "jae.csv");
    let gap = with_cell(&clean, "theta_rad", 1000, None, "gap.csv");
    let model = "JAE (Eq. 25-26):";
    let n_clean = fit_rows(
        &String::from_utf8_lossy(&identify(&clean, "jae").stdout),
        model,
    );
    let out = identify(&gap, "jae");
    let n_gap = fit_rows(&String::from_utf8_lossy(&out.stdout), model);
    assert_eq!(n_gap, n_clean - 1);
    let err = stderr(&out);
    assert!(
        err.contains(&format!(
            "warning: {}: the JAE fit uses {n_gap} of",
            gap.display()
        )) && err
            .contains("1 with column theta_rad not measured or not finite (first at line 1002)"),
        "{err}"
    );
}

#[test]
fn identify_warns_when_a_replay_fault_leaves_rows_out() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path(), "tension-ident", 3.0, "ten.csv");
    // Slider 1's grating jumps a centimetre in one row: an encoder jump
    // the core latches as a fault (a current beyond the DAC's range, the
    // cause this test used before, is now refused up front).
    let x1 = host_sim::log::Log::read(&clean)
        .unwrap()
        .col_required("x1_m")
        .unwrap()[3000];
    let jump = with_cell(&clean, "x1_m", 3000, Some(x1 + 0.01), "jump.csv");
    let err = stderr(&identify(&jump, "tension"));
    assert!(
        err.contains(&format!(
            "warning: {}: the tension fit uses",
            jump.display()
        )) && err.contains("from where the replay latched")
            && err.contains("line 3002"),
        "{err}"
    );
    // The clean log leaves no row out (the configuration's own warning,
    // that the parameters not fitted here are the datasheet plant's, is
    // about something else).
    let clean_err = stderr(&identify(&clean, "tension"));
    assert!(
        !clean_err.contains("fit uses") && !clean_err.contains("latched"),
        "{clean_err}"
    );
}

/// `log` with `fault_code` set to `code` from data row `from` on (the
/// firmware latched a fault there), and `fw_phase` to `phase` on every
/// row when given, written to `dir/name`.
fn with_firmware_fault(
    log: &Path,
    from: usize,
    code: f64,
    phase: Option<f64>,
    name: &str,
) -> PathBuf {
    let mut l = host_sim::log::Log::read(log).unwrap();
    let n = l.len();
    let fault = (0..n).map(|k| if k >= from { code } else { 0.0 }).collect();
    l.set_col("fault_code", fault).unwrap();
    if let Some(p) = phase {
        l.set_col("fw_phase", vec![p; n]).unwrap();
    }
    let path = log.with_file_name(name);
    l.write(&path).unwrap();
    path
}

#[test]
fn identify_fits_only_the_rows_before_the_firmwares_fault_and_refuses_a_failed_start_up() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path(), "tension-ident", 3.0, "ten.csv");
    // A fault of the board's own (a command timeout) at row 4000: the core
    // does not latch it again on replay, so only the recorded code can end
    // the fit there. The fit must be the one of the first 4000 rows.
    let faulted = with_firmware_fault(&clean, 4000, 24.0, None, "faulted.csv");
    let cut = dir.path().join("cut.csv");
    let whole = host_sim::log::Log::read(&clean).unwrap();
    whole.rows(0..4000).write(&cut).unwrap();
    let out = identify(&faulted, "tension");
    let err = stderr(&out);
    assert!(
        err.contains(&format!(
            "identify: {}: the firmware latched",
            faulted.display()
        )) && err.contains("(code 24) at line 4002")
            && err.contains(&format!("the {} rows from there on", whole.len() - 4000)),
        "{err}"
    );
    identify(&cut, "tension");
    let read = |p: &Path| std::fs::read_to_string(p.with_extension("toml")).unwrap();
    assert_eq!(read(&faulted), read(&cut));
    let model = "simplified model C (Eq. 28-29):";
    assert_eq!(
        fit_rows(&String::from_utf8_lossy(&out.stdout), model),
        fit_rows(
            &String::from_utf8_lossy(&identify(&cut, "tension").stdout),
            model
        )
    );
    // Start-up that never ended (homing failed: phase 3 throughout, fault
    // 23 latched at row 1000): refused by identify, estimate and residual,
    // naming the file and the fault, and nothing written.
    let failed = with_firmware_fault(&clean, 1000, 23.0, Some(3.0), "failed.csv");
    let config_out = dir.path().join("failed-out.toml");
    let est_out = dir.path().join("failed-est.csv");
    for cmd in [
        host_sim()
            .args(["identify", "--procedure", "tension", "--log"])
            .arg(&failed)
            .arg("--config-out")
            .arg(&config_out),
        host_sim()
            .args(["estimate", "--log"])
            .arg(&failed)
            .arg("--out")
            .arg(&est_out),
        host_sim()
            .args(["residual", "--model", "tension", "--log"])
            .arg(&failed)
            .arg("--config-out")
            .arg(&config_out),
    ] {
        let err = run_err(cmd);
        assert!(
            err.contains(&failed.display().to_string())
                && err.contains("never reaches 4 (running)")
                && err.contains("(code 23) at line 1002"),
            "{err}"
        );
    }
    assert!(!config_out.exists() && !est_out.exists());
}

/// `--procedure all` without a no-load motor run (it needs the rope wheel
/// unhooked; issue 9 makes it optional): the JAE and the tension model are
/// identified, `B_m` stays the starting configuration's and a note says
/// so; a bm= log to validate on without one to fit is refused.
#[test]
fn identify_all_without_a_no_load_motor_run_keeps_b_m_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let jae = simulated(dir.path(), "jae-ident", 6.0, "jae.csv");
    let ten = simulated(dir.path(), "tension-ident", 6.0, "ten.csv");
    let start = dir.path().join("start.toml");
    std::fs::write(&start, "[dob]\nviscous_nm_s_rad = 2.5e-5\n").unwrap();
    let out_toml = dir.path().join("id.toml");
    let tagged = |extra: &[&str]| {
        let mut c = host_sim();
        c.args(["identify", "--procedure", "all", "--config"])
            .arg(&start)
            .arg("--log")
            .arg(format!("jae={}", jae.display()))
            .arg(format!("tension={}", ten.display()))
            .args(extra)
            .arg("--config-out")
            .arg(&out_toml);
        c
    };
    let err = run_ok(&mut tagged(&[]));
    assert!(
        err.contains("no bm= log: B_m is not identified")
            && err.contains("viscous_nm_s_rad = 2.5e-5"),
        "{err}"
    );
    let written = host_sim::io::config::load_config(&out_toml).unwrap();
    let datasheet = cable_joint::Config::default();
    assert_eq!(written.dob.viscous_nm_s_rad, 2.5e-5);
    assert_ne!(written.tension.f_sc1_n, datasheet.tension.f_sc1_n);
    assert_ne!(written.stretch.cable1_n_m, datasheet.stretch.cable1_n_m);
    std::fs::remove_file(&out_toml).unwrap();
    let bm_val = format!("bm={}", jae.display());
    let err = run_err(&mut tagged(&["--validate", &bm_val]));
    assert!(err.contains("no bm= log to fit B_m on"), "{err}");
    assert!(!out_toml.exists());
}

#[test]
fn residual_names_left_out_rows_and_why_there_are_no_validation_rows() {
    let dir = tempfile::tempdir().unwrap();
    let fit = simulated(dir.path(), "jae-ident", 3.0, "fit.csv");
    let gap = with_cell(&fit, "theta_rad", 500, None, "gap.csv");
    let out = run(host_sim()
        .args(["residual", "--model", "jae", "--log"])
        .arg(&gap));
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(
            "warning: gap.csv: column theta_rad is not measured on 1 of 6000 rows (first at line 502)"
        ),
        "{}",
        stderr(&out)
    );
    // A validation log without a single magnetic-encoder reading.
    let mut l = host_sim::log::Log::read(&fit).unwrap();
    l.set_col_opt("theta_rad", &vec![None; l.len()]).unwrap();
    let blind = dir.path().join("blind.csv");
    l.write(&blind).unwrap();
    let err = run_err(
        host_sim()
            .args(["residual", "--model", "jae", "--log"])
            .arg(&fit)
            .arg("--validate")
            .arg(&blind),
    );
    assert!(
        err.contains(
            "no validation rows: blind.csv: lines 2..6001 (6000 rows), none usable \
             (the first, line 2: \"theta_rad\" is not finite)"
        ),
        "{err}"
    );
}

/// A generic fit whose input has one empty cell: that row is left out and
/// said so, and the input's derived velocity holds the last reading instead
/// of turning every later row into NaN (398 of 600 validation rows were
/// lost silently before).
#[test]
fn a_generic_fit_with_an_empty_input_cell_loses_that_row_only_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let fit = simulated(dir.path(), "jae-ident", 3.0, "fit.csv");
    let gap = with_cell(&fit, "x2_m", 500, None, "gap.csv");
    let out = run(host_sim()
        .args([
            "residual",
            "--target",
            "theta_rad",
            "--inputs",
            "x2_m",
            "--log",
        ])
        .arg(&gap));
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(
            "warning: gap.csv: column x2_m is not measured on 1 of 6000 rows (first at line 502)"
        ),
        "{}",
        stderr(&out)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("4199 fitting rows, 1800 validation rows"),
        "{text}"
    );
}

/// `estimate` on a log whose current command is beyond the core's `f32`
/// range (and so beyond the DAC's) names the input file, line and cell,
/// not the output file; so on a reference force beyond any the joint can
/// carry (a hundred times its drive's 54.6 N squeeze: 1e300 N, 1e30 N,
/// 6 kN), while a large but possible one (500 N, the joint back-driven)
/// is taken.
#[test]
fn estimate_names_a_current_beyond_the_drives_range_and_a_reference_beyond_any_force_carried() {
    let dir = tempfile::tempdir().unwrap();
    let fit = simulated(dir.path(), "jae-ident", 3.0, "fit.csv");
    let bad = with_cell(&fit, "i_ref_a", 3000, Some(1e308), "bad.csv");
    let est = dir.path().join("est.csv");
    let err = run_err(
        host_sim()
            .args(["estimate", "--log"])
            .arg(&bad)
            .arg("--out")
            .arg(&est),
    );
    assert!(
        err.contains("bad.csv")
            && err.contains("line 3002: column \"i_ref_a\" = 1e308 A is beyond")
            && !err.contains("est.csv"),
        "{err}"
    );
    assert!(!est.exists(), "nothing written");
    for (value, text) in [(1e300, "1e300"), (1e30, "1e30"), (-6000.0, "-6000")] {
        let bad = with_cell(&fit, "f_ext_n", 100, Some(value), "bad_ref.csv");
        let err = run_err(
            host_sim()
                .args(["estimate", "--log"])
                .arg(&bad)
                .arg("--out")
                .arg(&est),
        );
        assert!(
            err.contains("bad_ref.csv")
                && err.contains(&format!(
                    "line 102: column \"f_ext_n\" = {text} N is beyond any tip force the joint \
                     can carry (100 times the 54.6 N its drive holds"
                )),
            "{err}"
        );
        assert!(!est.exists(), "nothing written");
    }
    let large = with_cell(&fit, "f_ext_n", 100, Some(500.0), "large_ref.csv");
    let out = run(host_sim()
        .args(["estimate", "--log"])
        .arg(&large)
        .arg("--out")
        .arg(&est));
    assert!(out.status.success(), "{}", stderr(&out));
}

/// Holes each short enough to fill but together longer than the replay
/// fills in a log (three of 300 s at 2 kHz: 1.8 million ticks) are refused
/// in a second, naming the longest, not replayed for minutes.
#[test]
fn estimate_refuses_holes_longer_in_all_than_the_replay_fills() {
    let dir = tempfile::tempdir().unwrap();
    let fit = simulated(dir.path(), "jae-ident", 1.0, "fit.csv");
    let mut l = host_sim::log::Log::read(&fit).unwrap();
    let t: Vec<f64> = l
        .col_required("t_s")
        .unwrap()
        .iter()
        .enumerate()
        .map(|(k, t)| t + 300.0 * (k / 500) as f64)
        .collect();
    l.set_col("t_s", t).unwrap();
    let holes = dir.path().join("holes.csv");
    l.write(&holes).unwrap();
    let est = dir.path().join("est.csv");
    let err = run_err(
        host_sim()
            .args(["estimate", "--log"])
            .arg(&holes)
            .arg("--out")
            .arg(&est),
    );
    assert!(
        err.contains("holes.csv")
            && err.contains("misses 1800000 rows in 3 holes")
            && err.contains("at line 502")
            && err.contains("split it"),
        "{err}"
    );
    assert!(!est.exists(), "nothing written");
}

#[test]
fn residual_names_the_file_and_line_of_times_too_large_for_a_sample_period() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("run.TXT");
    // Increasing times whose differences from the first overflow.
    let mut t = vec![-1.7e308];
    t.extend((0..19).map(|k| 1.7e308 * (1.0 + k as f64 * 1e-9)));
    std::fs::write(&input, mrdlab_text(&[], &t)).unwrap();
    let err = run_err(
        host_sim()
            .args(["residual", "--target", "theta_rad", "--log"])
            .arg(&input),
    );
    assert!(
        err.contains(&format!("{}:2: column \"1: time\"", input.display()))
            && err.contains("is not a finite number"),
        "{err}"
    );
    assert!(!err.contains("NaN"), "{err}");
}

#[test]
fn estimate_warns_about_rows_without_a_reference_force() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulated(dir.path(), "loading", 4.0, "load.csv");
    let gap = with_cell(&log, "f_ext_n", 100, None, "gap.csv");
    let out = run(host_sim()
        .args(["estimate", "--log"])
        .arg(&gap)
        .arg("--out")
        .arg(dir.path().join("est.csv")));
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    let rows = host_sim::log::Log::read(&gap).unwrap().len();
    assert!(
        err.contains(&format!(
            "warning: {}: column f_ext_n is not measured on 1 of {rows} rows (first at line 102)",
            gap.display()
        )),
        "{err}"
    );
}

/// `report --duration-scale` is refused up front when one of its runs would
/// exceed the tick limit a simulated run has (it grew past 6 GB before).
#[test]
fn report_refuses_a_duration_scale_beyond_the_tick_limit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rep");
    let err = run_err(
        host_sim()
            .args(["report", "--quiet", "--duration-scale", "100", "--out"])
            .arg(&out),
    );
    assert!(
        err.contains("--duration-scale 100 (scenario") && err.contains("at most 1000000 ticks"),
        "{err}"
    );
    assert!(!out.exists(), "refused before creating anything");
}

/// A 5 MB column name is quoted, not copied, when `residual` lists the
/// columns of a log that lacks the target (5 MB of stderr before).
#[test]
fn residual_quotes_a_huge_column_name_in_its_message() {
    let dir = tempfile::tempdir().unwrap();
    let fit = simulated(dir.path(), "jae-ident", 3.0, "fit.csv");
    let text = std::fs::read_to_string(&fit).unwrap();
    let (header, body) = text.split_once('\n').unwrap();
    let huge = format!("{}_m", "x".repeat(5_000_000));
    let renamed = header.replacen("x1_m", &huge, 1);
    let path = dir.path().join("huge.csv");
    std::fs::write(&path, format!("{renamed}\n{body}")).unwrap();
    let err = run_err(
        host_sim()
            .args(["residual", "--target", "nope", "--log"])
            .arg(&path),
    );
    assert!(
        err.contains("no target column \"nope\""),
        "{}",
        &err[..err.len().min(500)]
    );
    assert!(err.len() < 10_000, "{} bytes of stderr", err.len());
    // The long name is listed, quoted (its first characters and its size).
    let q = host_sim::log::quoted(&huge);
    assert!(q.ends_with(" (5000002 bytes)"), "{q}");
    assert!(err.contains(&q), "{}", &err[..err.len().min(500)]);
}

/// A scenario longer than one simulated run can hold (the seed's loading
/// protocol at 5 kHz: 1.155e6 ticks) is refused before it runs, naming the
/// limit and how to shorten it or run one part; nothing is written.
#[test]
fn a_scenario_too_long_for_one_run_is_refused_with_the_way_to_shorten_it() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("c5k.toml");
    std::fs::write(&config, "control_rate_hz = 5000.0\n").unwrap();
    let out = dir.path().join("loading.csv");
    let e = run_err(
        host_sim()
            .args(["simulate", "--scenario", "loading", "--config"])
            .arg(&config)
            .arg("--out")
            .arg(&out),
    );
    assert!(
        e.contains("scenario loading") && e.contains("at most 1000000 ticks"),
        "{e}"
    );
    assert!(
        e.contains("--duration-scale") && e.contains("--angle-deg"),
        "{e}"
    );
    assert!(!out.exists());
}

/// `estimate-wrist` refuses an Eq. 3 model whose friction sign speed is
/// not positive (a negative one flipped every friction torque, exit 0)
/// and one whose torque on the run goes beyond a hundred times a joint's
/// drive (a Coulomb parameter of 1e30 emptied Eq. 5's total-force bound,
/// exit 0), each naming the file and what is wrong; nothing is written.
/// The model as fitted is taken.
#[test]
fn estimate_wrist_refuses_an_eq3_model_no_wrist_could_have() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p);
    run_ok(host_sim().args(["simulate-wrist", "--out"]).arg(d("free")));
    run_ok(
        host_sim()
            .args(["simulate-wrist", "--grasp", "2", "--out"])
            .arg(d("grasp")),
    );
    let wrist = ["--gravity=-8.496,-4.905,0", "--jaw-open-deg", "20"];
    run_ok(
        host_sim()
            .args(["identify-wrist", "--run"])
            .arg(d("free"))
            .args(wrist)
            .arg("--out")
            .arg(d("eq3.toml")),
    );
    let fitted: toml::Value =
        toml::from_str(&std::fs::read_to_string(d("eq3.toml")).unwrap()).unwrap();
    let edited = |name: &str, key: &str, k: usize, v: f64| {
        let mut t = fitted.clone();
        t["fit"]["body"][key].as_array_mut().unwrap()[k] = toml::Value::Float(v);
        std::fs::write(d(name), toml::to_string(&t).unwrap()).unwrap();
        d(name)
    };
    let estimate = |eq3: &Path| {
        let mut c = host_sim();
        c.args(["estimate-wrist", "--run"])
            .arg(d("grasp"))
            .args(wrist)
            .arg("--eq3")
            .arg(eq3)
            .arg("--out")
            .arg(d("forces.csv"));
        c
    };
    let flipped = edited("flipped.toml", "sign_speed_rad_s", 0, -1.0);
    let err = run_err(&mut estimate(&flipped));
    assert!(
        err.contains("flipped.toml: fit.body.sign_speed_rad_s of joint roll is -1"),
        "{err}"
    );
    // Pitch's Coulomb friction (the grasp moves the pitch, not the roll).
    let huge = edited("huge.toml", "params", 9, 1e30);
    let err = run_err(&mut estimate(&huge));
    assert!(
        err.contains("huge.toml: Eq. 3's torque on joint pitch is")
            && err.contains("beyond a hundred times the 1.092 N·m a joint's drive holds"),
        "{err}"
    );
    assert!(!d("forces.csv").exists(), "nothing written");
    run_ok(&mut estimate(&d("eq3.toml")));
}

/// Options that leave nothing to do are refused before any work and
/// nothing is written: an excitation the limits leave unidentifiable
/// (condition number inf had been written, and run), a trace too short
/// for a log (a header-only trace had been written), an unknown effect
/// for the report (found after seconds of work), an object at 0° (its
/// message had given another range than the option's), `--effect` with
/// `--no-effects`, `undeclared` at a rate the core refuses or with a plant
/// twice.
#[test]
fn options_that_leave_nothing_to_do_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p);
    // The command's words, then its output path.
    let line = |words: &[&str], out: &Path| -> Vec<std::ffi::OsString> {
        words
            .iter()
            .map(Into::into)
            .chain([out.as_os_str().to_owned()])
            .collect()
    };
    let (x, t, r, u) = (d("x.toml"), d("t.bin"), d("r"), d("u"));
    let mut trace = line(&["trace", "--duration-s", "1e-9", "--out"], &t);
    trace.extend(["--csv".into(), d("t.csv").into()]);
    let cases = [
        (
            line(
                &[
                    "excite",
                    "--max-vel-deg-s",
                    "1e-6",
                    "--restarts",
                    "1",
                    "--out",
                ],
                &x,
            ),
            "predicted condition number inf): nothing written",
            &x,
        ),
        (
            trace,
            "0 control ticks at 2000 Hz; a trace needs at least 10",
            &t,
        ),
        (
            line(&["trace", "--object-at-deg", "0", "--out"], &t),
            "--object-at-deg 0: the object's surface must be at a joint angle other than 0 \
             (within ±80°",
            &t,
        ),
        (
            line(&["report", "--effect", "creep,bogus", "--out"], &r),
            "unknown effect `bogus`",
            &r,
        ),
        (
            line(
                &["report", "--no-effects", "--effect", "creep", "--out"],
                &r,
            ),
            "cannot be used with",
            &r,
        ),
        (
            line(&["undeclared", "--rate", "99.5", "--out"], &u),
            "99.5 is outside [100, 20000]",
            &u,
        ),
        (
            line(&["undeclared", "--draw", "31", "31", "--out"], &u),
            "--draw 31 is given twice",
            &u,
        ),
    ];
    for (args, message, output) in cases {
        let err = run_err(host_sim().args(&args));
        assert!(err.contains(message), "{args:?}: {err}");
        assert!(!output.exists(), "{args:?}: {} written", output.display());
    }
    assert!(!d("t.csv").exists());
}

/// `simulate` of a second of `jae-ident` with `file` as its `option`
/// (`--plant`, `--config`), which must fail; its stderr.
fn simulate_refused(option: &str, file: &Path, out: &Path) -> String {
    run_err(
        host_sim()
            .args(["simulate", "--scenario", "jae-ident", "--duration", "1"])
            .arg(option)
            .arg(file)
            .arg("--out")
            .arg(out),
    )
}

/// A plant file is checked as a configuration is, naming the file: the
/// board's zero codes (NaN, -1 and 1e30 had been taken, to latch a
/// current-monitor fault), and an integration step so fine that a run
/// never ends (1e30 Hz had hung `simulate`); a mass too light for the
/// step is named.
#[test]
fn a_plant_file_with_scales_no_board_has_or_an_endless_step_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let plant = dir.path().join("plant.toml");
    let out = dir.path().join("run.csv");
    for (text, message) in [
        (
            "[sensors.scales]\ndac_zero_code = nan\n",
            "plant.sensors.scales.dac_zero_code must be within 0..=4095",
        ),
        (
            "[sensors.scales]\nadc_zero_code = -1.0\n",
            "plant.sensors.scales.adc_zero_code must be within 0..=4095",
        ),
        (
            "[integration]\nstep_hz = 1e30\n",
            "plant.integration.step_hz must be between 20000 and 1e7 Hz",
        ),
    ] {
        std::fs::write(&plant, text).unwrap();
        let err = simulate_refused("--plant", &plant, &out);
        assert!(
            err.contains("plant.toml") && err.contains(message),
            "{text}: {err}"
        );
        assert!(!out.exists());
    }
    // A mass too light for the step names the element that is.
    std::fs::write(&plant, "[slider1]\nmass_kg = 1e-9\n").unwrap();
    let err = simulate_refused("--plant", &plant, &out);
    assert!(
        err.contains("too coarse") && err.contains("(at slider1.mass_kg)"),
        "{err}"
    );
}

/// `identify --procedure bm` refuses a run with the cable attached (grating
/// 1 follows the motor): it had fitted the cable's tension as damping,
/// B_m twice the true one, and written it. A tag with no file is named.
#[test]
fn identify_bm_refuses_a_run_with_the_cable_attached_and_a_tag_without_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let coupled = simulated(dir.path(), "jae-ident", 3.0, "jae.csv");
    let config = dir.path().join("bm.toml");
    let err = run_err(
        host_sim()
            .args(["identify", "--procedure", "bm", "--log"])
            .arg(&coupled)
            .arg("--config-out")
            .arg(&config),
    );
    assert!(
        err.contains("grating 1 moves") && err.contains("the cable is attached"),
        "{err}"
    );
    assert!(!config.exists());
    let err = run_err(
        host_sim()
            .args(["identify", "--procedure", "all", "--log"])
            .arg(format!("jae={}", coupled.display()))
            .arg(format!("tension={}", coupled.display()))
            .arg("bm=")
            .arg("--config-out")
            .arg(&config),
    );
    assert!(err.contains("`bm=` names no file"), "{err}");
}

/// A configuration's refused value is echoed with the field that refused
/// it (the range alone left the user to find what the file gave), and a
/// bad fault limit is named as itself, not as a check that reads it.
#[test]
fn a_refused_configuration_value_is_named_with_what_the_file_gives() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("c.toml");
    let out = dir.path().join("run.csv");
    for (text, message) in [
        (
            "[limits]\nmax_motor_speed_rad_s = -1.0\n",
            "`limits.max_motor_speed_rad_s` must be between 1 and 5000 rad/s (the file gives -1)",
        ),
        (
            "[limits]\nmax_motor_speed_rad_s = nan\n",
            "`limits.max_motor_speed_rad_s` must be between 1 and 5000 rad/s (the file gives NaN)",
        ),
        (
            "[scales]\nadc_zero_code = 5000.0\n",
            "`scales.adc_zero_code` must be within 0..=4095 (the file gives 5000)",
        ),
    ] {
        std::fs::write(&config, text).unwrap();
        let err = simulate_refused("--config", &config, &out);
        assert!(
            err.contains("c.toml") && err.contains(message),
            "{text}: {err}"
        );
        assert!(!out.exists());
    }
}

/// An excitation whose angle leaves the configuration's joint-angle limit
/// (an offset of 3 rad: the run had latched AngleRange and recorded a
/// faulted run, exit 0) is refused before the run, and so is the default
/// design under a configuration whose limit it leaves; the designed one
/// runs.
#[test]
fn an_excitation_beyond_the_joint_angle_limit_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p);
    run_ok(
        host_sim()
            .args(["excite", "--restarts", "1", "--out"])
            .arg(d("ex.toml")),
    );
    let text = std::fs::read_to_string(d("ex.toml")).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("offset_rad = "))
        .expect("the series' offset");
    std::fs::write(d("off.toml"), text.replace(line, "offset_rad = 3.0")).unwrap();
    let simulate = |excitation: &Path| {
        let mut c = host_sim();
        c.args(["simulate", "--scenario", "excite", "--duration", "2"])
            .arg("--excitation")
            .arg(excitation)
            .arg("--out")
            .arg(d("run.csv"));
        c
    };
    let err = run_err(&mut simulate(&d("off.toml")));
    let refused = "the excitation's angle reaches";
    assert!(
        err.contains(refused)
            && err.contains("beyond the configuration's limits.max_joint_angle_rad"),
        "{err}"
    );
    assert!(!d("run.csv").exists());
    run_ok(&mut simulate(&d("ex.toml")));
    // The default design, under a configuration whose limit is narrower
    // than the design's angle (17°).
    std::fs::write(d("narrow.toml"), "[limits]\nmax_joint_angle_rad = 0.3\n").unwrap();
    let err = run_err(
        host_sim()
            .args(["simulate", "--scenario", "excite", "--duration", "2"])
            .arg("--config")
            .arg(d("narrow.toml"))
            .arg("--out")
            .arg(d("narrow.csv")),
    );
    assert!(err.contains(refused) && err.contains("(17.2°)"), "{err}");
    assert!(!d("narrow.csv").exists());
}

/// The reference force is checked by every command that judges an
/// estimate against it, not only `estimate`: `residual --model force` had
/// fitted 1e30 N (a baseline RMSE of 7.7e28 N) and `estimate-wrist` had
/// reported a clamp error of 1.9e28 N from a jaw's log, both exit 0.
#[test]
fn every_command_judging_against_the_reference_refuses_one_beyond_any_force_carried() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p);
    let fit = simulated(dir.path(), "jae-ident", 3.0, "fit.csv");
    let bad = with_cell(&fit, "f_ext_n", 100, Some(1e30), "bad_ref.csv");
    let err = run_err(
        host_sim()
            .args(["residual", "--model", "force", "--log"])
            .arg(&bad)
            .arg("--json")
            .arg(d("r.json")),
    );
    assert!(
        err.contains("bad_ref.csv")
            && err.contains("line 102: column \"f_ext_n\" = 1e30 N is beyond any tip force"),
        "{err}"
    );
    assert!(!d("r.json").exists());
    run_ok(
        host_sim()
            .args(["simulate-wrist", "--grasp", "2", "--out"])
            .arg(d("grasp")),
    );
    let jaw = d("grasp").join("jaw_a.csv");
    let mut log = host_sim::log::Log::read(&jaw).unwrap();
    let mut f = log.col_opt("f_ext_n").unwrap();
    f[5000] = Some(1e30);
    log.set_col_opt("f_ext_n", &f).unwrap();
    log.write(&jaw).unwrap();
    let err = run_err(
        host_sim()
            .args(["estimate-wrist", "--run"])
            .arg(d("grasp"))
            .args(["--gravity=-8.496,-4.905,0", "--jaw-open-deg", "20", "--out"])
            .arg(d("forces.csv")),
    );
    assert!(
        err.contains("jaw_a.csv") && err.contains("line 5002: column \"f_ext_n\" = 1e30 N"),
        "{err}"
    );
    assert!(!d("forces.csv").exists());
    // `identify`'s weights given as steps: the force came from the
    // argument, not from a cell (it had been named as "line N: column
    // f_ext_n" of the log).
    let mut bare = host_sim::log::Log::read(&fit).unwrap();
    bare.remove_col("f_ext_n");
    bare.write(d("bare.csv")).unwrap();
    let arg = format!("{}@0.5=0,1.5=1e30", d("bare.csv").display());
    let err = run_err(
        host_sim()
            .args(["identify", "--procedure", "weights", "--log"])
            .arg(&arg)
            .arg("--config-out")
            .arg(d("w.toml")),
    );
    assert!(
        err.contains(&format!(
            "`{arg}`: the reference step `1.5=1e30` = 1e30 N is beyond any tip force"
        )),
        "{err}"
    );
    assert!(!err.contains("line "), "{err}");
    assert!(!d("w.toml").exists());
}

/// A configuration whose `control_rate_hz` no board runs at (-5, 0,
/// 1e39) is a broken file, refused by `estimate` too (it had taken the
/// log's rate with a warning, as for a file made for another rate).
#[test]
fn estimate_refuses_a_configuration_whose_rate_is_no_control_rate() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulated(dir.path(), "jae-ident", 1.0, "run.csv");
    let config = dir.path().join("c.toml");
    let out = dir.path().join("est.csv");
    for (rate, shown) in [("-5.0", "-5"), ("0.0", "0"), ("1e39", "inf")] {
        std::fs::write(&config, format!("control_rate_hz = {rate}\n")).unwrap();
        let err = run_err(
            host_sim()
                .args(["estimate", "--log"])
                .arg(&log)
                .arg("--config")
                .arg(&config)
                .arg("--out")
                .arg(&out),
        );
        assert!(
            err.contains(&format!(
                "c.toml: control_rate_hz = {shown} is not a control rate"
            )),
            "{rate}: {err}"
        );
        assert!(!out.exists());
    }
}
