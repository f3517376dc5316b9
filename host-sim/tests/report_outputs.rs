//! The report (the default command) on a short version of the programme:
//! report.json carries every figure under stable keys and every figure is
//! finite, report.md and the plots exist and agree with the JSON, the
//! identified configurations load, and the results depend only on the seed.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

use host_sim::report::{generate, write, ReportOptions};
use serde_json::Value;

/// Short enough for the test profile, long enough for every identification.
const SCALE: f64 = 0.15;
const SEED: u64 = 5;

struct Run {
    _dir: tempfile::TempDir,
    out: std::path::PathBuf,
    json: Value,
    md: String,
    terminal: String,
    /// The figure map in memory (JSON's float parsing may differ in the
    /// last bit).
    map: BTreeMap<String, f64>,
}

fn run() -> &'static Run {
    static RUN: OnceLock<Run> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("report");
        let args = ReportOptions {
            out: out.clone(),
            seed: SEED,
            duration_scale: SCALE,
            quiet: true,
            ..ReportOptions::default()
        };
        let mut r = generate(&args).expect("report runs");
        let terminal = write(&mut r).expect("report written");
        let map = host_sim::report::render::figure_map(&r);
        let json: Value = serde_json::from_str(
            &std::fs::read_to_string(out.join("report.json")).expect("report.json exists"),
        )
        .expect("report.json parses");
        let md = std::fs::read_to_string(out.join("report.md")).expect("report.md exists");
        Run {
            _dir: dir,
            out,
            json,
            md,
            terminal,
            map,
        }
    })
}

fn figures(v: &Value) -> BTreeMap<String, f64> {
    v["figures"]
        .as_object()
        .expect("`figures` is an object")
        .iter()
        .map(|(k, x)| {
            (
                k.clone(),
                x.as_f64()
                    .unwrap_or_else(|| panic!("figure `{k}` is not a finite number: {x}")),
            )
        })
        .collect()
}

/// Keys every evaluated variant has (scripts rely on these names).
const EVALUATION_KEYS: [&str; 26] = [
    "jae.error.mean_abs_deg",
    "jae.error.max_abs_deg",
    "track_motor.desired_minus_actual.mean_abs_deg",
    "track_motor.desired_minus_actual.max_abs_deg",
    "track_jae.desired_minus_actual.mean_deg",
    "track_jae.desired_minus_actual.max_deg",
    "track_jae.desired_minus_actual.min_deg",
    "track_jae.actual_minus_estimated.mean_deg",
    "track_jae.actual_minus_estimated.max_abs_deg",
    "robust_2n5.desired_minus_actual.mean_deg",
    "robust_2n5.desired_minus_actual.max_abs_deg",
    "robust_2n5.actual_minus_estimated.max_abs_deg",
    "track_jae.true_minus_estimated.max_abs_deg",
    "robust_2n5.true_minus_estimated.max_abs_deg",
    "loading.static_noload.max_abs_n",
    "loading.static_noload_0.max_abs_n",
    "loading.static_noload_30_m40.max_abs_n",
    "loading.dynamic_noload_pos.max_abs_n",
    "loading.dynamic_noload_neg.max_abs_n",
    "loading.accuracy.above_1n.min_pct",
    "loading.accuracy.at_0n3.min_pct",
    "loading.accuracy.above_1n_0.min_pct",
    "loading.accuracy.at_0n3_30_m40.mean_pct",
    "loading.max_angle_error_0_deg",
    "loading.max_angle_error_30_m40_deg",
    "loading.faulted_cases",
];

/// Keys of the identifications (clean plant and plant with effects).
const IDENT_KEYS: [&str; 12] = [
    "bm.b_m_nm_s_rad",
    "bm.verification_rmse_nm",
    "jae.c1",
    "jae.c4",
    "jae.ident.mean_abs_deg",
    "jae.ident.max_deg",
    "tension.model_a.rmse_n",
    "tension.model_b.rmse_n",
    "tension.model_c.rmse_n",
    "tension.chi_p.k_s_n_m",
    "tension.chi_p.f_0_n",
    "tension.verification.mean_error_n",
];

#[test]
fn report_json_has_every_key_and_every_figure_is_finite() {
    let r = run();
    let f = figures(&r.json);
    let mut missing = Vec::new();
    for v in ["clean", "effects_seed_model", "effects_residual"] {
        for k in EVALUATION_KEYS {
            if !f.contains_key(&format!("{v}.{k}")) {
                missing.push(format!("{v}.{k}"));
            }
        }
    }
    for v in ["clean", "effects_seed_model"] {
        for k in IDENT_KEYS {
            if !f.contains_key(&format!("{v}.{k}")) {
                missing.push(format!("{v}.{k}"));
            }
        }
    }
    for k in [
        "effects_residual.residual.jae.before_rmse",
        "effects_residual.residual.jae.after_rmse",
        "effects_residual.residual.tension.before_rmse",
        "effects_residual.residual.tension.after_rmse",
        "runtime_s",
    ] {
        if !f.contains_key(k) {
            missing.push(k.to_owned());
        }
    }
    assert!(missing.is_empty(), "missing figures: {missing:?}");
    // `figures()` already refused any non-number (a NaN is written as null).
    assert!(f.len() > 300, "only {} figures", f.len());
    assert_eq!(r.json["seed"], SEED);
    assert_eq!(r.json["duration_scale"], SCALE);

    // Internal consistency of the statistics.
    for (k, v) in &f {
        if let Some(stem) = k.strip_suffix(".max_abs_deg") {
            for (max, min) in [(format!("{stem}.max_deg"), format!("{stem}.min_deg"))] {
                if let (Some(a), Some(b)) = (f.get(&max), f.get(&min)) {
                    assert!(
                        (v - a.abs().max(b.abs())).abs() < 1e-12,
                        "{k} = {v} but max {a}, min {b}"
                    );
                    assert!(a >= b, "{stem}: max {a} < min {b}");
                }
            }
        }
        if k.ends_with("_pct") && k.contains("accuracy") {
            assert!(*v <= 100.0, "{k} = {v} % above 100 %");
        }
    }
    // The residual loop is judged on held-out data and keeps a term only if
    // it lowers that error.
    for m in ["jae", "tension"] {
        let b = f[&format!("effects_residual.residual.{m}.before_rmse")];
        let a = f[&format!("effects_residual.residual.{m}.after_rmse")];
        assert!(a <= b, "{m}: validation RMSE rose from {b} to {a}");
        assert!(a > 0.0, "{m}: zero validation error is not credible");
    }
}

/// "Actual" is the magnetic encoder's reading of the plant's angle, so the
/// JAE's error against it and against the plant's true angle differ by the
/// encoder's rounding, within one count, on every tracking run of every
/// variant; the two are not the same figure (the encoder's quantum shows).
#[test]
fn the_jae_error_against_the_true_angle_is_the_encoders_within_a_count() {
    let f = figures(&run().json);
    let count_deg = 360.0
        / f64::from(
            cable_joint::Config::default()
                .scales
                .magnetic_counts_per_rev,
        );
    let mut differs = false;
    for v in ["clean", "effects_seed_model", "effects_residual"] {
        for t in ["track_motor", "track_jae", "robust_2n5"] {
            for stat in ["max_abs_deg", "mean_deg", "rms_deg"] {
                let key = |d: &str| format!("{v}.{t}.{d}.{stat}");
                let (actual, truth) = (
                    f[&key("actual_minus_estimated")],
                    f[&key("true_minus_estimated")],
                );
                assert!(
                    (actual - truth).abs() <= count_deg,
                    "{v} {t} {stat}: {actual:.4}° against the encoder, {truth:.4}° against the \
                     plant's angle: more than a count ({count_deg:.4}°) apart"
                );
                differs |= actual != truth;
            }
        }
    }
    assert!(
        differs,
        "the true-angle figures equal the encoder's everywhere"
    );
}

#[test]
fn seed_comparison_and_goals_match_the_figures() {
    let r = run();
    let f = figures(&r.json);
    let rows = r.json["seed_comparison"].as_array().expect("rows");
    assert!(rows.len() >= 20, "{} comparison rows", rows.len());
    for row in rows {
        let key = row["key"].as_str().expect("key");
        let ours = row["ours"].as_f64().expect("ours finite");
        let seed = row["seed"].as_f64().expect("seed finite");
        let ratio = row["ratio"].as_f64().expect("ratio finite");
        assert_eq!(ours, f[key], "row {key} disagrees with `figures`");
        let expect = if row["verdict"] == "-" || key.contains("accuracy") {
            ours / seed
        } else {
            ours.abs() / seed.abs()
        };
        assert!(
            (ratio - expect).abs() <= 1e-12 * expect.abs().max(1.0),
            "{key}: ratio {ratio} vs {expect}"
        );
        let q = row["quantity"].as_str().expect("quantity");
        assert!(r.terminal.contains(q), "terminal table lacks `{q}`");
        // Markdown table cells escape `|`.
        let md_q = q.replace('|', "\\|");
        assert!(r.md.contains(&md_q), "report.md lacks `{md_q}`");
    }
    // The seed's own figures are quoted as published.
    let seed_of = |k: &str| {
        rows.iter()
            .find(|row| row["key"] == format!("clean.{k}"))
            .and_then(|row| row["seed"].as_f64())
    };
    assert_eq!(seed_of("jae.error.max_deg"), Some(0.8355));
    assert_eq!(
        seed_of("track_jae.desired_minus_actual.max_deg"),
        Some(0.905)
    );
    assert_eq!(seed_of("loading.accuracy.above_1n_0.min_pct"), Some(94.0));

    let goals = r.json["goals"].as_array().expect("goals");
    assert!(goals.len() >= 5);
    for g in goals {
        let key = g["key"].as_str().expect("goal key");
        let limit = g["limit"].as_f64().expect("limit");
        for v in ["clean", "effects_seed_model", "effects_residual"] {
            let value = g[v]["value"].as_f64().expect("goal value");
            assert_eq!(value, f[&format!("{v}.{key}")]);
            let met = g[v]["met"].as_bool().expect("met");
            let within = if g["at_least"] == true {
                value >= limit
            } else {
                value <= limit
            };
            // Met implies within the limit (a fault can still fail it).
            assert!(
                !met || within,
                "{v} {key}: met with {value} against {limit}"
            );
        }
    }
    assert!(r.md.contains("## Where we stand"));
    assert!(r.terminal.contains("Where we stand"));
}

fn check_image(path: &Path) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    match path.extension().and_then(|e| e.to_str()) {
        Some("png") => assert!(
            bytes.starts_with(b"\x89PNG\r\n\x1a\n") && bytes.len() > 5_000,
            "{} is not a drawn PNG ({} bytes)",
            path.display(),
            bytes.len()
        ),
        Some("svg") => {
            let text = String::from_utf8_lossy(&bytes);
            assert!(
                text.contains("<svg") && (text.contains("<polyline") || text.contains("<circle")),
                "{} has no drawn series",
                path.display()
            );
        }
        _ => panic!("unexpected image {}", path.display()),
    }
}

#[test]
fn report_md_and_every_plot_exist() {
    let r = run();
    for stem in [
        "fig09_jae",
        "fig10_track_motor",
        "fig12_track_jae",
        "fig13_robust",
        "fig14_15_bm",
        "fig16_tension_models",
        "fig17_model_c_simplified",
        "fig18_model_c_verification",
        "fig20_loading_0deg_neg",
        "fig21_loading_0deg_pos",
        "fig22_partition",
        "fig23_loading_30deg_neg",
        "fig24_loading_30deg_pos",
        "fig25_loading_m40deg_pos",
        "fig26_loading_m40deg_neg",
        "fig_accuracy_variants",
    ] {
        for ext in ["svg", "png"] {
            check_image(&r.out.join(format!("{stem}.{ext}")));
        }
        assert!(
            r.md.contains(&format!("]({stem}.png)")),
            "report.md does not embed {stem}"
        );
    }
    // Every image report.md links to exists.
    let mut links = 0;
    for part in r.md.split("](").skip(1) {
        let target = part.split(')').next().unwrap_or("");
        if target.ends_with(".png") || target.ends_with(".svg") {
            links += 1;
            check_image(&r.out.join(target));
        }
    }
    assert!(links >= 32, "only {links} image links");
    // JSON lists the same plots.
    let plots = r.json["plots"].as_array().expect("plots");
    for p in plots {
        let stem = p["stem"].as_str().expect("stem");
        assert!(r.out.join(format!("{stem}.svg")).is_file(), "{stem}.svg");
    }
    // No temporary file is left behind.
    for e in std::fs::read_dir(&r.out).expect("dir") {
        let name = e.expect("entry").file_name().to_string_lossy().into_owned();
        assert!(!name.starts_with('.'), "leftover temporary file {name}");
    }
}

#[test]
fn identified_configurations_load_and_differ_from_the_datasheet() {
    let r = run();
    let def = cable_joint::Config::default();
    for name in [
        "config_clean.toml",
        "config_effects_seed_model.toml",
        "config_effects_residual.toml",
    ] {
        let c = host_sim::io::config::load_config(r.out.join(name)).expect(name);
        assert_ne!(
            c.dob.viscous_nm_s_rad, def.dob.viscous_nm_s_rad,
            "{name}: B_m not identified"
        );
        assert_ne!(
            c.jae.c_pos_rad_m, def.jae.c_pos_rad_m,
            "{name}: JAE not identified"
        );
        assert_ne!(
            c.tension.f_0_n, def.tension.f_0_n,
            "{name}: tension model not identified"
        );
        // c4 = (K_s + K_w2) / (K_w2 r) of a 4 mm pulley and a spring much
        // softer than the cable: a little above 1 / r = 250 rad/m.
        assert!(
            (250.0..300.0).contains(&c.jae.c_pos_rad_m),
            "{name}: c4 = {}",
            c.jae.c_pos_rad_m
        );
    }
    let res =
        host_sim::io::config::load_config(r.out.join("config_effects_residual.toml")).unwrap();
    let n = u32::from(res.jae.added.len) + u32::from(res.tension.added.len);
    let f = figures(&r.json);
    let added = f["effects_residual.residual.jae.terms_added"]
        + f["effects_residual.residual.tension.terms_added"];
    assert_eq!(
        f64::from(n),
        added,
        "terms in the configuration vs the report"
    );
}

/// Every plant variant's plant and identified configuration are written
/// beside the report, so `host-sim simulate` can rerun any of its cases:
/// the plant reads back as the variant's, the configuration loads, and the
/// probing one differs from it only by the dither being on.
#[test]
fn every_variant_writes_its_plant_and_configurations() {
    let r = run();
    let variants = host_sim::report::variants::variants();
    let reported = r.json["force_variants"].as_array().expect("force_variants");
    assert_eq!(reported.len(), variants.len());
    let dirs: Vec<_> = std::fs::read_dir(r.out.join("variants"))
        .expect("variants/")
        .map(|e| e.expect("entry").path())
        .collect();
    assert_eq!(dirs.len(), variants.len(), "{dirs:?}");
    for d in &dirs {
        let plant = host_sim::io::config::load_plant(Some(&d.join("plant.toml")))
            .unwrap_or_else(|e| panic!("{}: {e:#}", d.display()));
        assert!(
            variants.iter().any(|v| v.plant == plant),
            "{}: not a variant's plant",
            d.display()
        );
        let c = host_sim::io::config::load_config(d.join("config.toml")).expect("config.toml");
        let mut p = host_sim::io::config::load_config(d.join("config_probing.toml"))
            .expect("config_probing.toml");
        assert!(!c.probe.enabled && p.probe.enabled);
        p.probe.enabled = false;
        assert_eq!(p, c);
        let name = d.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            r.md.contains(&format!("--plant variants/{name}/plant.toml")),
            "report.md tells how to rerun {name}"
        );
    }
}

#[test]
fn the_clean_programme_depends_only_on_the_seed() {
    // The same seed on one thread and without step 7 gives the same clean
    // figures, bit for bit, as the two-thread run with step 7. (On the clean
    // plant the seed drives only the current monitor's noise, which the
    // control path does not read: the DOB takes the current reference.)
    let r = run();
    let f = &r.map;
    let dir = tempfile::tempdir().expect("temp dir");
    let again = |seed: u64, sub: &str| -> BTreeMap<String, f64> {
        let args = ReportOptions {
            out: dir.path().join(sub),
            seed,
            duration_scale: SCALE,
            no_effects: true,
            serial: true,
            quiet: true,
            ..ReportOptions::default()
        };
        let rep = generate(&args).expect("report runs");
        host_sim::report::render::figure_map(&rep)
    };
    let same = again(SEED, "same");
    let mut compared = 0;
    for (k, v) in &same {
        if k == "runtime_s" {
            continue;
        }
        assert!(k.starts_with("clean."), "{k} without step 7");
        assert_eq!(Some(v), f.get(k), "{k} differs between runs with one seed");
        compared += 1;
    }
    assert!(compared > 100);
}

/// All or none: when one output cannot be written (here `report.json` is a
/// directory), the run leaves no figure, configuration or report behind.
#[test]
fn a_report_that_cannot_be_written_leaves_nothing_behind() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("report");
    std::fs::create_dir_all(out.join("report.json")).expect("a directory in the way");
    let args = ReportOptions {
        out: out.clone(),
        seed: SEED,
        duration_scale: 0.05,
        no_effects: true,
        quiet: true,
        ..ReportOptions::default()
    };
    let mut r = generate(&args).expect("report runs");
    assert!(!r.figures.is_empty(), "figures were staged");
    let err = write(&mut r).expect_err("report.json is a directory");
    assert!(format!("{err:#}").contains("report.json"), "{err:#}");
    let left: Vec<String> = std::fs::read_dir(&out)
        .expect("output dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, ["report.json"], "nothing written beside the obstacle");
}
