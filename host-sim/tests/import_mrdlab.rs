//! MRDLab importer on the real runs in `tests/data/mrdlab` (ODbL/DbCL, see
//! the README there): scales and signs checked against physics, not against
//! numbers copied from the output.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

use host_sim::import::{
    import_mrdlab, import_mrdlab_run, mrdlab_schema, read_mrdlab, GEAR_RATIO, MRDLAB_COLUMNS,
};
use host_sim::log::{Log, LogErrorKind};

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mrdlab")
}

fn run_path(name: &str) -> PathBuf {
    data_dir().join(format!("{name}.TXT.gz"))
}

const RUNS: [&str; 12] = [
    "00", "02", "05", "09", "20", "22", "25", "29", "40", "42", "45", "49",
];

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

fn range(x: &[f64]) -> f64 {
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    hi - lo
}

fn corr(a: &[f64], b: &[f64]) -> f64 {
    let (ma, mb) = (mean(a), mean(b));
    let mut sab = 0.0;
    let mut saa = 0.0;
    let mut sbb = 0.0;
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

/// Least squares `y ≈ X β` by the normal equations (columns centred by the
/// caller where it matters); small dense Gauss–Jordan with partial pivoting.
fn lstsq(cols: &[Vec<f64>], y: &[f64]) -> Vec<f64> {
    let n = cols.len();
    let mut m = vec![vec![0.0; n + 1]; n];
    for i in 0..n {
        for j in 0..n {
            m[i][j] = cols[i].iter().zip(&cols[j]).map(|(a, b)| a * b).sum();
        }
        m[i][n] = cols[i].iter().zip(y).map(|(a, b)| a * b).sum();
    }
    for i in 0..n {
        let p = (i..n)
            .max_by(|&a, &b| m[a][i].abs().total_cmp(&m[b][i].abs()))
            .unwrap();
        m.swap(i, p);
        for k in 0..n {
            if k != i {
                let f = m[k][i] / m[i][i];
                let row_i = m[i].clone();
                for (a, b) in m[k].iter_mut().zip(&row_i) {
                    *a -= f * b;
                }
            }
        }
    }
    (0..n).map(|i| m[i][n] / m[i][i]).collect()
}

/// Direction of spindle motion over ±50 ms (the backlash regressor).
fn direction(x: &[f64]) -> Vec<f64> {
    let w = 50;
    (0..x.len())
        .map(|i| {
            let d = x[(i + w).min(x.len() - 1)] - x[i.saturating_sub(w)];
            if d > 0.0 {
                1.0
            } else if d < 0.0 {
                -1.0
            } else {
                0.0
            }
        })
        .collect()
}

#[test]
fn run_22_has_the_schema_timing_and_metadata() {
    let run = import_mrdlab_run(run_path("22")).unwrap();
    let log = &run.log;
    assert_eq!(
        log.names(),
        MRDLAB_COLUMNS,
        "exactly the project columns, in order"
    );
    assert_eq!(log.len(), 20_000, "20 s at 1 kHz");
    let t = log.time_s().unwrap();
    assert_eq!(t[0], 0.0, "time rebased to the first sample");
    for w in t.windows(2) {
        assert!(
            (w[1] - w[0] - 1e-3).abs() < 1e-9,
            "1 kHz sampling: step {} s",
            w[1] - w[0]
        );
    }
    assert!((t[t.len() - 1] - 19.999).abs() < 1e-9);
    for c in ["phi_rad", "spindle_rad", "theta_rad"] {
        assert_eq!(
            log.col(c).unwrap()[0],
            0.0,
            "{c} relative to the first sample"
        );
    }
    let m = &run.meta;
    assert_eq!((m.freq_index, m.torque_index), (Some(2), Some(2)));
    assert_eq!(
        (m.freq_hz, m.amplitude_deg, m.torque_percent),
        (Some(0.3), Some(30.0), Some(30.0))
    );
    assert_eq!(m.header.len(), 12, "all % lines kept");
    // The converted log passes the reader's own checks for its schema.
    log.validate(&mrdlab_schema(), "22").unwrap();
}

#[test]
fn motor_to_spindle_ratio_is_the_35_to_1_gear_on_every_run() {
    for name in RUNS {
        let log = import_mrdlab(run_path(name)).unwrap();
        let phi = log.col("phi_rad").unwrap();
        let sp = log.col("spindle_rad").unwrap();
        let tau = log.col("tau_in_nm").unwrap();
        // Plain slope: biased high by the motor–spindle compliance (the input
        // torque grows with the spindle angle).
        let (ms, mp) = (mean(sp), mean(phi));
        let spc: Vec<f64> = sp.iter().map(|v| v - ms).collect();
        let phc: Vec<f64> = phi.iter().map(|v| v - mp).collect();
        let plain = lstsq(std::slice::from_ref(&spc), &phc)[0];
        assert!(
            plain > GEAR_RATIO && plain < GEAR_RATIO * 1.025,
            "run {name}: plain slope {plain:.3} should be just above 35"
        );
        // With compliance (torque) and backlash (direction) regressors the
        // gear ratio comes out as 35 to within 1 %.
        let dir = direction(sp);
        let ones = vec![1.0; sp.len()];
        let beta = lstsq(&[sp.to_vec(), dir, tau.to_vec(), ones], phi);
        let ratio = beta[0];
        assert!(
            (ratio / GEAR_RATIO - 1.0).abs() < 0.01,
            "run {name}: motor/spindle ratio {ratio:.3}, expected 35 ± 1 %"
        );
        eprintln!("run {name}: plain slope {plain:.3}, with compliance and backlash {ratio:.3}");
        assert!(
            beta[2] > 0.0,
            "run {name}: compliance term {:.3} rad/(N·m) must be positive",
            beta[2]
        );
    }
}

#[test]
fn angles_follow_the_input_sine() {
    for name in RUNS {
        let run = import_mrdlab_run(run_path(name)).unwrap();
        let log = &run.log;
        let sp = log.col("spindle_rad").unwrap();
        let theta = log.col("theta_rad").unwrap();
        let amp_deg = run.meta.amplitude_deg.unwrap();
        // Spindle swings 2 × 30° peak to peak (8192 counts/rev).
        let sp_pp_deg = range(sp).to_degrees();
        assert!(
            (sp_pp_deg / (2.0 * amp_deg) - 1.0).abs() < 0.03,
            "run {name}: spindle peak to peak {sp_pp_deg:.1}°, header says ±{amp_deg}°"
        );
        // The jaw follows the spindle: tens of degrees, same sense, slightly
        // less (cable stretch, friction).
        let jaw_pp_deg = range(theta).to_degrees();
        assert!(
            (40.0..60.0).contains(&jaw_pp_deg),
            "run {name}: jaw peak to peak {jaw_pp_deg:.1}°"
        );
        let r = corr(sp, theta);
        assert!(
            r > 0.99,
            "run {name}: jaw and spindle turn together, corr {r:.4}"
        );
        // Frequency from the data (crossings of the mid level, with
        // hysteresis) agrees with the header.
        let mid = sp.iter().copied().fold(f64::INFINITY, f64::min) + range(sp) / 2.0;
        let band = 0.05 * range(sp);
        let mut state = 0i8;
        let mut crossings = 0u32;
        for &v in sp {
            let s = if v > mid + band {
                1
            } else if v < mid - band {
                -1
            } else {
                state
            };
            if s != state && state != 0 {
                crossings += 1;
            }
            state = s;
        }
        let dur = log.time_s().unwrap().last().unwrap();
        let f_hz = f64::from(crossings) / (2.0 * dur);
        let f_header = run.meta.freq_hz.unwrap();
        assert!(
            (f_hz / f_header - 1.0).abs() < 0.1,
            "run {name}: {crossings} crossings in {dur} s = {f_hz:.3} Hz, header {f_header} Hz"
        );
    }
}

#[test]
fn currents_and_torques_are_plausible_and_consistently_signed() {
    let mut tau_ext_by_level = Vec::new();
    for name in ["20", "22", "25", "29"] {
        let run = import_mrdlab_run(run_path(name)).unwrap();
        let log = &run.log;
        let i = log.col("i_meas_a").unwrap();
        let cmd = log.col("cmd").unwrap();
        let tau_in = log.col("tau_in_nm").unwrap();
        let tau_ext = log.col("tau_ext_nm").unwrap();
        let phi = log.col("phi_rad").unwrap();
        // Small motor: well inside the ±2 A drive limit.
        assert!(
            i.iter().all(|a| a.abs() < 2.0),
            "run {name}: current beyond the drive limit"
        );
        // The command asks for current of its own sign: i ≈ k·cmd, k ≈ 2 A.
        let gain = lstsq(&[cmd.to_vec(), vec![1.0; cmd.len()]], i)[0];
        assert!(
            (1.8..2.3).contains(&gain),
            "run {name}: current per command {gain:.3} A"
        );
        assert!(
            corr(i, cmd) > 0.99,
            "run {name}: current follows the command"
        );
        // Input torque is the motor's: it has the sign of the current
        // (35:1 gear × 23.4 mN·m/A ≈ 0.8 N·m/A nominal at the spindle).
        assert!(
            corr(i, tau_in) > 0.9,
            "run {name}: input torque follows the current"
        );
        let k_spindle = lstsq(&[i.to_vec(), vec![1.0; i.len()]], tau_in)[0];
        assert!(
            (0.3..1.0).contains(&k_spindle),
            "run {name}: spindle torque per amp {k_spindle:.3} N·m/A"
        );
        // Positive current speeds the motor up in the positive direction:
        // current correlates with motor velocity (friction dominates).
        let vel: Vec<f64> = phi.windows(101).map(|w| w[100] - w[0]).collect();
        assert!(
            corr(&i[50..i.len() - 50], &vel) > 0.6,
            "run {name}: current and motor velocity"
        );
        // mN·m range, resistive torque opposing positive jaw rotation.
        for (what, tau) in [("tau_in", tau_in), ("tau_ext", tau_ext)] {
            assert!(
                tau.iter().all(|t| t.abs() < 0.5),
                "run {name}: {what} beyond 0.5 N·m"
            );
        }
        assert!(
            tau_ext.iter().all(|&t| t > -0.01),
            "run {name}: tau_ext must oppose positive rotation"
        );
        tau_ext_by_level.push((
            run.meta.torque_percent.unwrap(),
            mean(tau_ext),
            mean(tau_in),
        ));
    }
    // More resistive torque commanded ⇒ more measured at the jaw, and the
    // motor carries it: mean input torque grows with the load level too.
    for w in tau_ext_by_level.windows(2) {
        assert!(
            w[1].1 > w[0].1,
            "tau_ext grows with the torque level: {tau_ext_by_level:?}"
        );
        assert!(
            w[1].2 > w[0].2,
            "tau_in grows with the torque level: {tau_ext_by_level:?}"
        );
    }
    let (pct, ext, inp) = tau_ext_by_level[3];
    assert_eq!(pct, 100.0);
    assert!(
        (0.05..0.3).contains(&ext),
        "100 % load: mean jaw torque {ext:.3} N·m"
    );
    assert!(
        (inp / ext - 1.0).abs() < 0.3,
        "100 % load: input {inp:.3} vs jaw {ext:.3} N·m"
    );
}

fn decompressed(name: &str) -> String {
    let mut s = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(run_path(name)).unwrap())
        .read_to_string(&mut s)
        .unwrap();
    s
}

/// Replaces 1-based line `line` of `text`.
fn with_line(text: &str, line: usize, new: &str) -> String {
    let mut lines: Vec<&str> = text.lines().collect();
    lines[line - 1] = new;
    lines.join("\n") + "\n"
}

#[test]
fn garbled_lines_are_reported_with_line_and_column() {
    let text = decompressed("22");
    assert!(
        text.lines().nth(12).unwrap().starts_with("0.000,"),
        "12 header lines"
    );
    // Line 500 holds t = 0.487 s.
    let line500 = text.lines().nth(499).unwrap().to_owned();
    let mut cells: Vec<&str> = line500.split(',').collect();
    cells[4] = "1x9";
    let e = read_mrdlab(with_line(&text, 500, &cells.join(",")).as_bytes(), "22.TXT").unwrap_err();
    assert!(matches!(e.kind, LogErrorKind::NotANumber(_)), "{e}");
    assert_eq!(
        e.to_string(),
        r#"22.TXT:500: column "5: jaw encoder": "1x9" is not a number"#
    );

    // A line with nine fields.
    let short = line500.rsplit_once(',').unwrap().0;
    let e = read_mrdlab(with_line(&text, 500, short).as_bytes(), "22.TXT").unwrap_err();
    assert!(
        matches!(
            e.kind,
            LogErrorKind::TooFewFields {
                found: 9,
                expected: 10
            }
        ),
        "{e}"
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(500), Some("10: trajectory target"))
    );

    // Repeated time stamp.
    let line900 = text.lines().nth(899).unwrap().to_owned();
    let e = read_mrdlab(with_line(&text, 901, &line900).as_bytes(), "22.TXT").unwrap_err();
    assert!(
        matches!(e.kind, LogErrorKind::NonIncreasingTime { .. }),
        "{e}"
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(901), Some("1: time")),
        "{e}"
    );

    // NaN in a column the log does not keep is still an error.
    let mut cells: Vec<&str> = line900.split(',').collect();
    cells[9] = "nan";
    let e = read_mrdlab(with_line(&text, 900, &cells.join(",")).as_bytes(), "22.TXT").unwrap_err();
    assert!(matches!(e.kind, LogErrorKind::NotFinite(_)), "{e}");
    assert_eq!(e.line, Some(900));

    // Header only: too few rows.
    let head: String = text.lines().take(15).map(|l| format!("{l}\n")).collect();
    let e = read_mrdlab(head.as_bytes(), "22.TXT").unwrap_err();
    assert!(
        matches!(e.kind, LogErrorKind::TooFewRows { rows: 3, .. }),
        "{e}"
    );
}

#[test]
fn truncated_files_are_reported_with_the_line() {
    let dir = tempfile::tempdir().unwrap();
    // Cut inside line 10 013 (after its fifth field), as a copy interrupted
    // mid-line leaves it. (A cut inside the last field cannot be told from a
    // complete line: the number is shorter but valid.)
    let text = decompressed("42");
    let mut cut: String = text
        .lines()
        .take(10_012)
        .map(|l| format!("{l}\n"))
        .collect();
    let partial: Vec<&str> = text
        .lines()
        .nth(10_012)
        .unwrap()
        .split(',')
        .take(5)
        .collect();
    cut.push_str(&partial.join(","));
    let path = dir.path().join("42.TXT");
    std::fs::write(&path, cut).unwrap();
    let e = import_mrdlab(&path).unwrap_err();
    assert!(
        matches!(e.kind, LogErrorKind::TooFewFields { found: 5, .. }),
        "{e}"
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(10_013), Some("6: jaw torque")),
        "{e}"
    );
    assert!(
        e.to_string()
            .starts_with(&format!("{}:10013: ", path.display())),
        "{e}"
    );

    // Cut gzip stream: the decoder fails at some line; the error names it.
    let gz = std::fs::read(run_path("42")).unwrap();
    let path = dir.path().join("42.TXT.gz");
    std::fs::File::create(&path)
        .unwrap()
        .write_all(&gz[..gz.len() / 2])
        .unwrap();
    let e = import_mrdlab(&path).unwrap_err();
    let line = e.line.expect("error names a line");
    assert!(line > 1000 && line < 20_012, "line {line}: {e}");
    assert!(e.to_string().contains(&format!(":{line}: ")), "{e}");
}

#[test]
fn cli_import_writes_a_log_that_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.csv");
    let exe = env!("CARGO_BIN_EXE_host-sim");
    let o = Command::new(exe)
        .args(["import", "mrdlab"])
        .arg(run_path("05"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(stdout.lines().count(), 1, "one-line summary: {stdout}");
    assert!(stdout.contains("20000 rows"), "{stdout}");
    let back = Log::read_with(&out, &mrdlab_schema()).unwrap();
    assert_eq!(
        back,
        import_mrdlab(run_path("05")).unwrap(),
        "CSV round trip of the import"
    );

    // A bad input: non-zero exit, the message names the line; no output.
    let bad = dir.path().join("bad.TXT");
    let text = decompressed("05");
    std::fs::write(&bad, with_line(&text, 100, "0.087,1,2,3")).unwrap();
    let out2 = dir.path().join("bad.csv");
    let o = Command::new(exe)
        .args(["import", "mrdlab"])
        .arg(&bad)
        .arg("--out")
        .arg(&out2)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("bad.TXT:100: column \"5: jaw encoder\""),
        "{stderr}"
    );
    assert!(!out2.exists());
}
