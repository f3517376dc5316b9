//! Configuration files, one way for every command: read (missing tables and
//! keys take the datasheet defaults, then [`Config::validate`]) and written
//! (checked first, atomically, for people to read and review); the
//! simulated plant's parameters.

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use cable_joint::config::{RateAdjustment, RATE_DERIVED_FIELDS};
use cable_joint::Config;

use crate::log::toml_error;
use crate::output::Outputs;
use crate::plant::PlantParams;

/// Read and check a configuration file (TOML), and say on stderr what it
/// derived ([`load_config_noted`]).
pub fn load_config(path: impl AsRef<Path>) -> Result<Config> {
    let path = path.as_ref();
    let (config, notes) = load_config_noted(path)?;
    for n in notes {
        eprintln!("note: {}: {n}", path.display());
    }
    Ok(config)
}

/// Read and check a configuration file (TOML). Missing tables and keys take
/// the datasheet defaults, except the rate-dependent settings: those the
/// file leaves out and that the datasheet's values cannot serve at the
/// file's `control_rate_hz` are derived from that rate ([`Config::at_rate`]),
/// each with a note for the caller to print. A setting the file gives is
/// kept as given. An unknown key, a type error or a value that
/// [`Config::validate`] rejects is an error naming the file and the field.
pub fn load_config_noted(path: impl AsRef<Path>) -> Result<(Config, Vec<String>)> {
    load_config_at(path.as_ref(), None)
}

/// [`load_config_noted`] for a log recorded at `rate_hz`: where the file's
/// `control_rate_hz` is another (by more than 1 %), the log's rate is
/// taken instead and the settings the file leaves out are derived at it,
/// with a warning among the notes where the file gives its rate (the
/// settings the file gives are kept, and checked at the log's rate).
pub fn load_config_for_rate(path: &Path, rate_hz: f64) -> Result<(Config, Vec<String>)> {
    load_config_at(path, Some(rate_hz))
}

/// [`load_config_for_rate`] at the control rate of the first of `logs`
/// (name, log), the one a command fits or replays first; a note where
/// another of them runs at another rate (the replay then derives, at each
/// log's own rate, the settings that do not fit it).
pub fn load_config_for_logs(
    path: &Path,
    logs: &[(&str, &crate::log::Log)],
) -> Result<(Config, Vec<String>)> {
    let mut rates = Vec::with_capacity(logs.len());
    for (name, log) in logs {
        let clock =
            crate::derive::log_clock(log).with_context(|| format!("the control rate of {name}"))?;
        rates.push((*name, clock.rate_hz()));
    }
    let Some(&(first, rate_hz)) = rates.first() else {
        return load_config_noted(path);
    };
    let (config, mut notes) = load_config_for_rate(path, rate_hz)?;
    let others: Vec<String> = rates
        .iter()
        .filter(|(_, r)| (r - rate_hz).abs() > 0.01 * rate_hz)
        .map(|(n, r)| format!("{n} at {r:.1} Hz"))
        .collect();
    if !others.is_empty() {
        notes.push(format!(
            "taken at {first}'s {rate_hz:.1} Hz, but {} run at another rate: for each of \
             them the replay derives the rate-dependent settings that do not fit its rate",
            others.join(", ")
        ));
    }
    Ok((config, notes))
}

fn load_config_at(path: &Path, log_rate_hz: Option<f64>) -> Result<(Config, Vec<String>)> {
    crate::output::note_input(path);
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading configuration {}", path.display()))?;
    let parse_err = |e: toml::de::Error| anyhow!("{}: {}", path.display(), toml_error(&text, &e));
    let mut table: toml::Table = toml::from_str(&text).map_err(parse_err)?;
    let mut config: Config = toml::from_str(&text).map_err(parse_err)?;
    let mut notes = Vec::new();
    // The file's own rate where the log's replaced it.
    let mut made_for_hz = None;
    if let Some(log_hz) = log_rate_hz {
        let file_hz = f64::from(config.control_rate_hz);
        // The log's rate replaces the file's, but a rate no board runs at
        // is a broken file, not another rate.
        let rates = &cable_joint::config::CONTROL_RATE_RANGE_HZ;
        if has_key(&table, "control_rate_hz") && !rates.contains(&config.control_rate_hz) {
            return Err(anyhow!(
                "{}: control_rate_hz = {} is not a control rate (the core runs at {} to {} Hz)",
                path.display(),
                crate::log::value_text(file_hz),
                rates.start(),
                rates.end()
            ));
        }
        if (file_hz - log_hz).abs() > 0.01 * log_hz {
            if has_key(&table, "control_rate_hz") {
                made_for_hz = Some(file_hz);
                notes.push(format!(
                    "warning: control_rate_hz = {file_hz} in the file, but the log runs at \
                     {log_hz:.1} Hz: taken at {log_hz:.1} Hz, the rate-dependent settings the \
                     file leaves out derived at it (the file was made for another rate: check \
                     the ones it gives)"
                ));
            }
            set_key(&mut table, "control_rate_hz", toml::Value::Float(log_hz));
            config = table
                .clone()
                .try_into()
                .map_err(|e: toml::de::Error| anyhow!("{}: {e}", path.display()))?;
        }
    }
    let rate_hz = config.control_rate_hz;
    let (_, changes) = config.at_rate(rate_hz);
    // The rate-dependent settings the file itself gives (kept as given).
    let given_rate_fields: Vec<&str> = RATE_DERIVED_FIELDS
        .into_iter()
        .filter(|f| has_key(&table, f))
        .collect();
    let missing: Vec<_> = changes
        .iter()
        .filter(|a| !has_key(&table, a.field))
        .collect();
    let missing_none = missing.is_empty();
    for a in missing {
        let value = if a.flag {
            toml::Value::Boolean(a.to != 0.0)
        } else {
            toml::Value::Float(f64::from(a.to))
        };
        set_key(&mut table, a.field, value);
        notes.push(rate_adjustment_note(
            a,
            "not in the file; the default",
            rate_hz as f32,
        ));
    }
    let config: Config = if missing_none {
        config
    } else {
        table
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| anyhow!("{}: {e}", path.display()))?
    };
    config.validate().map_err(|e| {
        // Only a rate-dependent setting the file gives was kept against the
        // rate; any other rejected value has nothing to do with it.
        if given_rate_fields.contains(&e.field) {
            anyhow!(
                "{}: {e}{} (at control_rate_hz = {rate_hz}: the value in the file is kept; leave it out to derive it from the rate){}",
                path.display(),
                given_value(&table, e.field),
                made_for_hz.map_or_else(String::new, |file_hz| another_rate_hint(file_hz, rate_hz))
            )
        } else {
            anyhow!(
                "{}: {e}{}{}",
                path.display(),
                given_value(&table, e.field),
                added_term_detail(&config, e.field)
            )
        }
    })?;
    Ok((config, notes))
}

/// Why a file made for `file_hz` may meet a log taken at `log_hz`: the log
/// runs at its rows' own rate, and a recording kept at a row every N-th
/// tick without the board's tick counter reads as N times slower
/// ([`ticks_per_row_hint`]).
fn another_rate_hint(file_hz: f64, log_hz: f32) -> String {
    format!(
        ". The file was made for {file_hz} Hz and the log's rows run at {log_hz:.1} Hz{}",
        ticks_per_row_hint(file_hz, f64::from(log_hz))
            .map_or_else(String::new, |h| format!(": {h}"))
    )
}

/// The line for a setting [`Config::at_rate`] derived at `rate_hz`:
/// `field = to (WHOSE from does not fit control_rate_hz = RATE, so derived
/// from it)`, the rate to a tenth of a hertz (a log's rate comes from its
/// time steps, 999.99994 Hz in `f32`), `whose` naming where the value it replaces came from ("the
/// default", "the tuned", "the configuration's").
pub fn rate_adjustment_note(a: &RateAdjustment, whose: &str, rate_hz: f32) -> String {
    format!(
        "{} = {} ({whose} {} does not fit control_rate_hz = {rate_hz:.1}, so derived from it)",
        a.field,
        a.to_text(),
        a.from_text()
    )
}

/// When a configuration's `file_hz` is a whole multiple N ≥ 2 of the
/// rate a log's rows run at, `log_hz` (a log without the board's tick
/// counter, whose rate is its rows' own): what `--ticks-per-row N` is for.
pub fn ticks_per_row_hint(file_hz: f64, log_hz: f64) -> Option<String> {
    let ratio = file_hz / log_hz;
    let n = ratio.round();
    (n >= 2.0 && (ratio - n).abs() <= 0.01 * n).then(|| {
        format!(
            "if the log was recorded at a row every {n} ticks of a {file_hz} Hz loop and has no \
             tick column, give --ticks-per-row {n}"
        )
    })
}

/// Which term of an added-term bank (`field` `jae.added` or
/// `tension.added`) the configuration's check refused, and why: ": term K
/// ..." (counted from 0, the order of `[[FIELD.kind]]` in the file), or
/// nothing for another field.
fn added_term_detail(config: &Config, field: &str) -> String {
    let bank = match field {
        "jae.added" => &config.jae.added,
        "tension.added" => &config.tension.added,
        _ => return String::new(),
    };
    if let Some(e) = bank.term_error() {
        return format!(": {e}");
    }
    bank.active()
        .iter()
        .zip(&bank.coef)
        .position(|(_, c)| !c.is_finite())
        .map_or_else(String::new, |k| {
            format!(": term {k}: `coef` is {}", bank.coef[k])
        })
}

/// Whether the dotted `field` (`cascade.kp_vel_a_s_rad`) is set in `table`.
fn has_key(table: &toml::Table, field: &str) -> bool {
    get_key(table, field).is_some()
}

/// The value of the dotted `field` in `table`, if it is set.
fn get_key<'a>(table: &'a toml::Table, field: &str) -> Option<&'a toml::Value> {
    let mut t = table;
    let mut parts = field.split('.').peekable();
    while let Some(p) = parts.next() {
        match (t.get(p), parts.peek()) {
            (Some(v), None) => return Some(v),
            (Some(toml::Value::Table(sub)), Some(_)) => t = sub,
            _ => return None,
        }
    }
    None
}

/// ", the file gives VALUE" for a number or flag the file sets at `field`
/// (what a range error refused), else nothing.
fn given_value(table: &toml::Table, field: &str) -> String {
    match get_key(table, field) {
        Some(toml::Value::Float(x)) => format!(" (the file gives {})", crate::log::value_text(*x)),
        Some(v @ (toml::Value::Integer(_) | toml::Value::Boolean(_))) => {
            format!(" (the file gives {v})")
        }
        _ => String::new(),
    }
}

/// Set the dotted `field` in `table`, creating the tables on its way.
fn set_key(table: &mut toml::Table, field: &str, value: toml::Value) {
    match field.split_once('.') {
        None => {
            table.insert(field.to_owned(), value);
        }
        Some((head, rest)) => {
            let sub = table
                .entry(head.to_owned())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(sub) = sub {
                set_key(sub, rest, value);
            }
        }
    }
}

/// The parts of `config` the force estimate rests on that are still the
/// datasheet plant's (equal to [`Config::default`]'s), each named with its
/// keys: until `host-sim identify` has fitted them on this machine's
/// calibration runs, the DOB's friction bands, the stretch estimate's scale
/// and the slack limit are another machine's. Empty when every one was
/// identified (or set by hand to other values).
pub fn datasheet_force_parts(config: &Config) -> Vec<&'static str> {
    let d = Config::default();
    let mut parts = Vec::new();
    if config.jae.is_datasheet() {
        parts.push("the JAE ([jae] c_*, offset_rad; --procedure jae)");
    }
    if config.tension.is_datasheet() {
        parts.push(
            "the tension model ([tension] f_sc1_n, f_cp2_n, k_s_n_m, f_0_n; --procedure tension)",
        );
    }
    if (config.stretch.cable1_n_m, config.stretch.cable2_n_m)
        == (d.stretch.cable1_n_m, d.stretch.cable2_n_m)
    {
        parts.push("the cables' stiffnesses ([stretch]; --procedure jae)");
    }
    if config.fusion.pin_coulomb_nm == d.fusion.pin_coulomb_nm {
        parts.push("the pin's friction (fusion.pin_coulomb_nm; --procedure jae)");
    }
    if motor_damping_is_datasheet(config) {
        parts.push("the motor's damping (dob.viscous_nm_s_rad; --procedure bm)");
    }
    parts
}

/// Whether the DOB's motor damping `B_m` (`dob.viscous_nm_s_rad`) is still
/// the datasheet plant's: no no-load motor run (`identify --procedure bm`)
/// has fitted it.
pub fn motor_damping_is_datasheet(config: &Config) -> bool {
    config.dob.viscous_nm_s_rad == Config::default().dob.viscous_nm_s_rad
}

/// A warning naming [`datasheet_force_parts`] of the configuration `what`
/// (a file name, or "the datasheet defaults"), or `None` when there are none.
pub fn datasheet_force_warning(config: &Config, what: &str) -> Option<String> {
    let parts = datasheet_force_parts(config);
    (!parts.is_empty()).then(|| {
        format!(
            "warning: {what}: still the datasheet plant's: {}. Until `host-sim identify \
             --procedure all` has fitted them on this machine's calibration runs, the DOB's \
             friction bands, the stretch estimate's scale and the slack limit are another \
             machine's, and the force bound may miss the load (while the JAE or the tension \
             model is the datasheet's, the bound is the stretch estimate's alone: the DOB's \
             interval rests on them)",
            parts.join("; ")
        )
    })
}

/// [`load_config`] when a file is given, else the datasheet defaults.
pub fn load_or_default(path: Option<&Path>) -> Result<Config> {
    path.map_or_else(|| Ok(Config::default()), load_config)
}

/// The plant parameters of a TOML file (merged key by key onto the
/// prototype's, [`PlantParams::from_toml_str`]), or the prototype's when no
/// file is given.
pub fn load_plant(path: Option<&Path>) -> Result<PlantParams> {
    let Some(path) = path else {
        return Ok(PlantParams::default());
    };
    crate::output::note_input(path);
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading plant parameters {}", path.display()))?;
    let plant = PlantParams::from_toml_str(&text).with_context(|| path.display().to_string())?;
    plant
        .validate()
        .with_context(|| path.display().to_string())?;
    Ok(plant)
}

/// `config` as the TOML text [`write_config`] writes: every number the
/// shortest decimal that reads back to the same `f32` (the core's type:
/// `0.0234`, not `0.023399999365210533`), only the effect terms in use,
/// sections in the order of [`Config`]'s fields, units in the key names.
pub fn to_toml(config: &Config) -> Result<String> {
    let mut value = toml::Value::try_from(config).context("serializing the configuration")?;
    shortest_f32(&mut value);
    drop_empty_lists(&mut value);
    let text = toml::to_string_pretty(&value).context("serializing the configuration")?;
    Ok(format!(
        "# cable-joint configuration (SI units, the unit in each key's name), written by host-sim.\n\n{text}"
    ))
}

/// Leave out every empty list (`jae.added`, `tension.added` with no effect
/// term): a file lists only what is in use, and reads back the same.
fn drop_empty_lists(v: &mut toml::Value) {
    if let toml::Value::Table(t) = v {
        t.retain(|_, v| !matches!(v, toml::Value::Array(a) if a.is_empty()));
        t.iter_mut().for_each(|(_, v)| drop_empty_lists(v));
    }
}

/// Replace every float that is an `f32` by the shortest decimal that reads
/// back to it (a float that is not an `f32` is left as it is).
fn shortest_f32(v: &mut toml::Value) {
    match v {
        toml::Value::Float(x) => {
            let f = *x as f32;
            if f64::from(f) == *x {
                if let Ok(short) = f.to_string().parse::<f64>() {
                    if short as f32 == f {
                        *x = short;
                    }
                }
            }
        }
        toml::Value::Array(a) => a.iter_mut().for_each(shortest_f32),
        toml::Value::Table(t) => t.iter_mut().for_each(|(_, v)| shortest_f32(v)),
        _ => {}
    }
}

/// Write `config` as TOML ([`to_toml`]), atomically ([`crate::output`]). An
/// invalid configuration is refused before the file system is touched.
pub fn write_config(path: impl AsRef<Path>, config: &Config) -> Result<()> {
    let mut out = Outputs::new();
    stage_config(&mut out, path, config)?;
    out.commit()?;
    Ok(())
}

/// Stage `config` as TOML among a command's outputs (written by
/// [`Outputs::commit`], all or none); checked as [`write_config`].
pub fn stage_config(out: &mut Outputs, path: impl AsRef<Path>, config: &Config) -> Result<()> {
    let path = path.as_ref();
    config
        .validate()
        .map_err(|e| anyhow!("refusing to write {}: {e}", path.display()))?;
    out.bytes(path, to_toml(config)?.as_bytes())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cable_joint::effects::{EffectKind, Term};
    use cable_joint::model::sig;

    #[test]
    fn ticks_per_row_is_named_only_for_a_whole_multiple_of_the_logs_rate() {
        let h = ticks_per_row_hint(2000.0, 1000.0).unwrap();
        assert!(h.ends_with("give --ticks-per-row 2"), "{h}");
        assert!(ticks_per_row_hint(2000.0, 200.0)
            .unwrap()
            .ends_with("--ticks-per-row 10"));
        for (file_hz, log_hz) in [(2000.0, 2000.0), (1000.0, 2000.0), (2000.0, 800.0)] {
            assert_eq!(
                ticks_per_row_hint(file_hz, log_hz),
                None,
                "{file_hz} / {log_hz}"
            );
        }
    }

    /// A log's rate comes from its time steps: the note names it to a
    /// tenth of a hertz, not as `f32` holds it.
    #[test]
    fn a_rate_note_names_the_rate_to_a_tenth_of_a_hertz() {
        let rate_hz = 999.999_94_f32;
        let (_, changes) = Config::default().at_rate(rate_hz);
        let a = changes.first().expect("2 kHz settings do not fit 1 kHz");
        let note = rate_adjustment_note(a, "the default", rate_hz);
        assert!(note.contains("control_rate_hz = 1000.0,"), "{note}");
        assert!(note.starts_with(a.field), "{note}");
    }

    #[test]
    fn numbers_are_written_shortest_and_read_back_equal() {
        let mut c = Config::default();
        c.jae.c_pos_rad_m = 264.902_68;
        c.jae.sign_switch_m_s = 2e-4;
        c.dob.viscous_nm_s_rad = 1.6934e-5;
        let text = to_toml(&c).unwrap();
        assert!(text.contains("sign_switch_m_s = 0.0002\n"), "{text}");
        assert!(text.contains("c_pos_rad_m = 264.90268\n"), "{text}");
        assert!(!text.contains("0.00019999"), "{text}");
        assert_eq!(toml::from_str::<Config>(&text).unwrap(), c);
    }

    #[test]
    fn only_the_effect_terms_in_use_are_written_with_their_signals_named() {
        let mut c = Config::default();
        let none = to_toml(&c).unwrap();
        assert!(!none.contains("added"), "no term, no table: {none}");
        let stop = EffectKind::Stop {
            half_width: 1.738e-5,
        };
        assert!(c.jae.added.push(Term::new(stop, sig::X2_M), 54.8));
        let product = Term::with_aux(EffectKind::Product, sig::X2_M, sig::I_MEAS_A);
        assert!(c.tension.added.push(product, -3.5));
        let text = to_toml(&c).unwrap();
        assert!(
            text.contains("[[jae.added]]\ninput = \"x2_m\"\ncoef = 54.8\n"),
            "{text}"
        );
        assert!(text.contains("half_width = 0.00001738"), "{text}");
        assert!(text.contains("aux = \"i_meas_a\""), "{text}");
        assert_eq!(
            text.matches("[[").count(),
            2,
            "two terms, no empty slots: {text}"
        );
        assert_eq!(toml::from_str::<Config>(&text).unwrap(), c);
    }

    #[test]
    fn the_slot_form_of_earlier_versions_is_still_read() {
        // As the slot writer wrote it: every slot, the unused ones constant.
        let mut text = String::from(
            "[jae.added]\nlen = 1\ncoef = [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n\n\
             [[jae.added.terms]]\nkind = \"Linear\"\ninput = 9\naux = 0\n",
        );
        for _ in 1..8 {
            text.push_str("\n[[jae.added.terms]]\nkind = \"Constant\"\ninput = 0\naux = 0\n");
        }
        let c: Config = toml::from_str(&text).unwrap();
        assert_eq!(c.jae.added.active(), &[Term::new(EffectKind::Linear, 9)]);
        assert_eq!(c.jae.added.coef[0], 2.0);
    }

    fn load_text(text: &str) -> Result<(Config, Vec<String>)> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        std::fs::write(&p, text).unwrap();
        load_config_noted(&p)
    }

    /// A file that sets only the rate: the settings the datasheet's values
    /// cannot serve at that rate are derived from it, each noted, and
    /// equal to what `Config::at_rate` derives; at 2 kHz nothing is.
    #[test]
    fn a_file_that_sets_only_the_rate_gets_the_rate_dependent_settings_derived() {
        let (c, notes) = load_text("control_rate_hz = 1000.0\n").unwrap();
        let (expected, changes) = Config::default().at_rate(1000.0);
        assert!(!changes.is_empty(), "1 kHz needs derived settings");
        assert_eq!(c, expected);
        assert_eq!(notes.len(), changes.len(), "{notes:?}");
        assert!(
            notes
                .iter()
                .any(|n| n.starts_with("differentiators.motor_bandwidth_hz = 100")),
            "{notes:?}"
        );
        let (c, notes) = load_text("control_rate_hz = 2000.0\n").unwrap();
        assert_eq!(c, Config::default());
        assert!(notes.is_empty(), "{notes:?}");
    }

    /// At 500 Hz the derivation also switches the position loop's
    /// derivative to the grating observer: the on/off setting is written
    /// as a TOML boolean and noted as `true`, and a file that says `false`
    /// keeps it.
    #[test]
    fn at_500_hz_the_derivative_from_the_observer_is_derived_as_a_flag() {
        let (c, notes) = load_text("control_rate_hz = 500.0\n").unwrap();
        assert_eq!(c, Config::default().at_rate(500.0).0);
        assert!(c.cascade.kd_on_observer_rate);
        assert!(
            notes.iter().any(|n| n.starts_with(
                "cascade.kd_on_observer_rate = true (not in the file; the default false"
            )),
            "{notes:?}"
        );
        let (c, notes) =
            load_text("control_rate_hz = 500.0\n[cascade]\nkd_on_observer_rate = false\n").unwrap();
        assert!(!c.cascade.kd_on_observer_rate);
        assert!(
            !notes
                .iter()
                .any(|n| n.starts_with("cascade.kd_on_observer_rate")),
            "{notes:?}"
        );
    }

    /// A rate-dependent setting the file gives is the user's: kept as given,
    /// and refused by `validate` when the rate cannot serve it, with the
    /// field named and how to have it derived.
    #[test]
    fn a_rate_dependent_setting_the_file_gives_is_kept_or_refused_never_replaced() {
        let (c, notes) =
            load_text("control_rate_hz = 1000.0\n[differentiators]\nmotor_bandwidth_hz = 80.0\n")
                .unwrap();
        assert_eq!(c.differentiators.motor_bandwidth_hz, 80.0);
        assert!(notes
            .iter()
            .all(|n| !n.starts_with("differentiators.motor")));
        let e =
            load_text("control_rate_hz = 1000.0\n[differentiators]\nmotor_bandwidth_hz = 150.0\n")
                .unwrap_err()
                .to_string();
        assert!(
            e.contains("motor_bandwidth_hz") && e.contains("leave it out"),
            "{e}"
        );
    }

    /// A refused value the rate has nothing to do with (the rate itself, a
    /// current limit) is named without the advice to leave it out for the
    /// rate to derive it: no rate derives it.
    #[test]
    fn a_refused_setting_the_rate_does_not_derive_gets_no_rate_advice() {
        for text in [
            "control_rate_hz = -5.0\n",
            "control_rate_hz = 1000.0\n[limits]\nmax_current_a = -1.0\n",
        ] {
            let e = load_text(text).unwrap_err().to_string();
            let field = if text.contains("limits") {
                "limits.max_current_a"
            } else {
                "control_rate_hz"
            };
            assert!(e.contains(field) && !e.contains("leave it out"), "{e}");
        }
    }

    #[test]
    fn an_unknown_signal_name_is_refused_with_the_names() {
        let text = "[[jae.added]]\ninput = \"x3_m\"\ncoef = 1.0\nkind = \"Linear\"\n";
        let e = toml::from_str::<Config>(text).unwrap_err().to_string();
        assert!(e.contains("x3_m") && e.contains("theta_motor_rad"), "{e}");
    }
}
