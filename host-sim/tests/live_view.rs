//! The live view as a person sees it: `host-sim trace --view` in a real
//! terminal (a tmux pane, 140 × 40), read back with `tmux capture-pane`
//! and driven with `tmux send-keys`.
//!
//! Needs tmux, so the tests are ignored in a plain `cargo test`; `.ci/run`
//! installs tmux and runs them (`cargo test -p host-sim --test live_view
//! -- --ignored`).

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// A tmux server of this test's own (its own socket), killed on drop.
struct Tmux {
    socket: String,
}

impl Tmux {
    /// Start `command` in a detached 140 × 40 session; when it ends, its
    /// exit code goes to `exit_file` and the pane stays for reading.
    fn start(name: &str, command: &str, exit_file: &Path) -> Tmux {
        let tmux = Tmux {
            socket: format!("cable-joint-live-{name}-{}", std::process::id()),
        };
        let script = format!("{command}; echo $? > {}; sleep 600", exit_file.display());
        let ok = tmux
            .cmd(&[
                "new-session",
                "-d",
                "-s",
                "t",
                "-x",
                "140",
                "-y",
                "40",
                &script,
            ])
            .status()
            .expect("tmux runs (install it: apt-get install tmux)")
            .success();
        assert!(ok, "tmux new-session failed");
        tmux
    }

    fn cmd(&self, args: &[&str]) -> Command {
        let mut c = Command::new("tmux");
        c.args(["-L", &self.socket]).args(args);
        c
    }

    /// The pane's text.
    fn capture(&self) -> String {
        let out = self
            .cmd(&["capture-pane", "-p", "-t", "t"])
            .output()
            .expect("tmux capture-pane");
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// Wait until the pane shows `text`; the pane's text then.
    fn wait_for(&self, text: &str, limit: Duration) -> String {
        let start = Instant::now();
        loop {
            let pane = self.capture();
            if pane.contains(text) {
                return pane;
            }
            assert!(
                start.elapsed() < limit,
                "{text:?} not shown within {limit:?}; the pane:\n{pane}"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    fn keys(&self, keys: &str) {
        let ok = self
            .cmd(&["send-keys", "-t", "t", keys])
            .status()
            .expect("tmux send-keys")
            .success();
        assert!(ok, "tmux send-keys failed");
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = self.cmd(&["kill-server"]).status();
    }
}

/// Wait for the command's exit code.
fn exit_code(file: &Path, limit: Duration) -> i32 {
    let start = Instant::now();
    loop {
        if let Ok(s) = std::fs::read_to_string(file) {
            if let Ok(code) = s.trim().parse() {
                return code;
            }
        }
        assert!(
            start.elapsed() < limit,
            "the command did not end within {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn trace_command(dir: &Path, duration_s: f64) -> String {
    format!(
        "{} trace --view --duration-s {duration_s} --drive-fault-at-s -1 --load-n 1 \
         --load-at-s 2.5 --out {}",
        env!("CARGO_BIN_EXE_host-sim"),
        dir.join("trace.bin").display()
    )
}

#[test]
#[ignore = "needs tmux; .ci/run runs it"]
fn the_live_view_shows_the_run_as_it_goes_and_its_end_until_q() {
    let dir = tempfile::tempdir().unwrap();
    let exit = dir.path().join("exit");
    let tmux = Tmux::start("run", &trace_command(dir.path(), 4.0), &exit);

    // While it runs: the header, the three charts with their readouts.
    let pane = tmux.wait_for("phase running", Duration::from_secs(120));
    for want in [
        "cable joint · simulated prototype (host-sim trace) · tick",
        "drive on · fault none",
        "joint angle, deg reference",
        "external force, N estimate",
        "bound [",
        "motor current, A command",
        "q quits",
    ] {
        assert!(pane.contains(want), "{want:?} missing from\n{pane}");
    }
    assert!(
        pane.chars().any(|c| ('\u{2801}'..='\u{28ff}').contains(&c)),
        "no line drawn:\n{pane}"
    );

    // At the end: the last state held, the file written, and q quits.
    let pane = tmux.wait_for("run finished: q quits", Duration::from_secs(120));
    assert!(pane.contains("8000 records"), "{pane}");
    assert!(pane.contains("reference 30.00"), "{pane}");
    assert!(pane.contains("wrote "), "{pane}");
    assert!(
        dir.path().join("trace.bin").exists(),
        "written before the hold"
    );
    tmux.keys("q");
    assert_eq!(exit_code(&exit, Duration::from_secs(30)), 0);
    let pane = tmux.capture();
    assert!(
        pane.contains("wrote "),
        "the summary after the view:\n{pane}"
    );
}

#[test]
#[ignore = "needs tmux; .ci/run runs it"]
fn q_during_the_run_stops_it_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let exit = dir.path().join("exit");
    let tmux = Tmux::start("quit", &trace_command(dir.path(), 300.0), &exit);
    tmux.wait_for("phase ", Duration::from_secs(120));
    tmux.keys("q");
    assert_ne!(exit_code(&exit, Duration::from_secs(30)), 0);
    let pane = tmux.capture();
    assert!(pane.contains("stopped with q at tick"), "{pane}");
    assert!(pane.contains("nothing written"), "{pane}");
    assert!(!dir.path().join("trace.bin").exists());
}
