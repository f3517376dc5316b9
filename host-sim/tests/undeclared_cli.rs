//! `host-sim undeclared` end to end on its smallest programme (one drawn
//! plant, one rate, the upper size, single effects): both files written,
//! one row per effect on the model it moves, with the clean reference, the
//! errors before and after and a verdict; a bad option refused by name.

use std::process::Command;

use host_sim::residual::programme::VISIBLE_RISE;

#[test]
fn the_smallest_programme_writes_one_judged_row_per_effect() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("u");
    let exe = env!("CARGO_BIN_EXE_host-sim");
    let o = Command::new(exe)
        .args([
            "undeclared",
            "--draw",
            "41",
            "--rate",
            "2000",
            "--size",
            "upper",
            "--singles",
            "--quiet",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("upper size, 2000 Hz: single effects visible"),
        "{stdout}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("undeclared.json")).unwrap())
            .unwrap();
    let rows = json["rows"].as_array().unwrap();
    let moved = [
        ("creep", "Jae"),
        ("spring", "Jae"),
        ("presliding", "Tension"),
        ("thermal", "Tension"),
        ("drift", "Tension"),
    ];
    assert_eq!(rows.len(), moved.len());
    for (r, (effect, model)) in rows.iter().zip(moved) {
        assert_eq!(r["effects"][0], effect);
        assert_eq!(r["model"], model, "{effect}");
        assert_eq!(r["draw"], 41);
        for k in ["clean_rmse", "before_rmse", "after_rmse"] {
            let v = r[k].as_f64().unwrap();
            assert!(v.is_finite() && v > 0.0, "{effect}: {k} = {v}");
        }
        // The loop never makes the fitted run's validation worse.
        assert!(
            r["after_rmse"].as_f64() <= r["before_rmse"].as_f64(),
            "{effect}"
        );
        // The verdict the row's own numbers and terms give: below the noise
        // when the effect raised the error by less than VISIBLE_RISE, else
        // named when the first term the clean run did not also take is of
        // the effect's family.
        let verdict = r["verdict"].as_str().unwrap();
        let (clean, before) = (
            r["clean_rmse"].as_f64().unwrap(),
            r["before_rmse"].as_f64().unwrap(),
        );
        let strs = |k: &str| -> Vec<String> {
            r[k].as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_str().unwrap().to_owned())
                .collect()
        };
        let (expected, classes) = (strs("expected"), strs("classes"));
        let also_clean: Vec<bool> = r["also_clean"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_bool().unwrap())
            .collect();
        let first_new = classes
            .iter()
            .zip(also_clean.iter().chain(std::iter::repeat(&false)))
            .find(|(_, c)| !**c)
            .map(|(c, _)| c);
        let want = if before < VISIBLE_RISE * clean {
            "below_noise"
        } else if first_new == expected.first() {
            "named"
        } else {
            "missed"
        };
        assert_eq!(verdict, want, "{effect}: {r}");
    }
    assert_eq!(
        json["clean"].as_array().unwrap().len(),
        2,
        "JAE and tension"
    );
    let md = std::fs::read_to_string(out.join("undeclared.md")).unwrap();
    assert!(
        md.contains("30 % of the elastic stretch, 10 s"),
        "the physics of each size"
    );

    let o = Command::new(exe)
        .args(["undeclared", "--rate", "NaN", "--out"])
        .arg(dir.path().join("bad"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--rate"));
    assert!(!dir.path().join("bad").exists(), "nothing written");

    let o = Command::new(exe)
        .args(["undeclared", "--record-every", "0", "--out"])
        .arg(dir.path().join("bad"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--record-every"));
    assert!(!dir.path().join("bad").exists(), "nothing written");
}
