//! Eq. 3 identified on a wrist's run recorded as one log per joint
//! (`host_sim::wrist_log`, `host-sim simulate-wrist` and `identify-wrist`):
//! the logs replayed through the core give the fit the simulated wrist
//! gives in memory, and logs that cannot be one run are refused by name.

use std::path::Path;
use std::process::{Command, Output};

use cable_joint::wrist_dynamics::{InverseDynamics, N_PARAMS};
use host_sim::cli::wrist::simulated_wrist;
use host_sim::links::sign_speeds_rad_s;
use host_sim::links::{fit_eq3, fit_inverse_dynamics, run_free_settled, Eq3Sample, FreeRun, Links};
use host_sim::log::{Log, Schema};
use host_sim::report::wrist::object;
use host_sim::wrist::{run_grasp, Eq3Model, Grasp, WristParams};
use host_sim::wrist_estimate;
use host_sim::wrist_log::{self, Holding, OnFault, JOINT_NAMES};

/// A short free run (the identification run's motion for `seconds`), its
/// ticks from the controllers' start, and the four joints' logs of it.
fn short_run(params: &WristParams, seconds: f64) -> (Vec<host_sim::wrist::WristTick>, [Log; 4]) {
    let run = FreeRun {
        duration_s: seconds,
        ..FreeRun::identification()
    };
    let (ticks, _) = run_free_settled(params, &run, 7).unwrap();
    let logs = wrist_log::joint_logs(params, &ticks).unwrap();
    (ticks, logs)
}

/// The logs as a reader hands them over: written as CSV and read back.
fn round_trip(logs: &[Log; 4], dir: &Path) -> [(String, Log); 4] {
    core::array::from_fn(|j| {
        let path = dir.join(format!("{}.csv", JOINT_NAMES[j]));
        logs[j].write(&path).unwrap();
        wrist_log::read(&path, None, "test").unwrap()
    })
}

/// How the simulated wrist is held.
fn holding(params: &WristParams) -> Holding {
    Holding {
        gravity_m_s2: params.links.unwrap().gravity_m_s2,
        jaw_open_rad: params.jaw_open_rad,
    }
}

/// The note of `run` that contains `text`.
fn note<'a>(run: &'a wrist_log::WristRun, text: &str) -> &'a str {
    run.notes
        .iter()
        .find(|n| n.contains(text))
        .unwrap_or_else(|| panic!("no note with {text:?}: {:?}", run.notes))
}

/// The four joints' logs, written as CSV, read back and replayed through
/// the core, are the simulated wrist's run bit for bit: every tick's JAE
/// angles, estimated torques and bounds, so Eq. 3's fit on them is the fit
/// on the wrist's own ticks (the replay is the controllers' arithmetic on
/// the same sensor values; the CSV keeps every digit).
#[test]
fn eq3_fitted_on_the_joints_logs_is_eq3_fitted_on_the_simulated_wrist() {
    let params = simulated_wrist(None);
    let (ticks, logs) = short_run(&params, 10.0);
    let dir = tempfile::tempdir().unwrap();
    let read = round_trip(&logs, dir.path());
    let run =
        wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Refuse).unwrap();
    assert_eq!(run.samples.len(), ticks.len());
    for (k, (s, t)) in run.samples.iter().zip(&ticks).enumerate() {
        assert_eq!(*s, Eq3Sample::of_tick(&params, t), "tick {k}");
    }
    let from_logs = fit_eq3(&run.setting, &run.samples).unwrap();
    let in_memory = fit_inverse_dynamics(&params, &ticks, Links::prototype().gravity_m_s2).unwrap();
    assert!(in_memory.kept, "the model helps on the simulated run");
    assert_eq!(from_logs.body, in_memory.body);
    assert_eq!(
        (from_logs.condition, from_logs.condition_with_links),
        (in_memory.condition, in_memory.condition_with_links)
    );
    assert_eq!(
        (
            from_logs.links_observed,
            from_logs.kept,
            from_logs.held_out_rms_nm
        ),
        (
            in_memory.links_observed,
            in_memory.kept,
            in_memory.held_out_rms_nm
        )
    );
}

/// Logs that did not start together are refused, naming the joints and
/// their lengths; a shift shorter than the force estimate's time constant
/// (16 ms at the default 10 Hz cutoff) is cut off with a note; logs as
/// long as each other whose commanded motions start apart are warned of.
#[test]
fn logs_recorded_apart_are_refused_and_a_small_shift_is_cut() {
    let params = simulated_wrist(None);
    let (ticks, mut logs) = short_run(&params, 1.0);
    let n = logs[1].len();
    // 10 ticks (5 ms) short: within the time constant.
    let mut near = logs.clone();
    near[1] = near[1].rows(0..n - 10);
    let dir = tempfile::tempdir().unwrap();
    let read = round_trip(&near, dir.path());
    let run =
        wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Refuse).unwrap();
    assert_eq!(run.samples.len(), ticks.len() - 10);
    note(&run, "cut to the shortest");
    // The pitch's log starting 100 ticks (50 ms) late and the others
    // ending as early: the lengths agree, the motions' starts do not.
    let mut apart = logs.clone();
    for (j, log) in apart.iter_mut().enumerate() {
        *log = if j == 1 {
            log.rows(100..n)
        } else {
            log.rows(0..n - 100)
        };
    }
    let read = round_trip(&apart, dir.path());
    let run =
        wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Refuse).unwrap();
    let note = note(&run, "first moves");
    assert!(
        note.contains("0.050 s apart") && note.contains("not aligned"),
        "{note}"
    );
    // 100 ticks (50 ms) late: refused (2 s of settling and 1 s of motion).
    logs[1] = logs[1].rows(100..n);
    let read = round_trip(&logs, dir.path());
    let e = wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Refuse)
        .unwrap_err()
        .to_string();
    assert!(e.contains("recorded") && e.contains("together"), "{e}");
    assert!(
        e.contains("pitch 2.950 s") && e.contains("roll 3.000 s"),
        "{e}"
    );
}

/// `log` with the host's clock (`t_unix_s`, as `host-sim link` records
/// it), its first row at `start_s`.
fn with_host_clock(log: &Log, start_s: f64) -> Log {
    let mut out = log.clone();
    let t = log.time_s().unwrap();
    let clock = t.iter().map(|x| start_s + x - t[0]).collect();
    out.set_col("t_unix_s", clock).unwrap();
    out
}

/// Logs carrying the host's clock are aligned on it, not on their first
/// rows: the pitch's recording started 200 ticks (0.1 s) after the others
/// and ends with them, so the run starts at the pitch's first tick and
/// the roll's and the jaws' samples are the simulated wrist's from tick
/// 200 on. (Without the clock, logs 0.1 s apart are refused:
/// `logs_recorded_apart_are_refused_and_a_small_shift_is_cut`.) Logs that
/// do not overlap on the clock are refused.
#[test]
fn logs_with_the_host_clock_are_aligned_on_it() {
    let params = simulated_wrist(None);
    let (ticks, logs) = short_run(&params, 1.0);
    let n = logs[1].len();
    let t0 = 1.7e9;
    let mut late: [Log; 4] = core::array::from_fn(|j| with_host_clock(&logs[j], t0));
    late[1] = with_host_clock(&logs[1].rows(200..n), t0 + 0.1);
    let dir = tempfile::tempdir().unwrap();
    let read = round_trip(&late, dir.path());
    let run =
        wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Refuse).unwrap();
    let note = note(&run, "aligned on the host's clock");
    assert!(note.contains("pitch +0.100 s"), "{note}");
    assert_eq!(run.samples.len(), n - 200);
    for (k, s) in run.samples.iter().enumerate() {
        let t = Eq3Sample::of_tick(&params, &ticks[200 + k]);
        for j in [0, 2, 3] {
            assert_eq!(
                s.theta_hat_rad[j], t.theta_hat_rad[j],
                "tick {k}, joint {j}"
            );
            assert_eq!(s.torque_nm[j], t.torque_nm[j], "tick {k}, joint {j}");
        }
    }
    // The pitch's whole run recorded 0.1 s after the others': aligned on
    // the clock, its commanded motion starts 0.1 s after theirs, and the
    // note says the joints started apart, not that the logs are not
    // aligned.
    let mut started_late: [Log; 4] = core::array::from_fn(|j| with_host_clock(&logs[j], t0));
    started_late[1] = with_host_clock(&logs[1], t0 + 0.1);
    let read = round_trip(&started_late, dir.path());
    let run =
        wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Refuse).unwrap();
    let starts = self::note(&run, "first moves at");
    assert!(
        starts.contains("started apart") && !starts.contains("not aligned"),
        "{starts}"
    );
    // The pitch recorded 10 s after the others had ended.
    let mut apart = late.clone();
    apart[1] = with_host_clock(&logs[1], t0 + 10.0);
    let read = round_trip(&apart, dir.path());
    let e = wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Refuse)
        .unwrap_err()
        .to_string();
    assert!(e.contains("do not overlap") && e.contains("roll"), "{e}");
}

/// Jaws configured with different lengths cannot be the wrist's two jaws:
/// refused, naming both.
#[test]
fn jaws_of_different_lengths_are_refused() {
    let params = simulated_wrist(None);
    let (_, logs) = short_run(&params, 0.2);
    let dir = tempfile::tempdir().unwrap();
    let read = round_trip(&logs, dir.path());
    let mut configs = params.configs;
    configs[3].machine.gripper_length_m *= 1.1;
    let e = wrist_log::replay(&read, &configs, &holding(&params), OnFault::Refuse)
        .unwrap_err()
        .to_string();
    assert!(e.contains("jaw A") && e.contains("jaw B"), "{e}");
}

/// A grasp recorded as four logs and replayed (`estimate-wrist`'s path)
/// gives the simulated wrist's Eq. 4–5 bit for bit on every tick: each
/// joint's external torque bound with Eq. 3 taken out, each jaw's force,
/// the clamp force and its bound; and the jaws' logs give the true contact
/// force as the reference. Eq. 3 here is the links' true moments, so the
/// model's path is compared too.
#[test]
fn the_clamp_force_from_a_grasps_logs_is_the_simulated_wrists_tick_for_tick() {
    let mut params = simulated_wrist(None);
    let links = params.links.unwrap();
    let mut body_params = [0.0f32; N_PARAMS];
    for (p, v) in body_params
        .iter_mut()
        .zip(links.base_params(&params.geometry))
    {
        *p = v as f32;
    }
    let model = Eq3Model {
        body: InverseDynamics {
            params: body_params,
            std_dev: body_params.map(|p| 0.1 * p.abs()),
            gravity_m_s2: links.gravity_m_s2.map(|g| g as f32),
            sign_speed_rad_s: sign_speeds_rad_s(&params.configs),
        },
        motion_bandwidth_hz: 30.0,
    };
    params.inverse_dynamics = Some(model);
    let grasp = Grasp {
        target_n: 2.0,
        settle_s: 0.3,
        move_s: 0.3,
        hold_s: 0.6,
        after_s: 0.2,
    };
    let ticks: Vec<_> = run_grasp(&params, object(1000.0), &grasp, 5)
        .unwrap()
        .into_iter()
        .map(|(_, t)| t)
        .collect();
    assert!(
        ticks.iter().any(|t| t.contact_n > 1.0),
        "the grasp squeezes the object"
    );
    let logs = wrist_log::joint_logs(&params, &ticks).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let read = round_trip(&logs, dir.path());
    let run = wrist_log::replay(&read, &params.configs, &holding(&params), OnFault::Cut).unwrap();
    let replayed = wrist_estimate::estimate(&run, Some(&model));
    assert_eq!(replayed.len(), ticks.len());
    for (k, (e, t)) in replayed.iter().zip(&ticks).enumerate() {
        assert_eq!(e.force.clamp_n.to_bits(), t.clamp_n.to_bits(), "tick {k}");
        assert_eq!(e.force.clamp_bound_n, t.clamp_bound_n, "tick {k}");
        assert_eq!(e.force.torque_bound_nm, t.torque_bound_nm, "tick {k}");
        assert_eq!(e.force.jaws[0].force_n, t.jaws[0].force_n, "tick {k}");
        assert_eq!(e.force.jaws[1].force_n, t.jaws[1].force_n, "tick {k}");
        assert_eq!(e.force.pose_rad, t.pose_rad, "tick {k}");
        assert_eq!(e.links_hat_nm, t.links_hat_nm, "tick {k}");
        assert_eq!(e.reference_n, Some(t.contact_n), "tick {k}");
    }
}

/// `o` failed, its stderr says every one of `words`, and `out` was not
/// written.
fn refused(o: &Output, out: &Path, words: &[&str]) {
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{e}");
    assert!(words.iter().all(|w| e.contains(w)), "{words:?} in {e}");
    assert!(!out.exists(), "{}", out.display());
}

/// `host-sim` run with `args`.
fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap()
}

/// The command line end to end: `simulate-wrist` writes a run's four logs
/// with each joint's configuration beside them; `identify-wrist` fits
/// Eq. 3 on one run, validates it on another, writes the model and its
/// figures, and the model cuts the unseen run's no-load error on every
/// joint; `--links-scale` makes the links heavier. The same run given as
/// its own validation, a run missing a joint and a bad cell are refused,
/// each by name, and nothing is written.
#[test]
fn identify_wrist_fits_one_simulated_run_and_validates_on_another() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p).display().to_string();
    for (out, run, seed) in [("id", "identification", "1"), ("val", "validation", "2")] {
        let o = host_sim(&[
            "simulate-wrist",
            "--out",
            &d(out),
            "--free-run",
            run,
            "--seed",
            seed,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for name in JOINT_NAMES {
            assert!(dir.path().join(out).join(format!("{name}.csv")).is_file());
            assert!(dir.path().join(out).join(format!("{name}.toml")).is_file());
        }
    }
    // Links three times heavier put about three times their torque in the
    // logs' truth column (the motion differs a little between the runs).
    let o = host_sim(&[
        "simulate-wrist",
        "--out",
        &d("heavy"),
        "--free-run",
        "validation",
        "--seed",
        "2",
        "--links-scale",
        "3",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let links_rms = |run: &str| {
        let (_, log) =
            wrist_log::read(&dir.path().join(run).join("pitch.csv"), None, "test").unwrap();
        let f = log.col("f_links_true_n").unwrap();
        (f.iter().map(|x| x * x).sum::<f64>() / f.len() as f64).sqrt()
    };
    let ratio = links_rms("heavy") / links_rms("val");
    assert!(
        (2.5..3.5).contains(&ratio),
        "links' torque {ratio}x with --links-scale 3"
    );
    let g = Links::prototype().gravity_m_s2;
    let gravity = format!("--gravity={},{},{}", g[0], g[1], g[2]);
    let fit = |run: &str, validate: &str, out: &str| {
        host_sim(&[
            "identify-wrist",
            "--run",
            &d(run),
            "--validate",
            &d(validate),
            &gravity,
            "--jaw-open-deg",
            "20",
            "--out",
            &d(out),
        ])
    };
    let o = host_sim(&[
        "identify-wrist",
        "--run",
        &d("id"),
        "--validate",
        &d("val"),
        &gravity,
        "--jaw-open-deg",
        "20",
        "--out",
        &d("eq3.toml"),
        "--plot",
        &d("no-load"),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("no-load.svg").is_file(), "{stdout}");
    assert!(stdout.contains("kept = true"), "{stdout}");
    let text = std::fs::read_to_string(dir.path().join("eq3.toml")).unwrap();
    let file: toml::Value = toml::from_str(&text).unwrap();
    assert_eq!(file["fit"]["kept"].as_bool(), Some(true), "{text}");
    let no_load = &file["validation"]["no_load"];
    let values = |k: &str| -> Vec<f64> {
        no_load[k]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_float().unwrap())
            .collect()
    };
    let (raw, corrected) = (values("raw_rms_n"), values("corrected_rms_n"));
    for j in 0..4 {
        assert!(
            corrected[j] < raw[j],
            "{}: {} -> {} N",
            JOINT_NAMES[j],
            raw[j],
            corrected[j]
        );
    }
    // Each joint's friction sign as the fit saw it, printed and written:
    // a width, at least the regressor's own (the simulated joints stick
    // and slip at low speed: wrist_eq3's test of it).
    assert!(
        stdout.contains("friction sign as the fit sees it"),
        "{stdout}"
    );
    let widths: Vec<f64> = file["fit"]["sign_width_seen_rad_s"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_float().unwrap())
        .collect();
    assert_eq!(widths.len(), 4, "{text}");
    assert!(widths.iter().all(|w| *w >= 0.05), "{widths:?}");
    // Without a validation run `--plot` draws the friction sign alone.
    let o = host_sim(&[
        "identify-wrist",
        "--run",
        &d("id"),
        &gravity,
        "--jaw-open-deg",
        "20",
        "--out",
        &d("alone.toml"),
        "--plot",
        &d("sign"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("sign.svg").is_file());
    assert!(dir.path().join("sign.png").is_file());
    // A grasp recorded the same way; its forces estimated with the model,
    // judged on the jaws' true contact force (`f_ext_n`).
    // (Its directory's name has a space, as a user's may.)
    let grasp = d("a grasp");
    let o = host_sim(&[
        "simulate-wrist",
        "--out",
        &grasp,
        "--grasp",
        "2",
        "--seed",
        "3",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The next step's command as `simulate-wrist` prints it runs as printed
    // in a shell (its `--gravity` starts with a minus, its directory is
    // quoted), `[--eq3 ...]` left out and its output put in the test's
    // directory; each estimate below adds to it.
    let stdout = String::from_utf8_lossy(&o.stdout);
    let printed = stdout
        .split('`')
        .find(|s| s.starts_with("host-sim estimate-wrist "))
        .unwrap_or_else(|| panic!("no estimate-wrist command in {stdout}"))
        .replace(" [--eq3 eq3.toml]", "");
    let word = |p: &str| host_sim::cli::shell_word(std::path::Path::new(p));
    let as_printed = printed
        .replacen("host-sim", &word(env!("CARGO_BIN_EXE_host-sim")), 1)
        .replace(
            "--out forces.csv",
            &format!("--out {}", word(&d("printed.csv"))),
        );
    let o = Command::new("sh")
        .arg("-c")
        .arg(&as_printed)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{printed}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(dir.path().join("printed.csv").is_file());
    // Its arguments, the quoted directory as one.
    let mut next: Vec<String> = printed
        .replace(&word(&grasp), "GRASP")
        .split_whitespace()
        .skip(1)
        .map(|a| {
            if a == "GRASP" {
                grasp.clone()
            } else {
                a.to_owned()
            }
        })
        .collect();
    let out_at = next.iter().position(|a| a == "--out").unwrap();
    assert_eq!(next.split_off(out_at).len(), 2, "{printed}");
    assert!(next.iter().any(|a| a == "--gravity"), "{printed}");
    assert!(next.contains(&grasp), "{printed}");
    let estimate = |extra: &[&str], out: &str| {
        let out = d(out);
        let mut args: Vec<&str> = next.iter().map(String::as_str).collect();
        args.extend_from_slice(extra);
        args.extend(["--out", &out]);
        host_sim(&args)
    };
    let eq3 = d("eq3.toml");
    let o = estimate(&["--eq3", &eq3, "--plot", &d("forces.csv")], "forces.csv");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("holding (reference clamp force >= 1 N"),
        "{stdout}"
    );
    assert!(stdout.contains("total force (Eq. 5"), "{stdout}");
    assert!(dir.path().join("forces.svg").is_file());
    let forces = Log::read_with(
        dir.path().join("forces.csv"),
        &Schema::with_required(&[
            "t_s",
            "clamp_n",
            "clamp_ref_n",
            "total_x_lo_n",
            "total_z_limit_n",
        ]),
    )
    .unwrap();
    // Along the wrist (z) the joints see none of a grasp's total: while
    // holding its bound is mostly the force limit's.
    let (z_lo, z_hi, z_limit) = (
        forces.col("total_z_lo_n").unwrap(),
        forces.col("total_z_hi_n").unwrap(),
        forces.col("total_z_limit_n").unwrap(),
    );
    let reference = forces.col("clamp_ref_n").unwrap();
    let mostly_limit = (0..reference.len())
        .filter(|&k| reference[k] >= 1.0)
        .all(|k| 2.0 * z_limit[k] > 0.9 * (z_hi[k] - z_lo[k]));
    assert!(mostly_limit);
    // A task's force limit narrows what the joints do not see: z's bound
    // shrinks with it, and a limit that is not a force is refused.
    let limited =
        |limit: &str, out: &str| estimate(&["--eq3", &eq3, "--force-limit-n", limit], out);
    let o = limited("5", "limited.csv");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let warning = "warning: the force limit";
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(!stdout.contains(warning), "a 2 N grasp under 5 N: {stdout}");
    // A limit the jaws' own bounds exceed is the user's claim against the
    // run: said, with the least limit the run allows.
    let o = limited("1e-30", "tiny-limit.csv");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains(&format!("{warning} (1.0000e-30 N)"))
            && stdout.contains("give --force-limit-n at least"),
        "{stdout}"
    );
    let narrow = Log::read_with(
        dir.path().join("limited.csv"),
        &Schema::with_required(&["total_z_limit_n"]),
    )
    .unwrap();
    let narrow_limit = narrow.col("total_z_limit_n").unwrap();
    assert!(
        (0..reference.len())
            .filter(|&k| reference[k] >= 1.0)
            .all(|k| narrow_limit[k] < 0.2 * z_limit[k]),
        "5 N against the drive's squeeze"
    );
    for bad in ["0", "-2", "inf"] {
        refused(
            &limited(bad, "bad-limit.csv"),
            &dir.path().join("bad-limit.csv"),
            &["--force-limit-n", "positive"],
        );
    }
    let (est, reference) = (
        forces.col("clamp_n").unwrap(),
        forces.col("clamp_ref_n").unwrap(),
    );
    let held: Vec<(f64, f64)> = est
        .iter()
        .zip(reference)
        .filter(|(_, r)| **r >= 1.0)
        .map(|(e, r)| (*e, *r))
        .collect();
    let mean = |f: fn(&(f64, f64)) -> f64| held.iter().map(f).sum::<f64>() / held.len() as f64;
    let (mean_est, mean_ref) = (mean(|p| p.0), mean(|p| p.1));
    assert!(
        held.len() > 1000 && (mean_est - mean_ref).abs() < 0.2 * mean_ref,
        "{} ticks held: clamp estimate {mean_est} N against {mean_ref} N",
        held.len()
    );
    // The same grasp on another plant (cable 1 half as stiff, as a
    // report variant's plant.toml gives it): the joints' logs differ.
    let mut soft = host_sim::plant::PlantParams::default();
    soft.cable1.stiffness_n_m *= 0.5;
    std::fs::write(dir.path().join("soft.toml"), soft.to_toml_string().unwrap()).unwrap();
    let o = host_sim(&[
        "simulate-wrist",
        "--out",
        &d("grasp-soft"),
        "--grasp",
        "2",
        "--seed",
        "3",
        "--plant",
        &d("soft.toml"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let x1 = |run: &str| {
        let (_, log) =
            wrist_log::read(&dir.path().join(run).join("jaw_a.csv"), None, "test").unwrap();
        log.col("x1_m").unwrap().to_vec()
    };
    assert_ne!(x1("a grasp"), x1("grasp-soft"));
    // Not a model: refused by name, nothing written.
    refused(
        &estimate(&["--eq3", &d("a grasp/roll.toml")], "not.csv"),
        &dir.path().join("not.csv"),
        &["roll.toml", "not an Eq. 3 model"],
    );
    // The fitted run as its own validation.
    refused(
        &fit("id", "id", "same.toml"),
        &dir.path().join("same.toml"),
        &["--validate", "fitted"],
    );
    // A run without jaw B's log.
    std::fs::remove_file(dir.path().join("val").join("jaw_b.csv")).unwrap();
    refused(
        &fit("id", "val", "missing.toml"),
        &dir.path().join("missing.toml"),
        &["jaw_b.csv", "no log of joint jaw_b"],
    );
    // A cell that is not a number, in the pitch's log at line 5.
    let pitch = dir.path().join("id").join("pitch.csv");
    let text = std::fs::read_to_string(&pitch).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let mut cells: Vec<&str> = lines[4].split(',').collect();
    cells[1] = "oops";
    lines[4] = cells.join(",");
    std::fs::write(&pitch, lines.join("\n") + "\n").unwrap();
    refused(
        &fit("id", "val", "bad.toml"),
        &dir.path().join("bad.toml"),
        &["pitch.csv:5", "x1_m"],
    );
}
