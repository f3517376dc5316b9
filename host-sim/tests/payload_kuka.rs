//! The payload tool on the measured KUKA wrist data (tests/data/kuka-wrist,
//! Zenodo 11096791, CC BY 4.0): orientation convention from the static
//! poses, identification on one no-contact run, validation on another, the
//! contact run, and error messages for bad input files.

use std::path::{Path, PathBuf};

use clap::Parser;
use host_sim::cli::payload::PayloadArgs;
use host_sim::payload::{
    analyse, check_convention, fit_accel_calibration, load_run, load_static_poses, PayloadOptions,
};

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/kuka-wrist")
}

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: PayloadArgs,
}

/// The CLI's defaults with the test data directory and extra flags.
fn args(extra: &[&str]) -> PayloadOptions {
    let dir = data_dir();
    let mut v = vec!["payload", "--dir", dir.to_str().unwrap()];
    v.extend_from_slice(extra);
    Cli::parse_from(v).args.options()
}

/// `0-calibration_fts-accel.csv` has gravity in the sensor frame and the
/// rotation for each pose: exactly one convention reproduces it.
#[test]
fn orientation_convention_from_static_poses() {
    let poses = load_static_poses(&data_dir().join("0-calibration_fts-accel.csv")).unwrap();
    assert_eq!(poses.orient.len(), 24);
    let c = check_convention(&poses).unwrap();
    assert!(c.transpose, "g_s = R^T g_w expected");
    assert!(c.world_gravity_m_s2[2] < -9.7 && c.world_gravity_m_s2[2] > -9.9);
    assert!(c.max_err_m_s2 < 1e-3, "max error {}", c.max_err_m_s2);
    assert!(
        c.runner_up_max_err_m_s2 > 10.0,
        "the alternatives must fail clearly: {}",
        c.runner_up_max_err_m_s2
    );
    // The accelerometer maps into the sensor frame by a proper rotation
    // scaled by about |g| (reading in g), with a small residual.
    let cal = fit_accel_calibration(&poses).unwrap();
    let r = nalgebra::Matrix3::from_fn(|i, j| cal.rotation[i][j]);
    assert!((r.determinant() - 1.0).abs() < 1e-9);
    assert!(cal.rms_m_s2 < 0.2, "accelerometer fit rms {}", cal.rms_m_s2);
}

/// Identify on 1-baseline, validate on 2-vibrations (no contact: the
/// estimate is the error) and look at 3-vibrations-contact.
#[test]
fn identification_improves_validation_and_sees_contact() {
    let (report, runs) = analyse(&args(&[])).unwrap();
    let m = report
        .params
        .iter()
        .find(|p| p.name == "m_kg")
        .expect("mass in the report")
        .value;
    assert!(
        m > 0.2 && m < 5.0,
        "identified mass {m} kg outside a plausible range for a wrist payload"
    );
    let m_static = report
        .static_params
        .iter()
        .find(|p| p.name == "m_kg")
        .unwrap()
        .value;
    assert!(
        (m - m_static).abs() < 0.05 * m_static,
        "dynamic {m} kg and static-pose {m_static} kg masses disagree"
    );

    let val = report
        .runs
        .iter()
        .find(|r| r.name == "2-vibrations")
        .unwrap();
    assert!(!val.contact);
    for k in 0..6 {
        assert!(
            val.ident_tare[k] < val.raw[k],
            "axis {k}: validation RMSE after identification {} not below raw {}",
            val.ident_tare[k],
            val.raw[k]
        );
        assert!(
            val.comp_tare[k] <= val.ident_tare[k] * 1.05,
            "axis {k}: the selected compensation {} is worse than none {} on the run that selected it",
            val.comp_tare[k],
            val.ident_tare[k]
        );
    }
    // Forces swing by about 2 m g over the run; the estimate must remove most.
    assert!(val.ident_tare[0] < 0.1 * val.raw[0]);

    // The contact run: the estimated contact force is far above the
    // no-contact error, and it is there only during part of the run.
    let contact = report
        .runs
        .iter()
        .find(|r| r.name == "3-vibrations-contact")
        .unwrap();
    assert!(contact.contact);
    let peak_f = contact.peak[..3].iter().cloned().fold(0.0, f64::max);
    let noise_f = val.comp_tare[..3].iter().cloned().fold(0.0, f64::max);
    assert!(
        peak_f > 20.0 * noise_f,
        "contact peak {peak_f} N vs no-contact error {noise_f} N"
    );
    let (_, t0, t1) = report
        .contact_intervals
        .iter()
        .find(|c| c.0 == "3-vibrations-contact")
        .expect("contact detected");
    let dur = runs[2].run.wrench.t_s.last().unwrap();
    assert!(
        *t0 > 0.3 && *t1 < dur - 0.3 && t1 > t0,
        "contact interval {t0}..{t1} s should lie inside the run"
    );
}

/// The orientation-only gravity (no linear acceleration) is worse than the
/// accelerometer on the validation run: the linear acceleration matters.
#[test]
fn accelerometer_beats_orientation_only() {
    let (acc, _) = analyse(&args(&[
        "--accel-lag-ms",
        "6.5",
        "--validate",
        "2-vibrations",
    ]))
    .unwrap();
    let (ori, _) = analyse(&args(&[
        "--gravity",
        "orient",
        "--validate",
        "2-vibrations",
    ]))
    .unwrap();
    let a = &acc.runs[1].ident_tare;
    let o = &ori.runs[1].ident_tare;
    assert!(
        a[0] + a[2] < o[0] + o[2],
        "accelerometer fx+fz {} vs orientation {}",
        a[0] + a[2],
        o[0] + o[2]
    );
}

/// A corrupted cell is reported with the file, the line and the column.
#[test]
fn bad_input_names_file_line_column() {
    let tmp = tempfile::tempdir().unwrap();
    for f in std::fs::read_dir(data_dir()).unwrap() {
        let f = f.unwrap();
        std::fs::copy(f.path(), tmp.path().join(f.file_name())).unwrap();
    }
    // `text` with the cell of file line `line` (header = line 1) and
    // column `col` replaced by `value`.
    let with_cell = |text: &str, line: usize, col: usize, value: &str| -> String {
        let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
        let mut cells: Vec<&str> = lines[line - 1].split(',').collect();
        cells[col] = value;
        lines[line - 1] = cells.join(",");
        lines.join("\n")
    };
    let wrench = tmp.path().join("2-vibrations_wrench.csv");
    let wrench_text = std::fs::read_to_string(&wrench).unwrap();
    // Line 6, column fz.
    std::fs::write(&wrench, with_cell(&wrench_text, 6, 3, "1.2.3")).unwrap();
    let err = load_run(tmp.path(), "2-vibrations").unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains("2-vibrations_wrench.csv"), "{msg}");
    assert!(msg.contains(":6"), "line number missing: {msg}");
    assert!(msg.contains("fz"), "column missing: {msg}");

    // A missing column is reported at the header (wrench file restored).
    std::fs::write(&wrench, &wrench_text).unwrap();
    let path = tmp.path().join("2-vibrations_accel.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, text.replacen("t,ax,ay,az", "t,ax,ay,aq", 1)).unwrap();
    let msg = format!("{:#}", load_run(tmp.path(), "2-vibrations").unwrap_err());
    assert!(
        msg.contains("2-vibrations_accel.csv:1") && msg.contains("az"),
        "{msg}"
    );
    // Through the whole tool as well.
    let mut a = args(&["--validate", "2-vibrations"]);
    a.dir = tmp.path().to_path_buf();
    let msg = format!("{:#}", analyse(&a).err().expect("must fail"));
    assert!(msg.contains("2-vibrations"), "{msg}");

    // A finite reading beyond any sensor's range (accel file restored),
    // in each file that holds readings: refused naming the file, the line
    // and the column, not taken into the fit (1e30 N in the fit run had
    // identified a mass of -3.7e25 kg).
    std::fs::write(&path, &text).unwrap();
    for (file, column, unit) in [
        ("2-vibrations_wrench.csv", "fx", "N"),
        ("2-vibrations_accel.csv", "ax", "g"),
        ("0-calibration_fts-accel.csv", "fx", "N"),
        ("0-steady-state_wrench.csv", "fx", "N"),
    ] {
        let bad = tmp.path().join(file);
        let good = std::fs::read_to_string(&bad).unwrap();
        let header: Vec<&str> = good.lines().next().unwrap().split(',').collect();
        let col = header.iter().position(|h| *h == column).unwrap();
        for value in ["1e300", "1e30"] {
            std::fs::write(&bad, with_cell(&good, 5, col, value)).unwrap();
            let msg = format!("{:#}", analyse(&a).err().expect("must fail"));
            assert!(
                msg.contains(&format!(
                    "{file}: line 5: column \"{column}\" = {value} {unit} is beyond any sensor's range"
                )),
                "{file} {value}: {msg}"
            );
        }
        std::fs::write(&bad, good).unwrap();
    }
    analyse(&a).expect("every file restored");

    // A corrupt last time (1e30 µs): increasing, so taken before, it made
    // a 6 s run last 1e24 s. Refused as a jump by its line.
    let last = wrench_text.lines().count();
    std::fs::write(&wrench, with_cell(&wrench_text, last, 0, "1e30")).unwrap();
    let msg = format!("{:#}", analyse(&a).err().expect("must fail"));
    assert!(
        msg.contains(&format!(
            "2-vibrations_wrench.csv: line {last}: column \"t\" jumps"
        )) && msg.contains("times the stream's median step"),
        "{msg}"
    );
    std::fs::write(&wrench, &wrench_text).unwrap();

    // An orientation row that is not a rotation (a corrupt r11, then an
    // all-zero row) is refused naming the file and line, not taken as a
    // motion (the wrench file restored).
    std::fs::write(&wrench, &wrench_text).unwrap();
    let orient = tmp.path().join("2-vibrations_orientations.csv");
    let orient_text = std::fs::read_to_string(&orient).unwrap();
    for value in ["1e300", "0"] {
        let mut bad = with_cell(&orient_text, 100, 1, value);
        if value == "0" {
            for col in 2..=9 {
                bad = with_cell(&bad, 100, col, "0");
            }
        }
        std::fs::write(&orient, bad).unwrap();
        let msg = format!("{:#}", load_run(tmp.path(), "2-vibrations").unwrap_err());
        assert!(
            msg.contains("2-vibrations_orientations.csv: line 100: r11..r33 is not a rotation"),
            "{value}: {msg}"
        );
    }
    std::fs::write(&orient, orient_text).unwrap();
}

/// A library caller of `analyse` gets the checks of the command line's
/// run (before any file is read).
#[test]
fn analyse_checks_its_options() {
    let cases = [
        (
            PayloadOptions {
                tare_s: f64::NAN,
                ..PayloadOptions::default()
            },
            "--tare-s",
        ),
        (
            PayloadOptions {
                lowpass_hz: f64::INFINITY,
                ..PayloadOptions::default()
            },
            "--lowpass-hz",
        ),
        (
            PayloadOptions {
                creep_taus: vec![1.0, 0.0],
                ..PayloadOptions::default()
            },
            "--creep-taus",
        ),
        (
            PayloadOptions {
                accel_lag_ms: Some(f64::NAN),
                ..PayloadOptions::default()
            },
            "--accel-lag-ms",
        ),
        (
            PayloadOptions {
                inertia: true,
                rotational: false,
                ..PayloadOptions::default()
            },
            "--inertia",
        ),
        // Validating on the fit run would score the fit on its own data.
        (
            PayloadOptions {
                validate: vec!["2-vibrations".into(), PayloadOptions::default().fit],
                ..PayloadOptions::default()
            },
            "--validate names the fit run",
        ),
        (
            PayloadOptions {
                validate: vec![String::new()],
                ..PayloadOptions::default()
            },
            "--validate names an empty run",
        ),
    ];
    for (opts, flag) in cases {
        let msg = format!("{:#}", analyse(&opts).err().expect("must fail"));
        assert!(msg.starts_with(flag), "{msg}");
        assert_eq!(
            opts.check().unwrap_err().to_string(),
            msg,
            "analyse fails on the check"
        );
    }
    assert!(PayloadOptions::default().check().is_ok());
}

/// A no-contact window (`--tare-s`) longer than half a run is refused
/// naming the run (100 s on runs of about 6 s had tared the contact away
/// silently: the contact run's peak fell from 17.6 to 12.2 N); half a run
/// is taken.
#[test]
fn a_tare_window_longer_than_half_a_run_is_refused() {
    let msg = format!(
        "{:#}",
        analyse(&args(&["--tare-s", "100"]))
            .err()
            .expect("must fail")
    );
    assert!(
        msg.contains("--tare-s 100: run 1-baseline lasts 6.267 s")
            && msg.contains("at most half of it (3.133 s)"),
        "{msg}"
    );
    analyse(&args(&["--tare-s", "3"])).expect("half a run is a window");
}
