//! Cable 0's stiffness `K_w0` (rope wheel to slider 1) from a calibration
//! run, for the cable-0 slack check's reach (`stretch.cable0_n_m`).
//!
//! The rope's elongation `e = phi r_m / z_i - x1` is measured (motor
//! encoder and grating 1), and the motor's torque balance reads its
//! tension. A plain slope of the DOB's reading (`tension1_hat_n`) against
//! `e` comes out 1.4 to 1.9 times the rope's on the simulator's plants:
//! the drive's own friction rides on the reading and turns with the motion
//! (README, "Cable 0's stiffness for the slack check"). So the slope is
//! taken only over stretches where slider 1 stands still and the motor
//! turns one way, each stretch with an offset of its own: there the
//! friction is one constant per stretch and `e` changes by the rope's
//! stretch alone.
//!
//! The DOB's reading is that balance through its low-pass `Q` (seed Eq.
//! 17, cut-off `dob.cutoff_rad_s`, 10 Hz by default), and the stretches
//! come right after the motor reverses, within about `1 / g` of it. There
//! `Q` still lags the rising tension (the slope reads low) and still
//! carries the drive's friction from its old sign to its new one (the
//! slope reads high): on the report's variants and draws 70-109 the two
//! left readings of 0.65 to 1.03 times the rope's, and 1.06 times on a
//! plant with cables twice as stiff. So the slope is taken on the reading
//! with `Q` undone from each log row to the next with the same pole the
//! core's filter has ([`unfiltered`]; over the row's ticks on a decimated
//! recording, the elongation through the same weights): the balance
//! itself, whose friction is one constant per stretch (0.94 to 1.04 times
//! the rope's on the same plants). Undoing `Q` lets the current's noise
//! and the ripple of the observer's differenced speed through; a moving
//! mean over [`MEAN_S`] on both sides averages it without biasing the
//! slope, and the standard error is written beside it.

use cable_joint::control::filter::LowPass1;
use serde::Serialize;

use super::replay::Prepared;

/// Slider 1 counts as standing still below this speed, m/s (20 grating
/// counts of 1 µm a second).
pub const STILL_X1_M_S: f64 = 2e-5;
/// The motor counts as turning one way above this speed, rad/s.
pub const TURNING_RAD_S: f64 = 0.3;
/// A stretch lasts at least this long, s.
pub const MIN_STRETCH_S: f64 = 0.01;
/// Both sides of the slope are averaged over this long inside each
/// stretch, s (half the shortest stretch): the same moving mean on the
/// elongation and on the reading keeps the slope exact and averages the
/// ripple the velocity observer leaves in the unfiltered reading.
pub const MEAN_S: f64 = 0.005;
/// Stretches and time the slope needs before it is written: on the
/// report's presliding plant a single stretch of 20 rows (10 ms at 2 kHz)
/// read 3.85 times the rope's stiffness.
pub const MIN_STRETCHES: usize = 5;
/// See [`MIN_STRETCHES`]: the stretches' total duration, s (200 rows at
/// 2 kHz, the floor's first form, which counted rows and so asked a 1 kHz
/// log for twice the time and a 4 kHz log for half).
pub const MIN_TOTAL_S: f64 = 0.1;

/// Cable 0's stiffness as the stretches give it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Cable0Stiffness {
    /// `K_w0`, N/m.
    pub n_m: f64,
    /// Stretches used.
    pub stretches: usize,
    /// Rows in them.
    pub rows: usize,
    /// Their total duration, s (each row counts for the mean row interval
    /// of its stretch).
    pub seconds: f64,
    /// The slope's standard error, N/m, from the scatter about it (one
    /// independent sample per 5 ms window, the moving mean's).
    pub std_error_n_m: f64,
}

/// Sums of the fixed-effects slope over the stretches closed so far.
#[derive(Default)]
struct Sums {
    num: f64,
    den: f64,
    /// Sum of the readings' squares about their stretch means.
    syy: f64,
    /// Independent samples in the moving means (one a window).
    independent: f64,
    stretches: usize,
    rows: usize,
    seconds: f64,
}

impl Sums {
    /// Take `stretch` (time, elongation, reading) if it lasts long enough,
    /// its moving means over [`MEAN_S`] about their own means, and empty
    /// it.
    fn close(&mut self, stretch: &mut Vec<(f64, f64, f64)>) {
        let lasts = matches!(
            (stretch.first(), stretch.last()),
            (Some(a), Some(b)) if b.0 - a.0 >= MIN_STRETCH_S
        );
        if lasts {
            let n = stretch.len() as f64;
            // `lasts` means two rows at least, `MIN_STRETCH_S` apart.
            let seconds = (stretch[stretch.len() - 1].0 - stretch[0].0) * n / (n - 1.0);
            // The window in rows (at least one), and the means over it
            // that lie wholly inside the stretch: none from another
            // stretch's friction.
            let width = ((MEAN_S * n / seconds).round() as usize).clamp(1, stretch.len() - 1);
            let means: Vec<(f64, f64)> = stretch
                .windows(width)
                .map(|w| {
                    let sum = w.iter().fold((0.0, 0.0), |a, s| (a.0 + s.1, a.1 + s.2));
                    (sum.0 / width as f64, sum.1 / width as f64)
                })
                .collect();
            let m = means.len() as f64;
            let me = means.iter().map(|s| s.0).sum::<f64>() / m;
            let mr = means.iter().map(|s| s.1).sum::<f64>() / m;
            for (e, r) in means.iter() {
                self.num += (e - me) * (r - mr);
                self.den += (e - me) * (e - me);
                self.syy += (r - mr) * (r - mr);
            }
            self.independent += m / width as f64;
            self.stretches += 1;
            self.rows += stretch.len();
            self.seconds += seconds;
        }
        stretch.clear();
    }

    /// The slope over the stretches closed, or why it is not cable 0's
    /// stiffness: too few stretches or too little time in them, or a slope
    /// below `cable1_n_m` (cable 0 is the rope's shortest stretch, so a
    /// slope below cable 1's stiffness is a slack rope or a reading without
    /// the rope's tension in it).
    fn stiffness(self, cable1_n_m: f64) -> Result<Cable0Stiffness, String> {
        let Sums {
            num,
            den,
            syy,
            independent,
            stretches,
            rows,
            seconds,
        } = self;
        if stretches < MIN_STRETCHES || seconds < MIN_TOTAL_S {
            return Err(format!(
                "{stretches} stretches ({rows} rows, {seconds:.3} s) where slider 1 stands still \
                 and the motor turns one way; {MIN_STRETCHES} stretches and {MIN_TOTAL_S} s are \
                 needed"
            ));
        }
        let n_m = num / den;
        if !(n_m.is_finite() && n_m >= cable1_n_m) {
            return Err(format!(
                "the slope over {stretches} stretches is {n_m:.0} N/m, below cable 1's \
                 {cable1_n_m:.0} N/m"
            ));
        }
        // One mean per stretch and the slope are fitted; the moving means
        // share their rows, so the scatter counts one sample a window.
        let scatter = (syy - n_m * num).max(0.0) / den;
        let dof = (independent - stretches as f64 - 1.0).max(1.0);
        let std_error_n_m = (scatter / dof).sqrt();
        Ok(Cable0Stiffness {
            n_m,
            stretches,
            rows,
            seconds,
            std_error_n_m,
        })
    }
}

/// Over the ticks `from + 1 ..= to` of a replay (a row a tick), the mean
/// input of the one-pole low-pass with pole `a` whose output is
/// `filtered`, and the mean of `signal` with the same weights. The
/// input's weight at tick `i` is proportional to `a^(to - i)`, and its
/// mean over the `n` ticks is `(y[to] - a^n y[from]) / (1 - a^n)`
/// ([`LowPass1::update`] solved for its input, `n` times over). One tick
/// (a log with every tick) gives the input itself and `signal[to]`; a
/// decimated log's row gives what the filtered reading can tell of the
/// ticks since the row before, whatever the replay filled them with.
pub fn unfiltered(
    filtered: &[f64],
    signal: &[f64],
    pole: f64,
    from: usize,
    to: usize,
) -> (f64, f64) {
    let (mut power, mut weights, mut sum) = (1.0, 0.0, 0.0);
    for i in (from + 1..=to).rev() {
        sum += power * signal[i];
        weights += power;
        power *= pole;
    }
    // `power` is now `a^n`.
    let input = (filtered[to] - power * filtered[from]) / (1.0 - power);
    (input, sum / weights)
}

/// `K_w0` from the logs, or why they do not give it.
pub fn read_cable0_stiffness(preps: &[Prepared]) -> Result<Cable0Stiffness, String> {
    let mut sums = Sums::default();
    for p in preps {
        let col = |c: &str| p.col(c).map_err(|e| format!("{e:#}"));
        let (phi, x1, x1_vel) = (col("phi_rad")?, col("x1_m")?, col("x1_vel_m_s")?);
        let (phi_vel, filtered) = (col("phi_vel_rad_s")?, col("tension1_hat_n")?);
        let cfg = p.config();
        let pole = f64::from(LowPass1::new(cfg.dob.cutoff_rad_s, cfg.period_s()).pole());
        let t = p.t_s().map_err(|e| format!("{e:#}"))?;
        // Rope per motor radian, as the core's cable-0 check has it: the
        // elongation at every tick of the replay.
        let m_per_rad = 1.0 / f64::from(cfg.machine.motor_rad_per_cable_m());
        let e: Vec<f64> = phi
            .iter()
            .zip(&x1)
            .map(|(p, x)| p * m_per_rad - x)
            .collect();
        let mut stretch = Vec::new();
        // The log row and the motor's direction of the last row taken.
        let mut last: Option<(usize, f64)> = None;
        // The replay's tick of the log's row before.
        let mut before: Option<usize> = None;
        for k in (0..p.len()).filter(|k| p.measured(*k)) {
            // The DOB's `Q` undone since the row before, and the
            // elongation through the same weights.
            let (reading, elongation) = before.map_or((f64::NAN, f64::NAN), |j| {
                unfiltered(&filtered, &e, pole, j, k)
            });
            before = Some(k);
            let sign = phi_vel[k].signum();
            let inside = p.usable[k]
                && x1_vel[k].abs() < STILL_X1_M_S
                && phi_vel[k].abs() > TURNING_RAD_S
                && [elongation, reading].iter().all(|v| v.is_finite());
            let follows = last.is_some_and(|(row, s)| p.log_row(k) == row + 1 && s == sign);
            if !(inside && follows) {
                sums.close(&mut stretch);
            }
            last = inside.then(|| (p.log_row(k), sign));
            if inside {
                stretch.push((t[k], elongation, reading));
            }
        }
        sums.close(&mut stretch);
    }
    let cable1_n_m = preps
        .first()
        .map_or(0.0, |p| f64::from(p.config().stretch.cable1_n_m));
    sums.stiffness(cable1_n_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `count` stretches of `rows` rows `1 / rate_hz` apart, the reading
    /// `k e` plus an offset of each stretch's own (its friction).
    fn sums(k_n_m: f64, rate_hz: f64, count: usize, rows: usize) -> Sums {
        let mut sums = Sums::default();
        let mut t = 0.0;
        for i in 0..count {
            let offset_n = 3.0 * i as f64 - 5.0;
            let mut stretch: Vec<(f64, f64, f64)> = (0..rows)
                .map(|j| {
                    let e = 1e-5 * (i + j) as f64;
                    (t + j as f64 / rate_hz, e, k_n_m * e + offset_n)
                })
                .collect();
            t += 1.0;
            sums.close(&mut stretch);
        }
        sums
    }

    /// The floor is a total time: 150 rows at 1 kHz (0.15 s) are read,
    /// the same 150 rows at 2 kHz (0.075 s) are not, whatever the rows;
    /// each stretch's own offset (its friction) leaves the slope alone.
    #[test]
    fn the_floor_is_the_stretches_total_time_not_their_rows() {
        let k = sums(1.6e5, 1000.0, 6, 25).stiffness(1.1e4).unwrap();
        assert!((k.n_m / 1.6e5 - 1.0).abs() < 1e-9, "{k:?}");
        assert_eq!((k.stretches, k.rows), (6, 150));
        assert!((k.seconds - 0.15).abs() < 1e-9, "{k:?}");
        let short = sums(1.6e5, 2000.0, 6, 25).stiffness(1.1e4).unwrap_err();
        assert!(
            short.contains("0.075 s") && short.contains("0.1 s"),
            "{short}"
        );
        let few = sums(1.6e5, 1000.0, MIN_STRETCHES - 1, 50).stiffness(1.1e4);
        assert!(few.unwrap_err().contains("stretches"));
        let soft = sums(5e3, 1000.0, 6, 25).stiffness(1.1e4).unwrap_err();
        assert!(soft.contains("below cable 1's"), "{soft}");
    }

    /// `unfiltered` gives back, to f32's rounding, the input the core's
    /// low-pass was fed: tick by tick, and over a gap of `n` ticks (a
    /// decimated log's rows) the input's mean with the weights `a^(to -
    /// i)`, the same mean as it gives of the signal beside.
    #[test]
    fn unfiltered_undoes_the_core_s_low_pass() {
        let lp = LowPass1::new(62.83, 1.0 / 1000.0);
        let a = f64::from(lp.pole());
        let input: Vec<f32> = (0..200).map(|k| (k as f32 * 0.37).sin() * 20.0).collect();
        let signal: Vec<f64> = input.iter().map(|u| f64::from(*u)).collect();
        let mut y = 0.0;
        let output: Vec<f64> = input
            .iter()
            .map(|u| f64::from(lp.update(&mut y, *u)))
            .collect();
        for k in 1..output.len() {
            let (u, s) = unfiltered(&output, &signal, a, k - 1, k);
            assert!(
                (signal[k] - u).abs() < 1e-3,
                "tick {k}: fed {}, got {u}",
                signal[k]
            );
            assert_eq!(s, signal[k]);
        }
        for n in [3, 10] {
            for to in (n..output.len()).step_by(n) {
                let (u, s) = unfiltered(&output, &signal, a, to - n, to);
                let w: Vec<f64> = (0..n).map(|j| a.powi(j as i32)).collect();
                let mean =
                    (0..n).map(|j| w[j] * signal[to - j]).sum::<f64>() / w.iter().sum::<f64>();
                assert!(
                    (mean - u).abs() < 1e-3,
                    "{n} ticks to {to}: mean {mean}, got {u}"
                );
                assert!(
                    (mean - s).abs() < 1e-9,
                    "{n} ticks to {to}: signal {mean}, got {s}"
                );
            }
        }
    }

    /// Stretches just after the motor reverses, as on a calibration run:
    /// the drive's friction `f` flips at the reversal and the rope then
    /// stretches faster and faster, so the DOB's reading `Q[K e + f sgn]`
    /// still lags the tension and still carries the friction's change.
    /// Its slope against `e` is off by more than 5 %; with `Q` undone
    /// and the ripple the observer leaves on top, the slope is the rope's.
    #[test]
    fn the_slope_is_taken_with_the_dob_s_low_pass_undone() {
        let (k_n_m, friction_n, rate_hz) = (2.0e5, 3.6, 1000.0);
        let lp = LowPass1::new(2.0 * std::f32::consts::PI * 10.0, 1.0 / rate_hz as f32);
        let (mut plain, mut undone) = (Sums::default(), Sums::default());
        let mut reading = 0.0;
        let mut e = 0.0;
        for i in 0..8 {
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            // 15 ticks between the reversal and the stretch, 20 in it.
            let (mut stretch_plain, mut stretch_undone) = (Vec::new(), Vec::new());
            let mut last = f64::from(reading);
            // `unfiltered`'s second signal is not used here.
            let ticks = [0.0, 0.0];
            for j in 0..35 {
                e += sign * 1e-7 * (1.0 + 0.15 * f64::from(j));
                let ripple_n = 0.2 * (f64::from(j) * 2.0 * std::f64::consts::PI * 0.1).sin();
                let tension_n = k_n_m * e + friction_n * sign;
                let r = f64::from(lp.update(&mut reading, tension_n as f32));
                let raw = unfiltered(&[last, r], &ticks, f64::from(lp.pole()), 0, 1).0 + ripple_n;
                last = r;
                if j >= 15 {
                    let t = f64::from(i * 35 + j) / rate_hz;
                    stretch_plain.push((t, e, r));
                    stretch_undone.push((t, e, raw));
                }
            }
            plain.close(&mut stretch_plain);
            undone.close(&mut stretch_undone);
        }
        let plain = plain.stiffness(1e4).unwrap();
        let undone = undone.stiffness(1e4).unwrap();
        assert!(
            (plain.n_m / k_n_m - 1.0).abs() > 0.05,
            "the filtered reading's slope {} N/m for {k_n_m}",
            plain.n_m
        );
        assert!(
            (undone.n_m / k_n_m - 1.0).abs() < 0.02,
            "with Q undone {} N/m for {k_n_m}",
            undone.n_m
        );
    }
}
