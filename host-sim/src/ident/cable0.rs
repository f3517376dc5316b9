//! Cable 0's stiffness `K_w0` (rope wheel to slider 1) from a calibration
//! run, for the cable-0 slack check's reach (`stretch.cable0_n_m`).
//!
//! The rope's elongation `e = phi r_m / z_i - x1` is measured (motor
//! encoder and grating 1), and the motor's torque balance reads its
//! tension (`tension1_hat_n`). A plain slope of the reading against `e`
//! comes out 1.4 to 1.9 times the rope's on the simulator's plants: the
//! drive's own friction rides on the reading and turns with the motion
//! (README, "Cable 0's stiffness for the slack check"). So the slope is
//! taken only over stretches where slider 1 stands still and the motor
//! turns one way, each stretch with an offset of its own: there the
//! friction is one constant per stretch and `e` changes by the rope's
//! stretch alone. Through a quantized `e` the slope reads low rather than
//! high, which is the side the check can take.

use serde::Serialize;

use super::replay::Prepared;

/// Slider 1 counts as standing still below this speed, m/s (20 grating
/// counts of 1 µm a second).
pub const STILL_X1_M_S: f64 = 2e-5;
/// The motor counts as turning one way above this speed, rad/s.
pub const TURNING_RAD_S: f64 = 0.3;
/// A stretch lasts at least this long, s.
pub const MIN_STRETCH_S: f64 = 0.01;
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
}

/// Sums of the fixed-effects slope over the stretches closed so far.
#[derive(Default)]
struct Sums {
    num: f64,
    den: f64,
    stretches: usize,
    rows: usize,
    seconds: f64,
}

impl Sums {
    /// Take `stretch` (time, elongation, reading) if it lasts long enough,
    /// about its own means, and empty it.
    fn close(&mut self, stretch: &mut Vec<(f64, f64, f64)>) {
        let lasts = matches!(
            (stretch.first(), stretch.last()),
            (Some(a), Some(b)) if b.0 - a.0 >= MIN_STRETCH_S
        );
        if lasts {
            let n = stretch.len() as f64;
            let me = stretch.iter().map(|s| s.1).sum::<f64>() / n;
            let mr = stretch.iter().map(|s| s.2).sum::<f64>() / n;
            for (_, e, r) in stretch.iter() {
                self.num += (e - me) * (r - mr);
                self.den += (e - me) * (e - me);
            }
            self.stretches += 1;
            self.rows += stretch.len();
            // `lasts` means two rows at least, `MIN_STRETCH_S` apart.
            self.seconds += (stretch[stretch.len() - 1].0 - stretch[0].0) * n / (n - 1.0);
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
        Ok(Cable0Stiffness {
            n_m,
            stretches,
            rows,
            seconds,
        })
    }
}

/// `K_w0` from the logs, or why they do not give it.
pub fn read_cable0_stiffness(preps: &[Prepared]) -> Result<Cable0Stiffness, String> {
    let mut sums = Sums::default();
    for p in preps {
        let col = |c: &str| p.col(c).map_err(|e| format!("{e:#}"));
        let (phi, x1, x1_vel) = (col("phi_rad")?, col("x1_m")?, col("x1_vel_m_s")?);
        let (phi_vel, reading) = (col("phi_vel_rad_s")?, col("tension1_hat_n")?);
        let t = p.t_s().map_err(|e| format!("{e:#}"))?;
        // Rope per motor radian, as the core's cable-0 check has it.
        let m_per_rad = 1.0 / f64::from(p.config().machine.motor_rad_per_cable_m());
        let mut stretch = Vec::new();
        // The log row and the motor's direction of the last row taken.
        let mut last: Option<(usize, f64)> = None;
        for k in (0..p.len()).filter(|k| p.measured(*k)) {
            let sign = phi_vel[k].signum();
            let inside = p.usable[k]
                && x1_vel[k].abs() < STILL_X1_M_S
                && phi_vel[k].abs() > TURNING_RAD_S
                && [phi[k], x1[k], reading[k]].iter().all(|v| v.is_finite());
            let follows = last.is_some_and(|(row, s)| p.log_row(k) == row + 1 && s == sign);
            if !(inside && follows) {
                sums.close(&mut stretch);
            }
            last = inside.then(|| (p.log_row(k), sign));
            if inside {
                stretch.push((t[k], phi[k] * m_per_rad - x1[k], reading[k]));
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
}
