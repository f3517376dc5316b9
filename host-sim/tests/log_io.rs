//! The CSV log: round trip, the bad-input policy (one error naming file, line
//! and column) and atomic writing (DESIGN.md §2).

use std::fs;
use std::path::Path;

use host_sim::log::{Log, LogError, LogErrorKind, Schema, REQUIRED_COLUMNS};

/// A small project log: the required columns, an estimate column and an
/// optional column with unmeasured cells, with values that are hard to print.
fn sample_log(rows: usize) -> Log {
    let mut log = Log::with_columns(&[
        "t_s",
        "x1_m",
        "x2_m",
        "phi_rad",
        "i_ref_a",
        "theta_hat_rad",
        "f_ext_n",
    ])
    .unwrap();
    for k in 0..rows {
        let t = k as f64 * 1e-3;
        let f_ext = (k % 3 != 0).then_some(0.1 * k as f64 - 0.35);
        let awkward = [1e-300, -0.0, std::f64::consts::PI, 1e20, -2.5e-7, 0.1 + 0.2][k % 6];
        log.push_row_opt(&[
            Some(t),
            Some(1e-6 * (k as f64).sin()),
            Some(awkward),
            Some(-3.0 * t),
            Some(0.25),
            Some(k as f64 / 7.0),
            f_ext,
        ])
        .unwrap();
    }
    log
}

fn assert_bit_identical(a: &Log, b: &Log) {
    assert_eq!(a.names(), b.names(), "column names and order");
    assert_eq!(a.len(), b.len(), "row count");
    for name in a.names() {
        let (ca, cb) = (a.col(name).unwrap(), b.col(name).unwrap());
        for r in 0..a.len() {
            assert_eq!(
                a.is_measured(name, r),
                b.is_measured(name, r),
                "{name} row {r}: measured flag"
            );
            if a.is_measured(name, r) {
                assert_eq!(
                    ca[r].to_bits(),
                    cb[r].to_bits(),
                    "{name} row {r}: {} vs {}",
                    ca[r],
                    cb[r]
                );
            }
        }
    }
}

/// Reads `text` as the file `run.csv` with `schema`; must fail.
fn read_err(text: &str, schema: &Schema) -> LogError {
    match Log::from_reader(text.as_bytes(), "run.csv", schema) {
        Ok(log) => panic!("accepted a bad log ({} rows):\n{text}", log.len()),
        Err(e) => e,
    }
}

/// A valid project CSV with `rows` rows, as text lines (header first).
fn good_lines(rows: usize) -> Vec<String> {
    let mut lines = vec!["t_s,x1_m,x2_m,phi_rad,i_ref_a,f_ext_n".to_owned()];
    for k in 0..rows {
        lines.push(format!(
            "{},{},{},{},0.5,{}",
            k as f64 * 0.001,
            k,
            2 * k,
            -(k as f64),
            k
        ));
    }
    lines
}

fn join(lines: &[String]) -> String {
    lines.join("\n") + "\n"
}

fn dir_entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn round_trip_plain_and_gzip_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let log = sample_log(40);
    for file in ["run.csv", "run.csv.gz"] {
        let path = dir.path().join(file);
        log.write(&path).unwrap();
        let back = Log::read(&path).unwrap();
        assert_bit_identical(&log, &back);
        assert_eq!(log, back, "PartialEq agrees with the cell-by-cell check");
        assert_eq!(back.time_s().unwrap()[39], 39.0 * 1e-3);
        assert!(
            !back.is_measured("f_ext_n", 0),
            "an empty cell reads as not measured"
        );
        assert!(
            back.col("f_ext_n").unwrap()[0].is_nan(),
            "not measured reads as NaN via col()"
        );
        assert_eq!(back.col_opt("f_ext_n").unwrap()[1], Some(0.1 - 0.35));
        assert!(
            back.col_required("f_ext_n").is_err(),
            "partly measured column is not 'required'"
        );
        assert!(back.col_required("x2_m").is_ok());
    }
    let plain = fs::read(dir.path().join("run.csv")).unwrap();
    let gz = fs::read(dir.path().join("run.csv.gz")).unwrap();
    assert_eq!(&gz[..2], &[0x1f, 0x8b], ".gz output is gzip");
    assert!(plain.starts_with(b"t_s,x1_m,x2_m,phi_rad,i_ref_a,theta_hat_rad,f_ext_n\n"));
    // Extra columns keep their place; a replaced column keeps its position.
    let mut log2 = Log::read(dir.path().join("run.csv")).unwrap();
    log2.set_col("x1_m", vec![1.0; 40]).unwrap();
    log2.set_col("theta_rad", vec![2.0; 40]).unwrap();
    assert_eq!(
        log2.names(),
        [
            "t_s",
            "x1_m",
            "x2_m",
            "phi_rad",
            "i_ref_a",
            "theta_hat_rad",
            "f_ext_n",
            "theta_rad"
        ]
    );
    assert_eq!(log2.remove_col("theta_hat_rad").map(|v| v.len()), Some(40));
    assert!(!log2.has("theta_hat_rad"));
}

#[test]
fn reader_accepts_crlf_bom_spaces_and_trailing_blank_lines() {
    let mut text = join(&good_lines(12)).replace('\n', "\r\n");
    text.insert(0, '\u{feff}');
    text = text.replace(",0.5,", ", 0.5 ,");
    text.push_str("\r\n\r\n");
    let log = Log::from_reader(text.as_bytes(), "crlf.csv", &Schema::project()).unwrap();
    assert_eq!(log.len(), 12);
    assert_eq!(log.names()[0], "t_s");
    assert_eq!(log.col("i_ref_a").unwrap(), &[0.5; 12]);
}

/// A spreadsheet's export: every cell quoted, a BOM, CRLF line ends. It
/// reads as the plain file does; line numbers in errors stay the file's.
#[test]
fn quoted_cells_and_names_from_a_spreadsheet_read_as_the_plain_file() {
    let plain = join(&good_lines(12));
    let quote = |line: &str| {
        line.split(',')
            .map(|c| format!("\"{c}\""))
            .collect::<Vec<_>>()
            .join(",")
    };
    let mut quoted: String = plain.lines().map(|l| quote(l) + "\r\n").collect();
    quoted.insert(0, '\u{feff}');
    let a = Log::from_reader(plain.as_bytes(), "plain.csv", &Schema::project()).unwrap();
    let b = Log::from_reader(quoted.as_bytes(), "quoted.csv", &Schema::project()).unwrap();
    assert_bit_identical(&a, &b);
    // A bad quoted cell is named at its own line, as an unquoted one is.
    let bad = quoted.replacen("\"0.5\"", "\"abc\"", 4);
    let e = read_err(&bad, &Schema::project());
    assert!(
        matches!(e.kind, LogErrorKind::NotANumber(ref c) if c == "abc"),
        "{e}"
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(2), Some("i_ref_a")),
        "{e}"
    );
    // A quoted cell that spans lines would shift every later line: refused.
    let e = read_err(
        &quoted.replacen("\"0.5\"", "\"0.5\n\"", 1),
        &Schema::project(),
    );
    assert!(matches!(e.kind, LogErrorKind::NotANumber(_)), "{e}");
    assert_eq!(e.line, Some(2), "{e}");
}

#[test]
fn non_numeric_cell_names_file_line_and_column() {
    let mut lines = good_lines(30);
    // Line 17 of the file is data row 15 (the header is line 1).
    lines[16] = "0.015,15,abc,-15,0.5,15".to_owned();
    let e = read_err(&join(&lines), &Schema::project());
    assert_eq!(
        e.to_string(),
        r#"run.csv:17: column "x2_m": "abc" is not a number"#
    );
    assert_eq!((e.line, e.column.as_deref()), (Some(17), Some("x2_m")));
    assert!(matches!(e.kind, LogErrorKind::NotANumber(ref s) if s == "abc"));
}

#[test]
fn nan_and_infinite_text_are_errors() {
    for (bad, col, field) in [
        ("nan", "x1_m", 1),
        ("NaN", "phi_rad", 3),
        ("inf", "i_ref_a", 4),
        ("-inf", "t_s", 0),
        ("infinity", "f_ext_n", 5),
        ("1e999", "x2_m", 2),
    ] {
        let mut lines = good_lines(20);
        let mut cells: Vec<String> = lines[8].split(',').map(str::to_owned).collect();
        cells[field] = bad.to_owned();
        lines[8] = cells.join(",");
        let e = read_err(&join(&lines), &Schema::project());
        assert!(matches!(e.kind, LogErrorKind::NotFinite(_)), "{bad}: {e}");
        assert_eq!(
            (e.line, e.column.as_deref()),
            (Some(9), Some(col)),
            "{bad}: {e}"
        );
        assert!(
            e.to_string()
                .starts_with(&format!("run.csv:9: column \"{col}\"")),
            "{e}"
        );
    }
}

#[test]
fn empty_cell_allowed_only_in_optional_columns() {
    let mut lines = good_lines(20);
    lines[5] = "0.004,4,8,-4,0.5,".to_owned(); // f_ext_n empty: fine
    let log = Log::from_reader(join(&lines).as_bytes(), "run.csv", &Schema::project()).unwrap();
    assert!(!log.is_measured("f_ext_n", 4));
    assert!(log.is_measured("f_ext_n", 5));
    lines[11] = "0.010,10,,-10,0.5,10".to_owned(); // x2_m empty: required
    let e = read_err(&join(&lines), &Schema::project());
    assert!(matches!(e.kind, LogErrorKind::NotMeasured), "{e}");
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(12), Some("x2_m")),
        "{e}"
    );
}

#[test]
fn missing_required_column_is_reported_at_the_header() {
    for missing in REQUIRED_COLUMNS {
        let lines: Vec<String> = good_lines(20)
            .iter()
            .map(|l| {
                let header = good_lines(0)[0].clone();
                let idx = header.split(',').position(|h| h == missing).unwrap();
                l.split(',')
                    .enumerate()
                    .filter(|(i, _)| *i != idx)
                    .map(|(_, c)| c)
                    .collect::<Vec<_>>()
                    .join(",")
            })
            .collect();
        let e = read_err(&join(&lines), &Schema::project());
        assert!(matches!(e.kind, LogErrorKind::MissingColumn), "{e}");
        assert_eq!(
            (e.line, e.column.as_deref()),
            (Some(1), Some(missing)),
            "{e}"
        );
        // The same file is fine when that column is not required.
        let others: Vec<&str> = REQUIRED_COLUMNS
            .iter()
            .copied()
            .filter(|c| *c != missing)
            .collect();
        let ok = Log::from_reader(
            join(&lines).as_bytes(),
            "run.csv",
            &Schema::with_required(&others),
        );
        assert!(
            ok.is_ok(),
            "custom schema without {missing}: {:?}",
            ok.err()
        );
    }
}

#[test]
fn custom_schema_requires_its_own_columns() {
    let text = "t_s,phi_rad,theta_rad\n0,0,0\n0.001,0.1,0.01\n0.002,0.2,0.02\n";
    let schema = Schema::with_required(&["t_s", "phi_rad", "theta_rad", "tau_ext_nm"]).min_rows(2);
    let e = read_err(text, &schema);
    assert_eq!(
        e.to_string(),
        r#"run.csv:1: column "tau_ext_nm": required column is missing"#
    );
    let schema = Schema::with_required(&["t_s", "phi_rad"]).min_rows(2);
    let log = Log::from_reader(text.as_bytes(), "run.csv", &schema).unwrap();
    assert_eq!(log.col("theta_rad").unwrap(), &[0.0, 0.01, 0.02]);
}

#[test]
fn time_must_increase_strictly() {
    for (bad_t, line) in [("0.005", 8), ("0.004", 8), ("-1", 15)] {
        let mut lines = good_lines(20);
        let idx = line - 1;
        let mut cells: Vec<String> = lines[idx].split(',').map(str::to_owned).collect();
        cells[0] = bad_t.to_owned();
        lines[idx] = cells.join(",");
        // Line 8 holds t = 0.006; line 7 holds 0.005.
        let e = read_err(&join(&lines), &Schema::project());
        assert!(
            matches!(e.kind, LogErrorKind::NonIncreasingTime { .. }),
            "{bad_t}: {e}"
        );
        assert_eq!(
            (e.line, e.column.as_deref()),
            (Some(line), Some("t_s")),
            "{bad_t}: {e}"
        );
    }
    // Without a time column in the schema, the same file is accepted.
    let mut lines = good_lines(20);
    lines[7] = lines[6].clone();
    let schema = Schema::project().time_column(None);
    assert!(Log::from_reader(join(&lines).as_bytes(), "run.csv", &schema).is_ok());
}

#[test]
fn too_few_rows_is_an_error_with_a_configurable_minimum() {
    let text = join(&good_lines(5));
    let e = read_err(&text, &Schema::project());
    assert!(
        matches!(e.kind, LogErrorKind::TooFewRows { rows: 5, min: 10 }),
        "{e}"
    );
    assert_eq!(e.line, Some(6), "points at the last line: {e}");
    assert!(e.to_string().starts_with("run.csv:6: "), "{e}");
    let log = Log::from_reader(text.as_bytes(), "run.csv", &Schema::project().min_rows(5)).unwrap();
    assert_eq!(log.len(), 5);
    let e = read_err("t_s,x1_m,x2_m,phi_rad,i_ref_a\n", &Schema::project());
    assert!(
        matches!(e.kind, LogErrorKind::TooFewRows { rows: 0, .. }),
        "{e}"
    );
    let e = read_err("", &Schema::project());
    assert!(matches!(e.kind, LogErrorKind::EmptyFile), "{e}");
}

#[test]
fn ragged_rows_name_the_missing_or_extra_column() {
    let mut lines = good_lines(20);
    lines[10] = "0.009,9,18".to_owned();
    let e = read_err(&join(&lines), &Schema::project());
    assert!(
        matches!(
            e.kind,
            LogErrorKind::TooFewFields {
                found: 3,
                expected: 6
            }
        ),
        "{e}"
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(11), Some("phi_rad")),
        "{e}"
    );

    let mut lines = good_lines(20);
    lines[3] = format!("{},7", lines[3]);
    let e = read_err(&join(&lines), &Schema::project());
    assert!(
        matches!(
            e.kind,
            LogErrorKind::TooManyFields {
                found: 7,
                expected: 6
            }
        ),
        "{e}"
    );
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(4), Some("f_ext_n")),
        "{e}"
    );

    // A blank line inside the data is a (short) row, not skipped.
    let mut lines = good_lines(20);
    lines[6] = String::new();
    let e = read_err(&join(&lines), &Schema::project());
    assert!(
        matches!(e.kind, LogErrorKind::TooFewFields { found: 0, .. }),
        "{e}"
    );
    assert_eq!((e.line, e.column.as_deref()), (Some(7), Some("t_s")), "{e}");
}

#[test]
fn bad_headers_are_reported() {
    let e = read_err("t_s,x1_m,x1_m,x2_m,phi_rad,i_ref_a\n", &Schema::project());
    assert!(matches!(e.kind, LogErrorKind::DuplicateColumn), "{e}");
    assert_eq!((e.line, e.column.as_deref()), (Some(1), Some("x1_m")));
    let e = read_err("t_s,,x1_m\n", &Schema::any());
    assert!(matches!(e.kind, LogErrorKind::BadName), "{e}");
    // A semicolon- or tab-separated export is named as such at its header,
    // not as a log missing every column.
    for (sep, what) in [(';', "`;`"), ('\t', "tabs")] {
        let text = join(&good_lines(20)).replace(',', &sep.to_string());
        let e = read_err(&text, &Schema::project());
        assert!(
            matches!(e.kind, LogErrorKind::NotCommaSeparated(c) if c == sep),
            "{e}"
        );
        assert_eq!(e.line, Some(1), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains(what) && msg.contains("comma-separated"),
            "{msg}"
        );
    }
}

#[test]
fn gzip_input_reports_lines_of_the_decompressed_text() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let mut lines = good_lines(25);
    lines[20] = "0.019,19,38,-19,0.5,x".to_owned();
    let path = dir.path().join("bad.csv.gz");
    let mut enc = flate2::write::GzEncoder::new(
        fs::File::create(&path).unwrap(),
        flate2::Compression::fast(),
    );
    enc.write_all(join(&lines).as_bytes()).unwrap();
    enc.finish().unwrap();
    let e = Log::read(&path).unwrap_err();
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(21), Some("f_ext_n")),
        "{e}"
    );
    assert_eq!(e.file, path.display().to_string());
    assert!(e
        .to_string()
        .starts_with(&format!("{}:21: column \"f_ext_n\"", path.display())));
}

#[test]
fn writing_a_nan_is_refused_before_anything_is_touched() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.csv");
    fs::write(&path, "old contents\n").unwrap();
    let mut log = sample_log(20);
    let mut x2 = log.col("x2_m").unwrap().to_vec();
    x2[13] = f64::NAN;
    log.set_col("x2_m", x2).unwrap();
    let e = log.write(&path).unwrap_err();
    assert!(matches!(e.kind, LogErrorKind::NotFinite(_)), "{e}");
    assert_eq!(
        (e.line, e.column.as_deref()),
        (Some(15), Some("x2_m")),
        "row 13 is line 15: {e}"
    );
    assert_eq!(
        fs::read_to_string(&path).unwrap(),
        "old contents\n",
        "old file untouched"
    );
    assert_eq!(
        dir_entries(dir.path()),
        ["run.csv"],
        "no temporary file left"
    );

    let mut log = sample_log(20);
    let mut t = log.col("t_s").unwrap().to_vec();
    t[2] = f64::INFINITY;
    log.set_col("t_s", t).unwrap();
    assert!(log.write(dir.path().join("new.csv")).is_err());
    assert_eq!(
        dir_entries(dir.path()),
        ["run.csv"],
        "no output created for a refused log"
    );
}

#[test]
fn failed_rename_leaves_target_and_directory_as_they_were() {
    // The target is a non-empty directory: the data can be written to the
    // temporary file but the rename fails (also as root, unlike a read-only
    // directory).
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("run.csv");
    fs::create_dir(&target).unwrap();
    fs::write(target.join("keep.txt"), "keep").unwrap();
    let e = sample_log(20).write(&target).unwrap_err();
    assert!(matches!(e.kind, LogErrorKind::Io(_)), "{e}");
    assert!(
        e.to_string().starts_with(&target.display().to_string()),
        "{e}"
    );
    assert_eq!(
        dir_entries(dir.path()),
        ["run.csv"],
        "no temporary file left"
    );
    assert_eq!(fs::read_to_string(target.join("keep.txt")).unwrap(), "keep");

    // A directory that does not exist: nothing is created.
    let missing = dir.path().join("nope").join("run.csv");
    assert!(sample_log(20).write(&missing).is_err());
    assert!(!dir.path().join("nope").exists());
}

#[test]
fn replacing_an_existing_file_is_complete() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.csv");
    fs::write(&path, "x".repeat(100_000)).unwrap();
    let log = sample_log(15);
    log.write(&path).unwrap();
    assert_eq!(Log::read(&path).unwrap(), log);
    assert_eq!(dir_entries(dir.path()), ["run.csv"]);
}

#[test]
fn programmatic_edits_are_checked() {
    let mut log = sample_log(12);
    let e = log.set_col("x3_m", vec![0.0; 11]).unwrap_err();
    assert!(
        matches!(
            e.kind,
            LogErrorKind::LengthMismatch {
                expected: 12,
                found: 11
            }
        ),
        "{e}"
    );
    assert!(log.push_row(&[0.0; 3]).is_err());
    assert!(log.set_col("bad,name", vec![0.0; 12]).is_err());
    assert_eq!(log.len(), 12, "failed edits change nothing");
    let e = log.col_required("nope").unwrap_err();
    assert!(matches!(e.kind, LogErrorKind::UnknownColumn), "{e}");

    // validate() applies the read-time rules to a log built in memory.
    assert!(log.validate(&Schema::project(), "mem").is_ok());
    let mut t = log.col("t_s").unwrap().to_vec();
    t[4] = t[3];
    log.set_col("t_s", t).unwrap();
    let e = log.validate(&Schema::project(), "mem").unwrap_err();
    assert_eq!((e.line, e.column.as_deref()), (Some(6), Some("t_s")), "{e}");
    log.remove_col("i_ref_a");
    let e = log
        .validate(&Schema::project().time_column(None), "mem")
        .unwrap_err();
    assert!(matches!(e.kind, LogErrorKind::MissingColumn), "{e}");
}
