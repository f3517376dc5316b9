//! The configuration file: what `identify` writes loads back equal, partial
//! files take the datasheet defaults, and a bad file gets an error that
//! names the file and the field.

use std::path::Path;

use cable_joint::effects::Term;
use cable_joint::Config;
use host_sim::io::config::{load_config, write_config};

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

#[test]
fn written_configuration_loads_back_equal() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.toml");
    let mut c = Config::default();
    // Identified-looking values with full f32 precision, and an added term.
    c.dob.viscous_nm_s_rad = 1.688_593_1e-5;
    c.jae.c_pos_rad_m = 264.968_33;
    c.jae.offset_rad = -5.582_2e-4;
    c.tension.f_sc1_n = 8.811_24;
    c.tension.f_cp2_n = 0.0;
    c.tension.k_s_n_m = 679.820_9;
    assert!(c.tension.added.push(Term::CONSTANT, 0.25));
    write_config(&path, &c).unwrap();
    let back = load_config(&path).unwrap();
    assert_eq!(back, c);
    // Overwriting keeps working (rename over the old file), no temp left.
    c.tension.f_0_n = 19.539_22;
    write_config(&path, &c).unwrap();
    assert_eq!(load_config(&path).unwrap(), c);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names, vec!["c.toml".to_owned()], "no temporary file left");
}

#[test]
fn partial_file_takes_the_datasheet_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("partial.toml");
    write(&path, "[dob]\nviscous_nm_s_rad = 2.0e-5\n");
    let c = load_config(&path).unwrap();
    let mut want = Config::default();
    want.dob.viscous_nm_s_rad = 2.0e-5;
    assert_eq!(c, want);
}

fn load_err(text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    write(&path, text);
    let msg = format!("{:#}", load_config(&path).unwrap_err());
    assert!(msg.contains("bad.toml"), "names the file: {msg}");
    msg
}

#[test]
fn bad_files_name_the_field() {
    // A value Config::validate rejects.
    let msg = load_err("[dob]\nviscous_nm_s_rad = -1.0\n");
    assert!(msg.contains("dob.viscous_nm_s_rad"), "{msg}");
    let msg = load_err("[machine]\ngear_ratio = 0.0\n");
    assert!(msg.contains("machine.gear_ratio"), "{msg}");
    // An unknown key (a typo) is not silently ignored.
    let msg = load_err("[tension]\nk_s_nm = 700.0\n");
    assert!(msg.contains("k_s_nm"), "{msg}");
    // A type error names the key.
    let msg = load_err("[jae]\nc_pos_rad_m = \"264\"\n");
    assert!(msg.contains("c_pos_rad_m"), "{msg}");
    // Not TOML at all: the line is given.
    let msg = load_err("[jae\n");
    assert!(msg.contains("line 1"), "{msg}");
    // A missing file.
    let msg = format!("{:#}", load_config("/nonexistent/c.toml").unwrap_err());
    assert!(msg.contains("/nonexistent/c.toml"), "{msg}");
}

#[test]
fn write_refuses_invalid_configs_and_non_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.toml");
    write(&path, "# old\n");
    let mut c = Config::default();
    c.tension.k_s_n_m = f32::NAN;
    let msg = format!("{:#}", write_config(&path, &c).unwrap_err());
    assert!(msg.contains("tension.k_s_n_m"), "{msg}");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "# old\n");
    // A directory (or a device) is not replaced by the rename.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    let msg = format!("{:#}", write_config(&sub, &Config::default()).unwrap_err());
    assert!(msg.contains("not a regular file"), "{msg}");
    assert!(sub.is_dir());
}
