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
    let path = dir.join(name);
    run_ok(
        host_sim()
            .args(["simulate", "--tuned-gains", "--scenario", scenario])
            .arg("--duration")
            .arg(seconds.to_string())
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
