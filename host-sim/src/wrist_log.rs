//! A wrist's run as logs: one project CSV log per joint (each joint's
//! controller records its own, `host-sim link ... --record roll.csv`, or
//! the simulated wrist writes them, [`joint_logs`]), read back together as
//! Eq. 3's samples ([`replay`]) so Eq. 3 is identified on a rig's own free
//! run (`host-sim identify-wrist`).
//!
//! # Four logs, one run
//!
//! * Each log is read and replayed as any single joint's is (`estimate`,
//!   `identify`): rows before homing's end dropped, rows from a recorded
//!   fault on refused, a log kept at a row every N ticks filled tick by
//!   tick, and the core stepped on every tick with that joint's
//!   configuration. The replay's JAE angle and fused force estimate are
//!   what the wrist reads, as in the simulated wrist.
//! * Where every log has the host's wall clock (`t_unix_s`, which `host-sim
//!   link --record` stamps from when the records arrived on the host:
//!   [`crate::ingest::host_clock_offset_s`]), the four are aligned on it:
//!   the run starts at the latest of their first replayed ticks and ends
//!   at the earliest last one, so the four controllers need not have
//!   started together; logs that do not overlap are refused. The stamps'
//!   error is the link's shortest delay (milliseconds over a probe or
//!   USB) plus the crystals' drift against the host's clock.
//! * Without it the four are aligned on time since each one's first
//!   replayed tick: the four controllers must start their runs together
//!   (as `excite --wrist`'s per-joint files already need). Nothing in the
//!   logs can check that; what is checked is that the four run at one
//!   control rate and last equally long within the force estimate's
//!   low-pass time constant (`1 / dob.cutoff_rad_s`): a shift shorter than
//!   the estimate's own lag is within what the fit already absorbs, a
//!   longer one would couple one joint's torque to another's motion at the
//!   wrong time. Within it, the run is cut to the shortest log. Where the
//!   logs have the commanded angle, when each joint's first moves is
//!   noted, with a warning when they are further apart than that time
//!   constant: the logs' lengths can agree while their starts do not.
//! * A fault the replay latches is refused, naming the joint and the line.

use std::path::Path;

use anyhow::{bail, ensure, Context, Result};
use cable_joint::wrist::Geometry;
use cable_joint::Config;

use crate::derive::TickReplay;
use crate::ingest::{fault_words, ReplayEnd, HOST_CLOCK_COLUMN};
use crate::links::{sign_speeds_rad_s, Eq3Sample, Eq3Setting};
use crate::log::{line_of_row, Log};
use crate::output::Outputs;
use crate::wrist::{Eq3Timing, TipForce, WristParams, WristTick, JAW_A, JAW_B};

/// The joints' names, in the wrist's order (roll, pitch, jaw A, jaw B), as
/// options, file names and messages spell them.
pub const JOINT_NAMES: [&str; 4] = ["roll", "pitch", "jaw_a", "jaw_b"];

/// How the wrist was held and built, which no joint's log says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Holding {
    /// Gravity in the shaft frame (`x_0 y_0 z_0`, `cable_joint::wrist`),
    /// m/s².
    pub gravity_m_s2: [f64; 3],
    /// Each jaw's angle from the wrist axis at its `theta = 0` (where its
    /// controller homed), rad.
    pub jaw_open_rad: f64,
}

/// What [`replay`] does with a fault a joint's replay latches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnFault {
    /// Refuse the run (Eq. 3's fit needs every joint under control).
    Refuse,
    /// Cut the four logs at the first faulted tick, with a note (an
    /// estimate is good up to it; the drive was off from it on).
    Cut,
}

/// Four joints' logs replayed as one run.
#[derive(Clone, Debug)]
pub struct WristRun {
    /// One sample per control tick.
    pub samples: Vec<Eq3Sample>,
    /// Each joint's force estimate at its tip, per tick (what the samples'
    /// torques were made of, as the core gave it: Eq. 4's input).
    pub tip_n: Vec<[TipForce; 4]>,
    /// The jaws' reference tip force (`f_ext_n` of jaw A's and jaw B's
    /// logs: a reference sensor's, or the simulator's truth), per tick,
    /// where both logs have the column.
    pub reference_n: Option<Vec<[f64; 2]>>,
    /// What Eq. 3's fit needs besides the samples.
    pub setting: Eq3Setting,
    /// Each joint's tip distance `l_e` (its configuration's gripper
    /// length), m.
    pub gripper_length_m: [f64; 4],
    /// The control rate, Hz.
    pub rate_hz: f64,
    /// What the reading did: rows dropped, ticks filled, the cut.
    pub notes: Vec<String>,
}

/// Replay four joints' logs (`(name, log)`, in the wrist's order, as read
/// by [`read`]) with their configurations as one run, the wrist held and
/// built as `holding` says (module docs).
///
/// # Errors
/// A log the core cannot replay, control rates that differ, lengths that
/// differ by more than the estimate's time constant, jaws of different
/// lengths, a fault latched in the replay (with [`OnFault::Refuse`], or on
/// the first tick): each naming the joint.
pub fn replay(
    logs: &[(String, Log); 4],
    configs: &[Config; 4],
    holding: &Holding,
    on_fault: OnFault,
) -> Result<WristRun> {
    let mut notes = Vec::new();
    let mut replays = Vec::with_capacity(4);
    for (j, ((name, log), config)) in logs.iter().zip(configs).enumerate() {
        let r = TickReplay::new(log, config)
            .with_context(|| format!("{} ({name}): replaying it", JOINT_NAMES[j]))?;
        notes.extend(
            r.clock_notes
                .iter()
                .map(|n| format!("{} ({name}): {n}", JOINT_NAMES[j])),
        );
        replays.push(r);
    }
    let rate_hz = replays[0].config.control_rate_hz;
    for (j, r) in replays.iter().enumerate() {
        ensure!(
            r.config.control_rate_hz == rate_hz,
            "{} ({}) runs at {} Hz, {} ({}) at {rate_hz} Hz: the wrist's joints run at one control rate",
            JOINT_NAMES[j],
            logs[j].0,
            r.config.control_rate_hz,
            JOINT_NAMES[0],
            logs[0].0
        );
    }
    let cutoff_rad_s = replays[0].config.dob.cutoff_rad_s;
    for (j, r) in replays.iter().enumerate() {
        ensure!(
            r.config.dob.cutoff_rad_s == cutoff_rad_s,
            "{} ({})'s force estimate low-passes at {} rad/s, {} ({})'s at {cutoff_rad_s} rad/s: \
             Eq. 3 is read through one low-pass (dob.cutoff_rad_s)",
            JOINT_NAMES[j],
            logs[j].0,
            r.config.dob.cutoff_rad_s,
            JOINT_NAMES[0],
            logs[0].0
        );
    }
    let rate_hz = f64::from(rate_hz);
    let lag_s = 1.0 / f64::from(configs[0].dob.cutoff_rad_s);
    let (skip, on_clock) = align(logs, &replays, rate_hz, lag_s, &mut notes)?;
    let shortest = replays
        .iter()
        .zip(skip)
        .map(|(r, k)| r.log.len() - k)
        .min()
        .unwrap_or(0);
    if let Some(note) = motion_starts(&replays, skip, rate_hz, lag_s, on_clock) {
        notes.push(note);
    }
    let mut columns = Vec::with_capacity(4);
    let mut first_fault: Option<(usize, usize, String)> = None;
    for (j, r) in replays.iter().enumerate() {
        let col = |n: &str| {
            r.log
                .col_required(n)
                .map_err(|e| anyhow::anyhow!("{} ({}): {e}", JOINT_NAMES[j], logs[j].0))
        };
        let fault = &col("fault_code")?[skip[j]..];
        if let Some(k) = fault[..shortest].iter().position(|c| *c != 0.0) {
            let what = format!(
                "{} ({}): the replay latched {} at line {}",
                JOINT_NAMES[j],
                logs[j].0,
                fault_words(fault[k].clamp(0.0, 255.0) as u8),
                line_of_row(r.log_row(skip[j] + k))
            );
            if first_fault.as_ref().is_none_or(|(_, at, _)| k < *at) {
                first_fault = Some((j, k, what));
            }
        }
        columns.push([
            &col("theta_hat_rad")?[skip[j]..],
            &col("f_ext_fused_n")?[skip[j]..],
            &col("f_ext_lo_n")?[skip[j]..],
            &col("f_ext_hi_n")?[skip[j]..],
        ]);
    }
    let mut shortest = shortest;
    if let Some((_, k, what)) = first_fault {
        match on_fault {
            OnFault::Refuse => {
                bail!("{what}: a free run for Eq. 3 needs every joint under control throughout")
            }
            OnFault::Cut if k == 0 => {
                bail!("{what}, on its first replayed tick: nothing to estimate")
            }
            OnFault::Cut => {
                notes.push(format!(
                    "{what}: the run is cut there ({k} ticks, {:.3} s; its drive was off from then on)",
                    k as f64 / rate_hz
                ));
                shortest = k;
            }
        }
    }
    let reference: Option<[Vec<f64>; 2]> = match (
        replays[JAW_A].log.col("f_ext_n"),
        replays[JAW_B].log.col("f_ext_n"),
    ) {
        (Some(a), Some(b)) => Some([a[skip[JAW_A]..].to_vec(), b[skip[JAW_B]..].to_vec()]),
        _ => None,
    };
    let jaw_length_m = [JAW_A, JAW_B].map(|j| replays[j].config.machine.gripper_length_m);
    ensure!(
        jaw_length_m[0] == jaw_length_m[1],
        "jaw A's configuration has a gripper length of {} m, jaw B's {} m: the wrist's two jaws \
         are one length (cable_joint::wrist::Geometry)",
        jaw_length_m[0],
        jaw_length_m[1]
    );
    let replayed: [Config; 4] = core::array::from_fn(|j| replays[j].config);
    // One limit bounds both jaws: the larger of their drives' squeezes.
    let [a, b] = [JAW_A, JAW_B].map(|j| Geometry::with_jaws_of(&replayed[j].machine));
    let geometry = Geometry {
        force_limit_n: a.force_limit_n.max(b.force_limit_n),
        ..a
    };
    let l = replayed.map(|c| f64::from(c.machine.gripper_length_m));
    let (samples, tip_n) = (0..shortest)
        .map(|k| {
            let [theta, fused, lo, hi] =
                core::array::from_fn(|c| core::array::from_fn::<f64, 4, _>(|j| columns[j][c][k]));
            let sample = Eq3Sample {
                theta_hat_rad: theta.map(|x| x as f32),
                torque_nm: core::array::from_fn(|j| fused[j] * l[j]),
                bound_nm: core::array::from_fn(|j| [(lo[j] * l[j]) as f32, (hi[j] * l[j]) as f32]),
            };
            let tip = core::array::from_fn(|j| TipForce {
                point_n: fused[j] as f32,
                lo_n: lo[j] as f32,
                hi_n: hi[j] as f32,
            });
            (sample, tip)
        })
        .unzip();
    Ok(WristRun {
        samples,
        tip_n,
        reference_n: reference.map(|[a, b]| (0..shortest).map(|k| [a[k], b[k]]).collect()),
        setting: Eq3Setting {
            geometry,
            sign_speed_rad_s: sign_speeds_rad_s(&replayed),
            gravity_m_s2: holding.gravity_m_s2,
            timing: Eq3Timing {
                period_s: 1.0 / rate_hz,
                q_cutoff_rad_s: cutoff_rad_s,
                jaw_open_rad: holding.jaw_open_rad,
            },
        },
        gripper_length_m: l,
        rate_hz,
        notes,
    })
}

/// Where each joint's replay starts in the common run: the ticks to skip
/// at its start. With the host's clock in every log ([`HOST_CLOCK_COLUMN`],
/// `host-sim link` writes it) the four are aligned on it: each starts at
/// the latest first replayed tick, and they may have started apart.
/// Without it they are taken to have started together, which their
/// lengths can only check: lengths further apart than `lag_s` are
/// refused (module docs). Notes what it did; says whether the clock
/// aligned them.
fn align(
    logs: &[(String, Log); 4],
    replays: &[TickReplay],
    rate_hz: f64,
    lag_s: f64,
    notes: &mut Vec<String>,
) -> Result<([usize; 4], bool)> {
    let lengths: [usize; 4] = core::array::from_fn(|j| replays[j].log.len());
    // The host's clock at each replay's first tick (one of the log's own
    // rows: homing's rows are dropped before the replay).
    let clock: Vec<Option<f64>> = logs
        .iter()
        .zip(replays)
        .map(|((_, log), r)| {
            let row = r.source_row.first().copied().flatten()?;
            log.col(HOST_CLOCK_COLUMN)?
                .get(row)
                .copied()
                .filter(|t| t.is_finite())
        })
        .collect();
    if let [Some(a), Some(b), Some(c), Some(d)] = clock[..] {
        let starts = [a, b, c, d];
        let common = starts.iter().copied().fold(f64::MIN, f64::max);
        let skip: [usize; 4] =
            core::array::from_fn(|j| ((common - starts[j]) * rate_hz).round() as usize);
        let earliest = starts.iter().copied().fold(f64::MAX, f64::min);
        let each: Vec<String> = (0..4)
            .map(|j| format!("{} {:+.3} s", JOINT_NAMES[j], starts[j] - earliest))
            .collect();
        for j in 0..4 {
            ensure!(
                skip[j] < lengths[j],
                "{} ({}) ends {:.3} s before {} starts on the host's clock ({HOST_CLOCK_COLUMN}): \
                 the four logs do not overlap",
                JOINT_NAMES[j],
                logs[j].0,
                (common - starts[j]) - lengths[j] as f64 / rate_hz,
                JOINT_NAMES[(0..4).find(|&k| starts[k] == common).unwrap_or(0)]
            );
        }
        let common_len = (0..4).map(|j| lengths[j] - skip[j]).min().unwrap_or(0);
        notes.push(format!(
            "aligned on the host's clock ({HOST_CLOCK_COLUMN}): first replayed ticks at {}; \
             {common_len} ticks ({:.3} s) in common",
            each.join(", "),
            common_len as f64 / rate_hz
        ));
        return Ok((skip, true));
    }
    if clock.iter().any(Option::is_some) {
        notes.push(format!(
            "only {} of the four logs have the host's clock ({HOST_CLOCK_COLUMN}): aligned on \
             their first replayed ticks instead",
            clock.iter().filter(|c| c.is_some()).count()
        ));
    }
    let (shortest, longest) = (
        lengths.iter().copied().min().unwrap_or(0),
        lengths.iter().copied().max().unwrap_or(0),
    );
    let spread_s = (longest - shortest) as f64 / rate_hz;
    if spread_s > lag_s {
        let each: Vec<String> = (0..4)
            .map(|j| format!("{} {:.3} s", JOINT_NAMES[j], lengths[j] as f64 / rate_hz))
            .collect();
        bail!(
            "the four logs last {} after their first replayed rows: {spread_s:.3} s apart, more \
             than the force estimate's time constant ({lag_s:.3} s), and they have no common \
             clock ({HOST_CLOCK_COLUMN}, which `host-sim link --record` writes) to align them \
             on. They must be recorded together: start the four controllers' runs at once",
            each.join(", ")
        );
    }
    if longest > shortest {
        notes.push(format!(
            "the logs differ by {} ticks ({:.1} ms) in length: cut to the shortest",
            longest - shortest,
            spread_s * 1e3
        ));
    }
    Ok(([0; 4], false))
}

/// When each joint's commanded angle (`theta_ref_rad`, where the logs
/// have it) first leaves its first value, after its log's first replayed
/// tick: a program whose joints start moving together shows the four
/// logs' alignment. A note, with a warning when they are further apart
/// than `lag_s` (a program may start its joints apart on purpose); logs
/// aligned on the host's clock (`on_clock`) are aligned, so there the
/// warning is about the start, not the logs.
fn motion_starts(
    replays: &[TickReplay],
    skip: [usize; 4],
    rate_hz: f64,
    lag_s: f64,
    on_clock: bool,
) -> Option<String> {
    let starts: Vec<Option<f64>> = replays
        .iter()
        .zip(skip)
        .map(|(r, skip)| {
            let reference = &r.log.col("theta_ref_rad")?[skip..];
            let first = *reference.first()?;
            let k = reference
                .iter()
                .position(|x| x.is_finite() && *x != first)?;
            Some(k as f64 / rate_hz)
        })
        .collect();
    let known: Vec<f64> = starts.iter().flatten().copied().collect();
    if known.len() < 2 {
        return None;
    }
    let each: Vec<String> = (0..4)
        .map(|j| match starts[j] {
            Some(t) => format!("{} {t:.3} s", JOINT_NAMES[j]),
            None => format!("{} (no move)", JOINT_NAMES[j]),
        })
        .collect();
    let spread_s = known.iter().fold(f64::MIN, |m, x| m.max(*x))
        - known.iter().fold(f64::MAX, |m, x| m.min(*x));
    let warning = if spread_s > lag_s {
        let (clock, meaning) = if on_clock {
            (
                " on the host's clock",
                "the joints started apart (if they were meant to start together, start each \
                 board's `link` with one `--start-at`)",
            )
        } else {
            (
                "",
                "if the program starts the joints together, the logs are not aligned",
            )
        };
        format!(
            "; {spread_s:.3} s apart{clock}, more than the force estimate's time constant \
             ({lag_s:.3} s): {meaning}"
        )
    } else {
        String::new()
    };
    Some(format!(
        "each joint's commanded angle first moves at {}{warning}",
        each.join(", ")
    ))
}

/// Read a joint's log as [`replay`] needs it (`ReplayEnd::BeforeFault`:
/// a fault the firmware recorded ends the rows replayed, with a note on
/// stderr after `command: `).
pub fn read(path: &Path, ticks_per_row: Option<u32>, command: &str) -> Result<(String, Log)> {
    let log = crate::ingest::read_for_replay(path, ticks_per_row, command, ReplayEnd::BeforeFault)?;
    Ok((path.display().to_string(), log))
}

/// Columns of [`joint_logs`]: DESIGN.md's CSV columns the simulated wrist
/// measures, the board's estimates, and the truth (`theta_true_rad`; the
/// links' true torque on the joint over `l_e`, `f_links_true_n`).
pub const JOINT_LOG_COLUMNS: [&str; 14] = [
    "t_s",
    "x1_m",
    "x2_m",
    "phi_rad",
    "i_ref_a",
    "i_meas_a",
    "theta_ref_rad",
    "f_ext_n",
    "theta_hat_rad",
    "f_ext_fused_n",
    "f_ext_lo_n",
    "f_ext_hi_n",
    "fault_code",
    "theta_true_rad",
];

/// The simulated wrist's ticks as one project log per joint (the wrist's
/// order): what each joint's controller would record on a rig, plus the
/// truth. `f_ext_n` is the true contact force at the tip (the object's
/// on a jaw, zero on the roll and pitch).
pub fn joint_logs(params: &WristParams, ticks: &[WristTick]) -> Result<[Log; 4]> {
    let mut names: Vec<&str> = JOINT_LOG_COLUMNS.to_vec();
    names.push("f_links_true_n");
    let mut logs = Vec::with_capacity(4);
    for j in 0..4 {
        let mut log = Log::with_columns(&names)?;
        let l = f64::from(params.configs[j].machine.gripper_length_m);
        for t in ticks {
            let o = &t.outputs[j];
            let e = &o.est;
            let f = |v: f32| f64::from(v);
            let contact_n = if j >= JAW_A { t.contact_n } else { 0.0 };
            log.push_row(&[
                t.t_s,
                f(e.x1_m),
                f(e.x2_m),
                f(e.phi_rad),
                f(o.current_ref_a),
                f(e.i_meas_a),
                f(e.theta_ref_rad),
                contact_n,
                f(e.theta_hat_rad),
                f(e.f_ext_fused_n),
                f(e.f_ext_lo_n),
                f(e.f_ext_hi_n),
                f64::from(cable_joint::Fault::code_of(o.fault)),
                t.theta_rad[j],
                t.links_true_nm[j] / l,
            ])?;
        }
        logs.push(log);
    }
    logs.try_into()
        .map_err(|_| anyhow::anyhow!("four joints' logs"))
}

/// Stage [`joint_logs`] as `dir/roll.csv`, `dir/pitch.csv`,
/// `dir/jaw_a.csv`, `dir/jaw_b.csv` in `out` (written together when it
/// commits); the paths, in the wrist's order.
pub fn stage_joint_logs(
    out: &mut Outputs,
    dir: &Path,
    logs: &[Log; 4],
) -> Result<[std::path::PathBuf; 4]> {
    let paths = JOINT_NAMES.map(|n| dir.join(format!("{n}.csv")));
    for (log, path) in logs.iter().zip(&paths) {
        log.stage(out, path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(paths)
}
