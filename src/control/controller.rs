//! The one control step: raw sample in, current command and estimates out.
//!
//! [`Controller::step`] is the whole control path. The firmware's control task
//! and the simulator are its only two callers. It never allocates, never
//! panics, and reports faults as values: on a fault the drive is disabled in
//! the same tick, the fault is latched, and only [`Controller::clear_fault`]
//! re-arms it.
//!
//! Stages (each can be timed by a [`StageTimer`], e.g. TIM2 under QEMU or
//! DWT on hardware): sensing (counter extension, jump checks, scaling,
//! differentiators), JAE, cascade, DOB.

use crate::cascade::{self, CascadeIn, CascadeState};
use crate::config::{Config, ConfigError};
use crate::dob::{self, Dob, DobOut, DobState, TensionState};
use crate::fault::{Fault, Sensor};
use crate::filter::{Kinematics, LowPass1, TrackingObserver};
use crate::fusion::{self, Fusion, FusionIn, FusionState};
use crate::grip::{self, Grip, GripIn, GripPartner, GripState};
use crate::jae::{self, JaeState};
use crate::math;
use crate::model::{sig, AddedState, Signals};
use crate::probe::{Averaged, Probe, ProbeState};
use crate::trajectory::{Reference, Trajectory};
use crate::units::{AdcCode, DacCode, Extender16, GratingCount, MagneticCount, MotorCount};

/// One raw sample, as the board reads it at the tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RawSample {
    /// Grating 1 (slider 1), 32-bit timer.
    pub grating1: GratingCount,
    /// Grating 2 (slider 2), 32-bit timer.
    pub grating2: GratingCount,
    /// Motor encoder, 16-bit timer (wraps).
    pub motor: MotorCount,
    /// Magnetic joint encoder, 16-bit timer (wraps; calibration only).
    pub magnetic: MagneticCount,
    /// Current monitor, 12-bit ADC.
    pub current: AdcCode,
}

/// Operating mode.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Mode {
    /// Drive disabled, estimators running.
    #[default]
    Idle,
    /// Motor in closed loop on the motor encoder, joint in open loop (seed
    /// Fig. 8 and Fig. 10: the motor-implied angle is the feedback).
    MotorPosition,
    /// Joint in closed loop on the estimated angle (seed Fig. 11).
    JointClosedLoop,
}

impl Mode {
    /// Stable numeric code for telemetry.
    pub const fn code(self) -> u8 {
        match self {
            Mode::Idle => 0,
            Mode::MotorPosition => 1,
            Mode::JointClosedLoop => 2,
        }
    }

    /// Decode a telemetry code.
    pub const fn from_code(code: u8) -> Option<Mode> {
        match code {
            0 => Some(Mode::Idle),
            1 => Some(Mode::MotorPosition),
            2 => Some(Mode::JointClosedLoop),
            _ => None,
        }
    }
}

/// What to do: a mode and the joint-angle trajectory it follows.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Command {
    /// Mode.
    pub mode: Mode,
    /// Joint-angle reference (ignored in [`Mode::Idle`]).
    pub trajectory: Trajectory,
}

impl Default for Command {
    fn default() -> Self {
        Self {
            mode: Mode::Idle,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        }
    }
}

/// Everything the step estimates, SI units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimates {
    /// Time since the controller started, s.
    pub t_s: f32,
    /// Joint-angle reference, rad.
    pub theta_ref_rad: f32,
    /// Estimated joint angle (JAE), rad.
    pub theta_hat_rad: f32,
    /// Joint angle implied by the motor through rigid cables, rad.
    pub theta_motor_rad: f32,
    /// Magnetic encoder (calibration ground truth when fitted), rad.
    pub theta_mag_rad: f32,
    /// Slider 1, m.
    pub x1_m: f32,
    /// Slider 2, m.
    pub x2_m: f32,
    /// Slider 1 speed, m/s.
    pub x1_vel_m_s: f32,
    /// Slider 1 acceleration, m/s².
    pub x1_acc_m_s2: f32,
    /// Slider 2 speed, m/s.
    pub x2_vel_m_s: f32,
    /// Slider 2 acceleration, m/s².
    pub x2_acc_m_s2: f32,
    /// Motor shaft angle, rad.
    pub phi_rad: f32,
    /// Motor speed, rad/s.
    pub phi_vel_rad_s: f32,
    /// Motor acceleration, rad/s².
    pub phi_acc_rad_s2: f32,
    /// Measured drive current, A.
    pub i_meas_a: f32,
    /// Motor-velocity reference of the cascade, rad/s.
    pub motor_vel_ref_rad_s: f32,
    /// DOB load torque at the motor, N·m.
    pub load_torque_nm: f32,
    /// Cable-1 tension from the DOB, N.
    pub tension1_n: f32,
    /// Modelled no-load cable-1 tension (filtered like the DOB), N.
    pub tension1_model_n: f32,
    /// Estimated external tip force (DOB, seed Fig. 6), N.
    pub f_ext_hat_n: f32,
    /// Estimated external tip force from the cables' stretch, through the
    /// same low-pass as the DOB, N.
    pub f_ext_stretch_n: f32,
    /// Fused tip-force estimate (DOB and stretch intervals intersected,
    /// [`crate::fusion`]), N.
    pub f_ext_fused_n: f32,
    /// Lower end of the fused estimate's bound, N: every tip force the
    /// measurements and the friction bands allow lies in `[lo, hi]`.
    pub f_ext_lo_n: f32,
    /// Upper end of the fused estimate's bound, N.
    pub f_ext_hi_n: f32,
    /// [`crate::fusion::flags`] bits: which elements stick, whether the
    /// estimates disagree.
    pub fusion_flags: u8,
    /// Cable-1 tension from its stretch, `K_w1 (x1 - r theta_hat) + F_0`, N
    /// (the slack check's input).
    pub tension1_stretch_n: f32,
}

/// Result of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Output {
    /// Current reference for the drive, A (0 when disabled).
    pub current_ref_a: f32,
    /// The same as a DAC code (the board writes this).
    pub dac: DacCode,
    /// Drive enable line.
    pub drive_enable: bool,
    /// Latched fault, if any.
    pub fault: Option<Fault>,
    /// Mode in force.
    pub mode: Mode,
    /// Estimates.
    pub est: Estimates,
}

/// The stages of a step, for timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Step entered.
    Start,
    /// Counters extended, checked, scaled and differentiated.
    Sensing,
    /// Joint angle estimated.
    Jae,
    /// Tension model and DOB updated.
    Dob,
    /// Reference and cascade computed, output ready.
    Cascade,
}

/// Receives a mark at the end of each stage (a cycle counter on the target).
pub trait StageTimer {
    /// Called when `stage` ends.
    fn mark(&mut self, stage: Stage);
}

/// A timer that records nothing.
pub struct NoTimer;

impl StageTimer for NoTimer {
    #[inline(always)]
    fn mark(&mut self, _stage: Stage) {}
}

/// Zeroing offsets taken at the origin (homing).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Origin {
    grating1: i32,
    grating2: i32,
    motor: i32,
    magnetic: i32,
}

/// Precomputed constants derived from the configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Derived {
    period_s: f32,
    grating_obs: TrackingObserver,
    motor_obs: TrackingObserver,
    dob: Dob,
    fusion: Fusion,
    probe: Probe,
    grip: Grip,
    blend: Option<LowPass1>,
    force_lp: LowPass1,
    motor_per_joint: f32,
    max_grating_step: i32,
    max_motor_step: i32,
    max_magnetic_step: i32,
    /// Per-tick weight of the I²t low-pass, `T / tau_thermal`.
    i2t_weight: f32,
    /// Per-tick weight of the current-error low-pass, `T / tau_error`.
    current_error_weight: f32,
    /// Cable 1's compliance `1 / K_w1`, m/N, which bounds cable 0's (see
    /// the cable-0 checks in [`Controller::step_timed`]).
    cable1_m_per_n: f32,
    /// Rope the rope wheel winds per motor radian, `r_m / z_i`, m/rad.
    rope_m_per_motor_rad: f32,
    /// Check 1's payout limit, `limit / K_w1`, m.
    cable0_payout_m: f32,
    /// The payout stop's threshold, half the rope's shortening from the
    /// limit to zero tension, `limit / (2 max(K_w0, K_w1))`, m.
    cable0_stop_m: f32,
    /// Cable 0's compliance for check 2's reach, `1 / max(K_w0, K_w1)`,
    /// m/N: the identified `K_w0` where there is one, else cable 1's bound.
    cable0_m_per_n: f32,
}

impl Derived {
    fn new(c: &Config) -> Self {
        let period_s = c.period_s();
        let d = &c.differentiators;
        let m = &c.machine;
        let mut derived = Self {
            period_s,
            grating_obs: TrackingObserver::new(d.grating_bandwidth_hz, period_s),
            motor_obs: TrackingObserver::new(d.motor_bandwidth_hz, period_s),
            dob: Dob::new(&c.dob, m, period_s),
            fusion: Fusion::new(c, period_s),
            probe: Probe::new(&c.probe, period_s, c.scales.grating_m_per_count),
            grip: Grip::new(c.dob.cutoff_rad_s, period_s),
            force_lp: LowPass1::new(c.dob.cutoff_rad_s, period_s),
            blend: (c.cascade.jae_blend_hz > 0.0)
                .then(|| LowPass1::new(2.0 * math::PI * c.cascade.jae_blend_hz, period_s)),
            motor_per_joint: m.gear_ratio * m.pulley_radius_m / m.rope_wheel_radius_m,
            max_grating_step: 0,
            max_motor_step: 0,
            max_magnetic_step: 0,
            i2t_weight: 0.0,
            current_error_weight: 0.0,
            cable1_m_per_n: 0.0,
            rope_m_per_motor_rad: 1.0 / m.motor_rad_per_cable_m(),
            cable0_payout_m: 0.0,
            cable0_stop_m: 0.0,
            cable0_m_per_n: 0.0,
        };
        derived.set_steps(c);
        derived
    }

    /// The constants the fault checks use, from the fault limits (cheap: no
    /// filter redesign): the largest possible counter step per tick plus two
    /// counts of jitter, and the per-tick weights of the I²t and
    /// current-error low-passes.
    fn set_steps(&mut self, c: &Config) {
        let (s, period_s) = (&c.scales, self.period_s);
        let grating = c.limits.max_grating_speed_m_s * period_s / s.grating_m_per_count;
        let motor = c.limits.max_motor_speed_rad_s * period_s * s.motor_counts_per_rev as f32
            / (2.0 * math::PI);
        let joint_rad_s =
            c.limits.max_motor_speed_rad_s / self.motor_per_joint.max(f32::MIN_POSITIVE);
        let magnetic =
            4.0 * joint_rad_s * period_s * s.magnetic_counts_per_rev as f32 / (2.0 * math::PI);
        // `validate` bounds the speeds and scales, so these fit an `i32`
        // with room; saturate anyway (a wrapped limit would disable the check).
        self.max_grating_step = (grating as i32).saturating_add(2);
        self.max_motor_step = (motor as i32).saturating_add(2);
        self.max_magnetic_step = (magnetic as i32).saturating_add(2);
        let l = &c.limits;
        self.i2t_weight = (period_s / l.thermal_time_constant_s).min(1.0);
        self.current_error_weight = (period_s / l.current_error_time_s).min(1.0);
        self.cable1_m_per_n = 1.0 / c.stretch.cable1_n_m;
        self.cable0_payout_m = c.slack_limit_n() * self.cable1_m_per_n;
        self.cable0_m_per_n = 1.0 / c.stretch.cable0_n_m.max(c.stretch.cable1_n_m);
        self.cable0_stop_m = 0.5 * c.slack_limit_n() * self.cable0_m_per_n;
    }
}

/// A configuration validated and with its filters designed (observer gains,
/// DOB and fusion constants, in soft `f64` on the MCU: tens of thousands of
/// instructions). Build it where time does not matter (the firmware's
/// priority-1 command task); [`Controller::install`] then costs one copy, so
/// a new configuration never stretches a control tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedConfig {
    config: Config,
    derived: Derived,
}

impl PreparedConfig {
    /// Validate `config` and design everything derived from it.
    pub fn new(config: Config) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            derived: Derived::new(&config),
            config,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Replace only the fault limits (cheap: rescales the jump thresholds and
    /// the fault low-passes, no filter redesign).
    pub fn set_limits(&mut self, limits: crate::config::FaultLimits) -> Result<(), ConfigError> {
        limits.validate()?;
        self.config.limits = limits;
        self.derived.set_steps(&self.config);
        Ok(())
    }
}

/// All mutable state of the control path (snapshot-able by the simulator).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct State {
    motor_ext: Extender16,
    magnetic_ext: Extender16,
    last_grating: Option<(i32, i32)>,
    origin: Origin,
    x1: Kinematics,
    x2: Kinematics,
    phi: Kinematics,
    jae: JaeState,
    tension: TensionState,
    jae_terms: AddedState,
    tension_terms: AddedState,
    dob: DobState,
    fusion: FusionState,
    /// Dither phase and its synchronous mean ([`crate::probe`]).
    probe: ProbeState,
    /// The last tick dithered (the probe state is reset when a hold ends).
    probing: bool,
    /// The grip law's state ([`crate::grip`]), restarted by every command.
    grip: GripState,
    /// The other jaw of a gripping pair, as of its last tick.
    grip_partner: Option<GripPartner>,
    /// `Q[F_1']`'s Coulomb part (model C's sign terms), N.
    tension_friction_n: f32,
    cascade: CascadeState,
    /// Low-passed stretch force estimate, N.
    stretch_force_n: f32,
    /// Low-passed cable stretch `theta_hat - theta_motor` (feedback blend), rad.
    stretch_rad: f32,
    last_current_a: f32,
    /// The drive was enabled by the last step (the current checks apply).
    drive_was_enabled: bool,
    /// I²t state: the measured current squared, low-passed with the
    /// winding's thermal time constant, A².
    i2t_a2: f32,
    /// Low-passed current-tracking error, A.
    current_error_a: f32,
    /// Cable 0's elongation `phi r_m / z_i - x1` on the last tick the
    /// motor's torque balance read its tension at or above the slack
    /// limit, m.
    cable0_taut_m: f32,
    /// While probing: the period mean of cable 0's elongation at the last
    /// block whose mean reading of the motor was at or above the slack
    /// limit, m (`None` until one is, and when not probing).
    cable0_mean_taut_m: Option<f32>,
    /// A lower bound on cable 0's elongation at zero tension, m: the
    /// highest `elongation - reach` seen since the check was armed.
    cable0_floor_m: f32,
    tick: u32,
    command_tick: u32,
    /// The trajectory's reference angle on the last tick (before a probing
    /// dither), rad: where a new command's transfer starts.
    last_ref_rad: f32,
    /// Its rate on the last tick, rad/s.
    last_ref_vel_rad_s: f32,
    /// The transfer of the command in force: the reference step its
    /// trajectory would have made at its start (old reference minus the
    /// new trajectory's start), added back and faded out by a
    /// minimum-jerk move over `transfer_s` ([`Controller::set_command`]).
    transfer_rad: f32,
    /// Duration of that transfer, s (0: none).
    transfer_s: f32,
    primed: bool,
    fault: Option<Fault>,
}

/// The controller: configuration, derived constants, command and state.
#[derive(Clone, Debug, PartialEq)]
pub struct Controller {
    prepared: PreparedConfig,
    command: Command,
    state: State,
}

impl Controller {
    /// Validate the configuration and build a controller in [`Mode::Idle`].
    pub fn new(config: Config) -> Result<Self, ConfigError> {
        Ok(Self {
            prepared: PreparedConfig::new(config)?,
            command: Command::default(),
            state: State::default(),
        })
    }

    /// The DOB's and the cable stretch's intervals of the last step, before
    /// the fusion intersected them ([`crate::fusion::Sources`]).
    pub fn fusion_sources(&self) -> fusion::Sources {
        self.state.fusion.sources
    }

    /// The configuration in force.
    pub fn config(&self) -> &Config {
        &self.prepared.config
    }

    /// The command in force.
    pub fn command(&self) -> Command {
        self.command
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.state.fault
    }

    /// Control period, s.
    pub fn period_s(&self) -> f32 {
        self.prepared.derived.period_s
    }

    /// Replace the configuration (e.g. new identified parameters). Filters
    /// keep their state; the cascade integrator is kept (bumpless). Designs
    /// the filters here: on the control path use [`PreparedConfig`] and
    /// [`Controller::install`].
    pub fn set_config(&mut self, config: Config) -> Result<(), ConfigError> {
        self.install(PreparedConfig::new(config)?);
        Ok(())
    }

    /// Put a prepared configuration in force (one copy; no validation or
    /// filter design left to do). Filters keep their state; the cascade
    /// integrator is kept (bumpless).
    pub fn install(&mut self, prepared: PreparedConfig) {
        // Term states the new banks no longer use go back to rest
        // (`set_origin` restarts only the active ones).
        let (old, new) = (&self.prepared.config, &prepared.config);
        old.jae
            .added
            .retire(&new.jae.added, &mut self.state.jae_terms);
        old.tension
            .added
            .retire(&new.tension.added, &mut self.state.tension_terms);
        self.prepared = prepared;
    }

    /// Replace only the fault limits: cheap enough to call inside the control
    /// tick (no filter redesign, unlike [`Controller::set_config`]).
    pub fn set_limits(&mut self, limits: crate::config::FaultLimits) -> Result<(), ConfigError> {
        // Written in place: the sequencer calls this on a control tick,
        // where a copy of the whole configuration would cost hundreds of
        // instructions.
        self.prepared.set_limits(limits)
    }

    /// Start a new command; its trajectory time starts now. Leaving
    /// [`Mode::Idle`] starts the velocity integrator from zero.
    ///
    /// A command whose trajectory starts away from the reference in force
    /// (a command sent late over a link that lost a frame, an operator's
    /// hold far from where the joint is) does not step the reference: the
    /// step is added back and faded out by a minimum-jerk transfer, its
    /// peak speed a quarter of the motor-velocity limit's joint speed, so
    /// the cascade is not slammed into the current limit. A step no larger
    /// than one tick of the old reference's motion and one of the
    /// transfer's is taken as it is (a planned command applied a tick late
    /// on a moving reference); a grip and [`Mode::Idle`] have no transfer.
    pub fn set_command(&mut self, command: Command) {
        if command.mode != self.command.mode {
            self.state.cascade = CascadeState::default();
        } else {
            self.state.cascade.primed = false;
        }
        let cfg = &self.prepared.config;
        let step_rad = self.state.last_ref_rad - command.trajectory.at(0.0).angle_rad;
        let joint_speed_rad_s = cfg
            .machine
            .joint_rad_from_motor_rad(0.25 * cfg.cascade.vel_limit_rad_s);
        let transfer = command.mode != Mode::Idle
            && !command.trajectory.is_grip()
            && self.state.primed
            && step_rad.is_finite()
            && step_rad.abs()
                > (self.state.last_ref_vel_rad_s.abs() + joint_speed_rad_s)
                    * self.prepared.derived.period_s;
        (self.state.transfer_rad, self.state.transfer_s) = if transfer && joint_speed_rad_s > 0.0 {
            // A minimum-jerk move of `d` in `T` peaks at 1.875 d / T.
            (step_rad, 1.875 * step_rad.abs() / joint_speed_rad_s)
        } else {
            (0.0, 0.0)
        };
        self.command = command;
        self.state.command_tick = self.state.tick;
        self.state.grip.started = false;
    }

    /// Tell a gripping jaw about its partner (the other jaw on the same
    /// object), as of the partner's last tick; `None` for a single jaw.
    /// [`crate::joints::Joints::set_pair`] does this every tick.
    pub fn set_grip_partner(&mut self, partner: Option<GripPartner>) {
        self.state.grip_partner = partner;
    }

    /// The partner a gripping jaw last heard of, if any.
    pub fn grip_partner(&self) -> Option<GripPartner> {
        self.state.grip_partner
    }

    /// Latch an external fault (drive fault line, overrun, origin switch).
    /// The next step outputs zero current with the drive disabled.
    pub fn report_fault(&mut self, fault: Fault) {
        if self.state.fault.is_none() {
            self.state.fault = Some(fault);
        }
    }

    /// Does the cause of a fault persist in the controller's own state? The
    /// winding's I²t state above (90 % of the continuous current)²: after an
    /// I²t fault it must cool first (2.5 s with no current at the default
    /// 12 s time constant). The board adds its own causes (the drive's
    /// fault line).
    pub fn fault_cause_persists(&self) -> bool {
        let ic = 0.9 * self.prepared.config.limits.continuous_current_a;
        self.state.i2t_a2 > ic * ic
    }

    /// Stop the drive because something outside this joint demands it (a
    /// fault on another joint of the same instrument): fall back to
    /// [`Mode::Idle`] for the ticks to come, and rewrite `out`, this tick's
    /// output, as a disabled drive (zero current, the zero DAC code), so
    /// the stop takes effect within the tick. The estimates in `out` stay.
    pub fn stop(&mut self, out: &mut Output) {
        self.set_command(Command::default());
        self.state.cascade = CascadeState::default();
        self.state.last_current_a = 0.0;
        self.state.drive_was_enabled = false;
        out.current_ref_a = 0.0;
        out.dac = self.prepared.config.scales.dac_code(0.0);
        out.drive_enable = false;
        out.mode = Mode::Idle;
    }

    /// Clear a latched fault and fall back to [`Mode::Idle`]; the operator
    /// must command a mode again. Callers check
    /// [`Controller::fault_cause_persists`] first.
    pub fn clear_fault(&mut self) {
        self.state.fault = None;
        self.set_command(Command::default());
    }

    /// Homing: take `raw` as the origin of every counter. Estimators restart
    /// from rest at zero.
    pub fn set_origin(&mut self, raw: &RawSample) {
        // Reset in place, field by field: this runs on a control tick
        // (homing), and `self.state = State::default()` built a 600-byte
        // temporary and copied it (about 1700 instructions under QEMU, the
        // tick's worst). The pattern names every field, so a field added to
        // `State` does not compile until it is reset here or kept.
        let State {
            motor_ext,
            magnetic_ext,
            last_grating,
            origin,
            x1,
            x2,
            phi,
            jae,
            tension,
            jae_terms,
            tension_terms,
            dob,
            fusion,
            probe,
            probing,
            grip,
            grip_partner,
            tension_friction_n,
            cascade,
            stretch_force_n,
            stretch_rad,
            last_current_a,
            drive_was_enabled,
            // The winding does not cool down because the counters were zeroed.
            i2t_a2: _,
            current_error_a,
            cable0_taut_m,
            cable0_mean_taut_m,
            cable0_floor_m,
            tick,
            command_tick,
            last_ref_rad,
            last_ref_vel_rad_s,
            transfer_rad,
            transfer_s,
            primed,
            // A latched fault stays latched.
            fault: _,
        } = &mut self.state;
        let cfg = &self.prepared.config;
        *motor_ext = Extender16::default();
        *magnetic_ext = Extender16::default();
        let (motor, _) = motor_ext.update(raw.motor.0);
        let (magnetic, _) = magnetic_ext.update(raw.magnetic.0);
        *last_grating = None;
        *origin = Origin {
            grating1: raw.grating1.0,
            grating2: raw.grating2.0,
            motor,
            magnetic,
        };
        for k in [x1, x2, phi] {
            *k = Kinematics::default();
        }
        *jae = JaeState::default();
        *tension = TensionState::default();
        // Only the active terms' slots: the others are at rest (`install`
        // retires what a replaced bank used), and rewriting all of them
        // cost the homing tick, the worst, about a hundred instructions.
        cfg.jae.added.restart(jae_terms);
        cfg.tension.added.restart(tension_terms);
        *dob = DobState::default();
        *fusion = FusionState::default();
        probe.restart();
        *probing = false;
        grip.started = false;
        *grip_partner = None;
        *tension_friction_n = 0.0;
        *cascade = CascadeState::default();
        *stretch_force_n = 0.0;
        *stretch_rad = 0.0;
        *last_current_a = 0.0;
        *drive_was_enabled = false;
        *current_error_a = 0.0;
        *cable0_taut_m = 0.0;
        *cable0_mean_taut_m = None;
        *cable0_floor_m = 0.0;
        *command_tick = *tick;
        *last_ref_rad = 0.0;
        *last_ref_vel_rad_s = 0.0;
        *transfer_rad = 0.0;
        *transfer_s = 0.0;
        *primed = false;
    }

    /// Trajectory time of the command in force, s.
    fn command_time_s(&self) -> f32 {
        self.state.tick.wrapping_sub(self.state.command_tick) as f32
            * self.prepared.derived.period_s
    }

    /// One control tick (see [`Controller::step_timed`]).
    #[inline]
    pub fn step(&mut self, raw: &RawSample) -> Output {
        self.step_timed(raw, &mut NoTimer)
    }

    /// One control tick with stage marks for timing.
    ///
    /// Long (about 290 lines) on purpose: the whole control path in the
    /// order it runs (sensing, JAE, tension model and DOB, fusion and slack
    /// check, reference and cascade, output), each stage closed by its
    /// timer mark, so the stages read in order and their instruction counts
    /// under QEMU map to one place each. The stages' arithmetic lives in
    /// their modules (`jae`, `dob`, `fusion`, `probe`, `cascade`).
    pub fn step_timed(&mut self, raw: &RawSample, timer: &mut impl StageTimer) -> Output {
        timer.mark(Stage::Start);
        let cfg = &self.prepared.config;
        let d = &self.prepared.derived;
        let st = &mut self.state;
        let mut fault = None;

        // --- Sensing ---------------------------------------------------------
        let (motor_c, motor_step) = st.motor_ext.update(raw.motor.0);
        let (mag_c, mag_step) = st.magnetic_ext.update(raw.magnetic.0);
        if let Some((g1, g2)) = st.last_grating {
            if raw.grating1.0.wrapping_sub(g1).unsigned_abs() > d.max_grating_step as u32 {
                fault = Some(Fault::EncoderJump(Sensor::Grating1));
            } else if raw.grating2.0.wrapping_sub(g2).unsigned_abs() > d.max_grating_step as u32 {
                fault = Some(Fault::EncoderJump(Sensor::Grating2));
            }
        }
        if motor_step.unsigned_abs() > d.max_motor_step as u32 {
            fault = fault.or(Some(Fault::EncoderJump(Sensor::Motor)));
        }
        if mag_step.unsigned_abs() > d.max_magnetic_step as u32 {
            fault = fault.or(Some(Fault::EncoderJump(Sensor::Magnetic)));
        }
        st.last_grating = Some((raw.grating1.0, raw.grating2.0));
        if cfg.scales.adc_at_rail(raw.current) {
            fault = fault.or(Some(Fault::AdcRail));
        }
        let s = &cfg.scales;
        let x1_m = s.grating_m(GratingCount(
            raw.grating1.0.wrapping_sub(st.origin.grating1),
        ));
        let x2_m = s.grating_m(GratingCount(
            raw.grating2.0.wrapping_sub(st.origin.grating2),
        ));
        let phi_rad = s.motor_rad(motor_c.wrapping_sub(st.origin.motor));
        let theta_mag_rad = s.magnetic_rad(mag_c.wrapping_sub(st.origin.magnetic));
        let i_meas_a = s.adc_a(raw.current);
        if !st.primed {
            d.grating_obs.reset(&mut st.x1, x1_m);
            d.grating_obs.reset(&mut st.x2, x2_m);
            d.motor_obs.reset(&mut st.phi, phi_rad);
        }
        let x1 = d.grating_obs.update(&mut st.x1, x1_m);
        let x2 = d.grating_obs.update(&mut st.x2, x2_m);
        let phi = d.motor_obs.update(&mut st.phi, phi_rad);
        if math::abs(phi.vel) > cfg.limits.max_motor_speed_rad_s {
            fault = fault.or(Some(Fault::Overspeed));
        }
        // Current protection: only while this controller drives the motor
        // (a replayed log or a disabled drive is not ours to judge). The
        // I²t state integrates always, as the winding does.
        let l = &cfg.limits;
        st.i2t_a2 += d.i2t_weight * (i_meas_a * i_meas_a - st.i2t_a2);
        if st.drive_was_enabled {
            if math::abs(i_meas_a) > l.max_current_a {
                fault = fault.or(Some(Fault::OverCurrent));
            }
            if st.i2t_a2 > l.continuous_current_a * l.continuous_current_a {
                fault = fault.or(Some(Fault::I2t));
            }
            let error_a = math::abs(i_meas_a - st.last_current_a);
            st.current_error_a += d.current_error_weight * (error_a - st.current_error_a);
            if l.max_current_error_a > 0.0 && st.current_error_a > l.max_current_error_a {
                fault = fault.or(Some(Fault::CurrentTracking));
            }
        } else {
            st.current_error_a = 0.0;
        }
        timer.mark(Stage::Sensing);

        let theta_motor_rad = cfg.machine.joint_rad_from_motor_rad(phi_rad);
        let mut signals: Signals = [0.0; sig::COUNT];
        signals[sig::X1_M as usize] = x1_m;
        signals[sig::X1_VEL_M_S as usize] = x1.vel;
        signals[sig::X2_M as usize] = x2_m;
        signals[sig::X2_VEL_M_S as usize] = x2.vel;
        signals[sig::X2_ACC_M_S2 as usize] = x2.acc;
        signals[sig::PHI_RAD as usize] = phi_rad;
        signals[sig::PHI_VEL_RAD_S as usize] = phi.vel;
        signals[sig::I_REF_A as usize] = st.last_current_a;
        signals[sig::I_MEAS_A as usize] = i_meas_a;
        signals[sig::THETA_MOTOR_RAD as usize] = theta_motor_rad;

        // --- JAE -------------------------------------------------------------
        let mut theta_hat_rad = jae::estimate(&cfg.jae, &mut st.jae, x2_m, &x2);
        if cfg.jae.added.len > 0 {
            theta_hat_rad += cfg.jae.added.eval(&mut st.jae_terms, &signals, d.period_s);
        }
        if math::abs(theta_hat_rad) > cfg.limits.max_joint_angle_rad {
            fault = fault.or(Some(Fault::AngleRange));
        }
        timer.mark(Stage::Jae);

        // --- Tension model and DOB ---------------------------------------------
        let mut model_n = dob::tension_model(&cfg.tension, &mut st.tension, x1.vel, x2_m, x2.vel);
        if cfg.tension.added.len > 0 {
            model_n += cfg
                .tension
                .added
                .eval(&mut st.tension_terms, &signals, d.period_s);
        }
        if !st.primed {
            d.dob.reset(&mut st.dob, model_n);
            // Best knowledge of the current on the first tick: the monitor.
            st.last_current_a = i_meas_a;
        }
        let drive_current = if cfg.dob.use_measured_current {
            i_meas_a
        } else {
            st.last_current_a
        };
        let dob_out: DobOut = d.dob.update(&mut st.dob, drive_current, phi.vel, model_n);
        let m = &cfg.machine;
        let r = m.pulley_radius_m;
        // Cable 1's stretch force (tension above the preload), used by the
        // stretch estimate and the slack check.
        let cable1_stretch_n = cfg.stretch.cable1_n_m * (x1_m - r * theta_hat_rad);
        let joint_torque_nm =
            r * (cable1_stretch_n - cfg.stretch.cable2_n_m * (r * theta_hat_rad - x2_m));
        let friction_n =
            cfg.tension.f_sc1_n * st.tension.sign_x1 + cfg.tension.f_cp2_n * st.tension.sign_x2;
        if !st.primed {
            st.stretch_force_n = joint_torque_nm / m.gripper_length_m;
            st.tension_friction_n = friction_n;
        }
        let f_ext_stretch_n = d.force_lp.update(
            &mut st.stretch_force_n,
            joint_torque_nm / m.gripper_length_m,
        );
        let tension_friction_n = d.force_lp.update(&mut st.tension_friction_n, friction_n);
        let mut fused = d.fusion.update(
            &mut st.fusion,
            &FusionIn {
                x1_m,
                x1_vel_m_s: x1.vel,
                x2_m,
                x2_vel_m_s: x2.vel,
                tension1_dob_n: dob_out.tension1_n,
                tension1_model_n: dob_out.tension1_model_n,
                tension1_friction_n: tension_friction_n,
                joint_torque_nm: f_ext_stretch_n * m.gripper_length_m,
                drive_torque_nm: m.torque_constant_nm_a * drive_current
                    - cfg.dob.viscous_nm_s_rad * phi.vel,
                drive_torque_q_nm: st.dob.drive_nm,
                // A pair's grip on the motor's angle presses toward its
                // object's side; a jaw alone is thrown back at contact, and
                // a pair on the JAE's angle rings ([`crate::grip`]).
                pressing_sign: match self.command.trajectory {
                    Trajectory::Grip { force_n, .. }
                        if st.grip_partner.is_some()
                            && self.command.mode == Mode::MotorPosition =>
                    {
                        grip::side(force_n)
                    }
                    _ => 0.0,
                },
            },
        );
        // Cable 1 is slack when both chains that see its tension put it
        // below a fraction of the preload (a physical threshold, not a
        // motor/joint disagreement): its stretch, whose scale rests on the
        // spring rate, and the motor's torque balance less slider
        // 1's friction band, whose scale rests on the torque constant. A
        // slack cable passes both (the motor then holds only the slider);
        // a stiffness scale off by a third fails only the first, so it is
        // no fault. While slider 1 sticks, though, its friction can hold
        // most of the tension from the motor, and the stretch alone decides:
        // it counts at the upper end of its stiffness scale's uncertainty
        // (`fusion.stiffness_tolerance`), so a scale off by that much is no
        // fault either.
        let tension1_stretch_n = cable1_stretch_n + cfg.tension.f_0_n;
        let tension1_stretch_hi_n =
            tension1_stretch_n + cfg.fusion.stiffness_tolerance * math::abs(cable1_stretch_n);
        let tension1_motor_n = dob_out.tension1_n - cfg.tension.f_sc1_n;
        if st.primed
            && cfg.limits.min_tension_fraction > 0.0
            && tension1_stretch_hi_n.max(tension1_motor_n) < cfg.slack_limit_n()
        {
            fault = fault.or(Some(Fault::TransmissionSlack));
        }
        // Cable 0 (rope wheel to slider 1): two checks on its elongation
        // `e = phi r_m / z_i - x1`, which falls below its zero-tension
        // value `e_0` only when the rope is slack. Cable 0 is the shortest
        // stretch of rope in the machine, so `K_w0 >= K_w1` and cable 1's
        // compliance bounds its stretch. A stuck slider 1 can keep cable 1
        // taut while the motor unwinds, so the check above cannot see this.
        //
        // 1. Fast, on the motor's reading: its torque balance puts the
        //    tension below the limit (no slider friction sits between the
        //    two) and the motor has paid out more than `limit / K_w1`
        //    since it last read the limit: more than the rope can shorten
        //    from the limit to zero tension.
        // 2. Without the motor's reading (which the drive's own friction,
        //    or a dither's currents, can hold above the limit while the
        //    rope hangs slack): quasi-statically `T_0 <= T_1 + 2 f_sc1`
        //    (slider 1's friction, static up to twice its kinetic band), so
        //    on every tick `e - reach <= e_0` with
        //    `reach = (T_1 + 2 f_sc1 + limit) / K_w0`, `K_w0` as `identify`
        //    read it (`stretch.cable0_n_m`, within a few percent either
        //    side; the floor stays under `e_0` well above that) or else
        //    `K_w1`. The highest such value seen is a floor under `e_0`;
        //    `e` below it is slack. Check 1 keeps `K_w1`: its bound rests
        //    on the motor's reading at the last taut tick, which the
        //    drive's friction puts off by several newtons.
        //
        // While probing, check 1 also runs on the means over the last whole
        // dither period of the motor's reading and of `e`: the dither's
        // currents lift the instantaneous reading above the limit once a
        // period with the rope slack, which re-arms the check on each tick
        // every period and can hide the payout. The means keep the check's
        // bound: a mean tension at the limit puts the mean of `e` at most
        // `limit / K_w0` above `e_0` (the tension is `K_w0 (e - e_0)` where
        // positive, zero where slack), and a mean of `e` below `e_0` means
        // the rope hung slack during that period. Either check latches. (A
        // rope already slack when the first mean is published leaves the
        // means nothing taut to compare with: check 2 stands.)
        let cable0_m = phi_rad * d.rope_m_per_motor_rad - x1_m;
        let limit_n = cfg.slack_limit_n();
        let mut no_payout = false;
        let reach_m =
            (tension1_stretch_n.max(0.0) + 2.0 * math::abs(cfg.tension.f_sc1_n) + limit_n)
                * d.cable0_m_per_n;
        if !st.primed || cfg.limits.min_tension_fraction <= 0.0 {
            st.cable0_taut_m = cable0_m;
            st.cable0_floor_m = cable0_m - reach_m;
            st.cable0_mean_taut_m = None;
        } else {
            if dob_out.tension1_n >= limit_n {
                st.cable0_taut_m = cable0_m;
            }
            let mut payout_m = st.cable0_taut_m - cable0_m;
            // (Only a configuration with probing on can publish a mean.)
            if d.probe.enabled() {
                match st.probe.mean() {
                    Some(p) => {
                        if p.tension1_dob_n >= limit_n {
                            st.cable0_mean_taut_m = Some(p.cable0_m);
                        }
                        if let Some(taut_m) = st.cable0_mean_taut_m {
                            payout_m = payout_m.max(taut_m - p.cable0_m);
                        }
                    }
                    None => st.cable0_mean_taut_m = None,
                }
            }
            st.cable0_floor_m = st.cable0_floor_m.max(cable0_m - reach_m);
            if payout_m > d.cable0_payout_m || cable0_m < st.cable0_floor_m {
                fault = fault.or(Some(Fault::Cable0Slack));
            }
            // The payout stop (`cascade.payout_stop`, off by default): while
            // the motor's reading has cable 0 below the slack limit and the
            // motor has unwound more than half the rope's shortening from
            // that limit to zero tension since (`limit / (2 K_w0)`, or
            // `K_w1`'s bound), the cascade unwinds no further. More would
            // only slacken a rope that a stuck slider 1 does not take up
            // (the hold's error just outside its dead band asks for exactly
            // that). It holds the motor rather than winding back: at rest
            // the motor's reading is its velocity integrator's current
            // against its own stiction, and a wind-back that trusted it
            // ratcheted the rope out a threshold at a time until the checks
            // above latched. They still latch on a rope slack beyond their
            // bounds.
            if cfg.cascade.payout_stop && payout_m > d.cable0_stop_m {
                no_payout = true;
                fused.flags |= fusion::flags::PAYOUT_STOPPED;
            }
        }
        timer.mark(Stage::Dob);

        // --- Reference and cascade -------------------------------------------
        let t_cmd = st.tick.wrapping_sub(st.command_tick) as f32 * d.period_s;
        if !st.primed {
            st.stretch_rad = theta_hat_rad - theta_motor_rad;
        }
        let stretch_rad = match &d.blend {
            Some(lp) => lp.update(&mut st.stretch_rad, theta_hat_rad - theta_motor_rad),
            None => theta_hat_rad - theta_motor_rad,
        };
        let feedback = match self.command.mode {
            Mode::JointClosedLoop => theta_motor_rad + stretch_rad,
            _ => theta_motor_rad,
        };
        // On `theta_hat` itself, optionally, the position loop's damping
        // takes the JAE's rate from the grating's observer (its position
        // term, `c4 x2'`) instead of differencing a quantized angle
        // (`cascade.kd_on_observer_rate`, [`crate::cascade`]).
        let feedback_vel_rad_s = (cfg.cascade.kd_on_observer_rate
            && self.command.mode == Mode::JointClosedLoop
            && d.blend.is_none())
        .then_some(cfg.jae.c_pos_rad_m * x2.vel);
        let gripping = self.command.trajectory.is_grip();
        let mut reference = match (self.command.mode, self.command.trajectory) {
            (Mode::Idle, _) => Reference {
                angle_rad: theta_hat_rad,
                vel_rad_s: 0.0,
            },
            (
                _,
                Trajectory::Grip {
                    force_n,
                    approach_rad_s,
                },
            ) if st.fault.is_none() => d.grip.update(
                &mut st.grip,
                &GripIn {
                    set_n: force_n,
                    approach_rad_s,
                    force_n: fused.f_ext_n,
                    angle_fb_rad: feedback,
                    partner: st.grip_partner,
                    max_angle_rad: cfg.limits.max_joint_angle_rad,
                },
            ),
            (_, trajectory) => trajectory.at(t_cmd),
        };
        if st.transfer_s > 0.0 {
            if t_cmd < st.transfer_s {
                let fade = Trajectory::PointToPoint {
                    from_rad: st.transfer_rad,
                    to_rad: 0.0,
                    duration_s: st.transfer_s,
                }
                .at(t_cmd);
                reference.angle_rad += fade.angle_rad;
                reference.vel_rad_s += fade.vel_rad_s;
            } else {
                st.transfer_s = 0.0;
            }
        }
        st.last_ref_rad = reference.angle_rad;
        st.last_ref_vel_rad_s = reference.vel_rad_s;
        // Probing: a dither on a hold, and the fused estimate replaced by
        // its mean over the last whole dither period once one is complete.
        // Never during a grip: its law reads the estimate every tick. Nor on
        // a tick that primes the estimators afresh (start-up, homing's
        // origin, a non-finite reading): they restart from the measurements
        // there, and it is the tick's worst case (the whole state's reset).
        let probing = d.probe.enabled()
            && st.primed
            && !gripping
            && self.command.mode != Mode::Idle
            && st.fault.is_none()
            && reference.vel_rad_s == 0.0;
        if probing {
            let (angle_rad, vel_rad_s) = d.probe.dither(&st.probe);
            reference.angle_rad += angle_rad;
            reference.vel_rad_s += vel_rad_s;
            let values = Averaged {
                f_ext_n: fused.f_ext_n,
                lo_n: fused.lo_n,
                hi_n: fused.hi_n,
                tension1_dob_n: dob_out.tension1_n,
                cable0_m,
            };
            // No growth while the payout stop holds the motor (see
            // `Probe::update`).
            if let Some(p) = d.probe.update(&mut st.probe, values, x2_m, no_payout) {
                fused.f_ext_n = p.f_ext_n;
                fused.lo_n = p.lo_n;
                fused.hi_n = p.hi_n;
                fused.flags |= fusion::flags::PROBED;
                if st.probe.stuck() {
                    fused.flags |= fusion::flags::PROBE_STUCK;
                }
            }
        } else if st.probing {
            st.probe.restart();
        }
        st.probing = probing;
        let current_ff_a = if cfg.cascade.tension_feedforward {
            (model_n * m.rope_wheel_radius_m / m.gear_ratio + cfg.dob.viscous_nm_s_rad * phi.vel)
                / m.torque_constant_nm_a
        } else {
            0.0
        };
        let casc = cascade::step(
            &cfg.cascade,
            &mut st.cascade,
            &CascadeIn {
                angle_ref_rad: reference.angle_rad,
                vel_ref_rad_s: reference.vel_rad_s,
                angle_fb_rad: feedback,
                vel_fb_rad_s: feedback_vel_rad_s,
                motor_vel_rad_s: phi.vel,
                current_ff_a,
                motor_per_joint: d.motor_per_joint,
                hold: reference.vel_rad_s == 0.0,
                no_payout,
            },
            d.period_s,
        );

        let est = Estimates {
            t_s: st.tick as f32 * d.period_s,
            theta_ref_rad: reference.angle_rad,
            theta_hat_rad,
            theta_motor_rad,
            theta_mag_rad,
            x1_m,
            x2_m,
            x1_vel_m_s: x1.vel,
            x1_acc_m_s2: x1.acc,
            x2_vel_m_s: x2.vel,
            x2_acc_m_s2: x2.acc,
            phi_rad,
            phi_vel_rad_s: phi.vel,
            phi_acc_rad_s2: phi.acc,
            i_meas_a,
            motor_vel_ref_rad_s: casc.motor_vel_ref_rad_s,
            load_torque_nm: dob_out.load_torque_nm,
            tension1_n: dob_out.tension1_n,
            tension1_model_n: dob_out.tension1_model_n,
            f_ext_hat_n: dob_out.f_ext_n,
            f_ext_stretch_n,
            f_ext_fused_n: fused.f_ext_n,
            f_ext_lo_n: fused.lo_n,
            f_ext_hi_n: fused.hi_n,
            fusion_flags: fused.flags,
            tension1_stretch_n,
        };
        let finite = casc.current_a.is_finite()
            && theta_hat_rad.is_finite()
            && dob_out.f_ext_n.is_finite()
            && f_ext_stretch_n.is_finite()
            && fused.f_ext_n.is_finite()
            && dob_out.tension1_n.is_finite()
            && x1.acc.is_finite()
            && phi.acc.is_finite();
        if !finite {
            fault = fault.or(Some(Fault::NonFinite));
            // Restart the estimators from the measurements on the next tick.
            st.primed = false;
        } else {
            st.primed = true;
        }
        if st.fault.is_none() {
            st.fault = fault;
        }

        let enabled = st.fault.is_none() && self.command.mode != Mode::Idle;
        let current_ref_a = if enabled { casc.current_a } else { 0.0 };
        if !enabled {
            st.cascade = CascadeState::default();
        }
        st.last_current_a = current_ref_a;
        st.drive_was_enabled = enabled;
        st.tick = st.tick.wrapping_add(1);
        timer.mark(Stage::Cascade);
        Output {
            current_ref_a,
            dac: s.dac_code(current_ref_a),
            drive_enable: enabled,
            fault: st.fault,
            mode: self.command.mode,
            est,
        }
    }

    /// Run the estimators on a recorded sample: the same step, with the drive
    /// left disabled and `applied_current_a` (the logged current reference)
    /// taken as the current applied over the last period. This is how the host
    /// tools recompute, from a log, exactly the estimates the firmware computes
    /// online.
    pub fn replay(&mut self, raw: &RawSample, applied_current_a: f32) -> Output {
        let command = self.command;
        self.command.mode = Mode::Idle;
        if self.state.primed {
            self.state.last_current_a = applied_current_a;
        }
        let out = self.step(raw);
        self.command = command;
        out
    }

    /// Time since the command in force started, s.
    pub fn command_elapsed_s(&self) -> f32 {
        self.command_time_s()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at_rest() -> RawSample {
        RawSample {
            current: AdcCode(2048),
            ..Default::default()
        }
    }

    #[test]
    fn idle_outputs_zero_with_drive_disabled() {
        let mut c = Controller::new(Config::default()).unwrap();
        for _ in 0..10 {
            let out = c.step(&at_rest());
            assert_eq!(out.current_ref_a, 0.0);
            assert!(!out.drive_enable);
            assert_eq!(out.fault, None);
        }
    }

    #[test]
    fn encoder_jump_disables_drive_in_the_same_tick_and_latches() {
        let mut c = Controller::new(Config::default()).unwrap();
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Hold { angle_rad: 0.1 },
        });
        let mut raw = at_rest();
        let out = c.step(&raw);
        assert!(out.drive_enable && out.current_ref_a != 0.0);
        raw.grating2 = GratingCount(5000); // 5 mm in 0.5 ms: impossible
        let out = c.step(&raw);
        assert_eq!(out.fault, Some(Fault::EncoderJump(Sensor::Grating2)));
        assert!(!out.drive_enable);
        assert_eq!(out.current_ref_a, 0.0);
        assert_eq!(out.dac, c.config().scales.dac_code(0.0));
        for _ in 0..100 {
            let out = c.step(&raw);
            assert!(!out.drive_enable, "does not re-enable on its own");
        }
        c.clear_fault();
        // After a fault the operator re-homes before running again.
        c.set_origin(&raw);
        let out = c.step(&raw);
        assert_eq!(
            (out.fault, out.mode, out.drive_enable),
            (None, Mode::Idle, false)
        );
    }

    /// Cable 1's tension read off its stretch: the joint turning positive
    /// (slider 2 moves out) while slider 1 stays put unloads cable 1; below
    /// the configured fraction of the preload it is slack, above it not.
    /// The motor here holds nothing (no current measured, the shaft still),
    /// so its torque balance agrees that cable 1 is slack.
    #[test]
    fn slack_cable_is_a_fault_by_its_tension_not_by_an_angle() {
        let mut cfg = Config::default();
        cfg.dob.use_measured_current = true;
        let (half, slack) = slack_runs(cfg, at_rest());
        assert_eq!(half.fault, None, "half the preload left is not slack");
        assert!((half.est.tension1_stretch_n - 0.5 * cfg.tension.f_0_n).abs() < 0.5);
        assert_eq!(slack.fault, Some(Fault::TransmissionSlack));
        assert!(!slack.drive_enable);
    }

    /// While slider 1 sticks the motor's balance cannot vouch for cable 1,
    /// and the stretch decides at the upper end of its stiffness scale's
    /// uncertainty: 15 % of the preload read off the stretch is no fault
    /// with the default ±10 % (it could be 23.5 %, above the 20 % limit),
    /// and is one with a scale taken as exact.
    #[test]
    fn a_stretch_below_the_limit_by_less_than_its_scale_uncertainty_is_no_fault() {
        let mut cfg = Config::default();
        cfg.dob.use_measured_current = true;
        assert!(cfg.limits.min_tension_fraction < 0.15 + 0.85 * cfg.fusion.stiffness_tolerance);
        let out = slack_run(cfg, at_rest(), 0.15);
        assert!(out.est.tension1_stretch_n < cfg.slack_limit_n());
        assert_eq!(out.fault, None);
        cfg.fusion.stiffness_tolerance = 0.0;
        assert_eq!(
            slack_run(cfg, at_rest(), 0.15).fault,
            Some(Fault::TransmissionSlack)
        );
    }

    /// The same stretch, while the measured motor current holds the full
    /// preload on cable 0: the motor's chain says cable 1 is taut (a
    /// stiffness scale off, not a slack cable), so there is no fault.
    #[test]
    fn a_stretch_that_reads_slack_while_the_motor_holds_the_preload_is_no_fault() {
        let mut cfg = Config::default();
        cfg.dob.use_measured_current = true;
        let raw = RawSample {
            current: preload_current(&cfg),
            ..Default::default()
        };
        let (_, slack) = slack_runs(cfg, raw);
        assert!(slack.est.tension1_stretch_n < cfg.slack_limit_n());
        assert_ne!(slack.fault, Some(Fault::TransmissionSlack));
    }

    /// Cable 0 slack: the motor pays out rope (its shaft turning negative,
    /// no current, so its torque balance reads no tension) while slider 1
    /// stays put. The fault latches once the payout passes the slack
    /// limit's stretch on a cable as compliant as cable 1, not before; the
    /// same payout taken up by slider 1 (the cable taut, the whole
    /// transmission moving) is no fault.
    #[test]
    fn a_motor_paying_out_rope_that_slider_1_does_not_take_up_is_cable_0_slack() {
        let cfg = cable0_config();
        let limit_m = cfg.slack_limit_n() / cfg.stretch.cable1_n_m;
        let run = |payout_m: f32, follow: f32| {
            pay_out_rope(cfg, |_| at_rest().current, payout_m, follow, |_| {})
        };
        assert_eq!(run(0.8 * limit_m, 0.0), None, "within the limit's stretch");
        let at_m = run(2.0 * limit_m, 0.0).expect("twice the limit's stretch paid out");
        assert!(
            (at_m - limit_m).abs() < 0.02 * limit_m,
            "latched at {at_m} m of payout, limit {limit_m} m"
        );
        assert_eq!(run(2.0 * limit_m, 1.0), None, "slider 1 took the rope up");
    }

    /// Cable 0 slack while the motor's torque balance still reads the full
    /// preload (a drive whose friction or currents the DOB does not model):
    /// with slider 1 stuck, a payout beyond what cable 1's tension plus
    /// twice slider 1's friction band (and the limit) could stretch the
    /// rope is slack; less is not. The stretch is cable 0's: with its
    /// stiffness identified (`stretch.cable0_n_m`, 15 times cable 1's
    /// here) the reach is that much shorter; a value below cable 1's, or
    /// none, leaves cable 1's bound.
    #[test]
    fn a_payout_beyond_any_stretch_the_tensions_allow_is_cable_0_slack_whatever_the_motor_reads() {
        let base = cable0_config();
        for (cable0_n_m, stiffness_n_m) in [
            (0.0, base.stretch.cable1_n_m),
            (0.5 * base.stretch.cable1_n_m, base.stretch.cable1_n_m),
            (
                15.0 * base.stretch.cable1_n_m,
                15.0 * base.stretch.cable1_n_m,
            ),
        ] {
            let mut cfg = base;
            cfg.stretch.cable0_n_m = cable0_n_m;
            // Cable 1 holds the preload (slider 1 and the joint at zero).
            let reach_m = (cfg.tension.f_0_n + 2.0 * cfg.tension.f_sc1_n + cfg.slack_limit_n())
                / stiffness_n_m;
            let run = |payout_m: f32| {
                pay_out_rope(
                    cfg,
                    |_| preload_current(&cfg),
                    payout_m,
                    0.0,
                    |out| {
                        assert!(out.est.tension1_stretch_n > 0.9 * cfg.tension.f_0_n);
                    },
                )
            };
            assert_eq!(
                run(0.9 * reach_m),
                None,
                "within the reach, K_w0 {cable0_n_m}"
            );
            let at_m = run(2.0 * reach_m).expect("twice the reach paid out");
            assert!(
                (at_m - reach_m).abs() < 0.02 * reach_m,
                "K_w0 {cable0_n_m}: latched at {at_m} m of payout, reach {reach_m} m"
            );
        }
    }

    /// Cable 0 slack while probing: the rope taut at the preload through
    /// the hold's first periods, then slack while the motor pays out, the
    /// dither's currents swinging the motor's torque balance by twice the
    /// slack limit either side of its mean once a period. The
    /// instantaneous reading would re-arm check 1 every period (a quarter
    /// of the limit's stretch is paid out per period here); over a whole
    /// period it reads no tension, and check 1 latches within two periods'
    /// payout of the limit's stretch. With the rope taut throughout and
    /// slider 1 taking it up, it does not.
    #[test]
    fn a_dithers_current_swing_does_not_hide_a_slack_cable_0_while_probing() {
        let mut cfg = cable0_config();
        cfg.probe.enabled = true;
        let limit_m = cfg.slack_limit_n() / cfg.stretch.cable1_n_m;
        let period_ticks = crate::probe::Probe::block_ticks(&cfg.probe, cfg.period_s())
            * crate::probe::BLOCKS as u32;
        // The motor's reading: the preload while the hold settles, then
        // `mean_n`, plus a swing of twice the limit in phase with the dither.
        let swing = |mean_n: f32| {
            move |tick: u32| {
                let phase = 2.0 * math::PI * (tick % period_ticks) as f32 / period_ticks as f32;
                let mean_n = if tick < SETTLE_TICKS {
                    cfg.tension.f_0_n
                } else {
                    mean_n
                };
                current_holding(&cfg, mean_n + 2.0 * cfg.slack_limit_n() * math::sin(phase))
            }
        };
        // The payout takes 2 s: eight periods at the default 4 Hz.
        let at_m = pay_out_rope(cfg, swing(0.0), 2.0 * limit_m, 0.0, |_| {})
            .expect("the rope reads no tension over a whole period: slack");
        let per_period_m = 2.0 * limit_m * period_ticks as f32 / 4000.0;
        assert!(
            at_m <= limit_m + 2.0 * per_period_m,
            "latched at {at_m} m of payout, limit {limit_m} m, {per_period_m} m per period"
        );
        assert_eq!(
            pay_out_rope(cfg, swing(cfg.tension.f_0_n), 2.0 * limit_m, 1.0, |_| {}),
            None,
            "slider 1 took the rope up"
        );
    }

    /// Ticks [`pay_out_rope`] holds still before paying out.
    const SETTLE_TICKS: u32 = 1000;

    /// The cable-0 tests' configuration: the DOB on the measured current,
    /// which the tests set and the drive never follows (not a tracking
    /// fault here).
    fn cable0_config() -> Config {
        let mut cfg = Config::default();
        cfg.dob.use_measured_current = true;
        cfg.limits.max_current_error_a = 0.0;
        cfg
    }

    /// The current-monitor code of a motor holding the preload on cable 0.
    fn preload_current(cfg: &Config) -> AdcCode {
        current_holding(cfg, cfg.tension.f_0_n)
    }

    /// The current-monitor code of a motor holding `tension_n` on cable 0.
    fn current_holding(cfg: &Config, tension_n: f32) -> AdcCode {
        let m = &cfg.machine;
        let a = tension_n * m.rope_wheel_radius_m / (m.gear_ratio * m.torque_constant_nm_a);
        AdcCode((a / cfg.scales.adc_a_per_code + cfg.scales.adc_zero_code) as u16)
    }

    /// Hold the motor at zero with the current-monitor code `current(tick)`
    /// measured, then pay out
    /// `payout_m` of rope while slider 1 follows by `follow` of it; `each`
    /// sees every output of the payout. The payout at which cable 0's fault
    /// latched (the drive off), if it did.
    fn pay_out_rope(
        cfg: Config,
        current: impl Fn(u32) -> AdcCode,
        payout_m: f32,
        follow: f32,
        each: impl Fn(&Output),
    ) -> Option<f32> {
        let s = cfg.scales;
        let rope_m_per_rad = 1.0 / cfg.machine.motor_rad_per_cable_m();
        let mut c = Controller::new(cfg).unwrap();
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        });
        let mut raw = RawSample::default();
        // The DOB starts from the modelled preload: let it read the idle
        // rope first (0.5 s, many times its time constant).
        for tick in 0..SETTLE_TICKS {
            raw.current = current(tick);
            assert_eq!(c.step(&raw).fault, None);
        }
        // Slowly (2 s), so the shaft's inertia and viscous drag, which the
        // torque balance reads as rope tension, stay far below the limit.
        for k in 1..=4000 {
            let out_m = payout_m * k as f32 / 4000.0;
            let phi_rad = -out_m / rope_m_per_rad;
            let counts = phi_rad / (2.0 * math::PI) * s.motor_counts_per_rev as f32;
            raw.motor = MotorCount(counts as i32 as u16);
            raw.grating1 = GratingCount((-follow * out_m / s.grating_m_per_count) as i32);
            raw.current = current(SETTLE_TICKS + k);
            let out = c.step(&raw);
            each(&out);
            if let Some(f) = out.fault {
                assert_eq!(f, Fault::Cable0Slack);
                assert!(!out.drive_enable);
                return Some(out_m);
            }
        }
        None
    }

    /// Hold the motor at zero and turn the joint positive by slider 2 alone
    /// until cable 1's stretch tension is half, then a tenth, of the
    /// preload: the controller's output after each.
    fn slack_runs(cfg: Config, start: RawSample) -> (Output, Output) {
        (slack_run(cfg, start, 0.5), slack_run(cfg, start, 0.1))
    }

    /// [`slack_runs`] to one fraction `f` of the preload left on cable 1.
    fn slack_run(cfg: Config, start: RawSample, f: f32) -> Output {
        let per_count = cfg.jae.c_pos_rad_m * cfg.scales.grating_m_per_count;
        let r = cfg.machine.pulley_radius_m;
        // Counts of x2 at which cable 1's tension is a fraction `f` of F_0.
        let counts_at = |f: f32| {
            ((1.0 - f) * cfg.tension.f_0_n / (cfg.stretch.cable1_n_m * r * per_count)) as i32
        };
        let run = |end_counts: i32| {
            let mut c = Controller::new(cfg).unwrap();
            c.set_command(Command {
                mode: Mode::MotorPosition,
                trajectory: Trajectory::Hold { angle_rad: 0.0 },
            });
            let mut raw = start;
            let mut out = c.step(&raw);
            for k in 1..=400 {
                raw.grating2 = GratingCount(end_counts * k / 400);
                out = c.step(&raw);
                if out.fault.is_some() {
                    break;
                }
            }
            for _ in 0..200 {
                out = c.step(&raw);
            }
            out
        };
        run(counts_at(f))
    }

    /// The stretch estimator reads the joint torque off the two cables:
    /// a static pose with cable 1 stretched by 20 µm beyond cable 2's side.
    #[test]
    fn stretch_force_matches_the_cable_balance() {
        let mut cfg = Config::default();
        cfg.jae = crate::config::JaeConfig {
            c_acc_rad_s2_m: 0.0,
            c_vel_rad_s_m: 0.0,
            c_sign_rad: 0.0,
            ..cfg.jae
        };
        let mut c = Controller::new(cfg).unwrap();
        c.step(&at_rest());
        let raw = RawSample {
            grating1: GratingCount(520),
            grating2: GratingCount(500),
            ..at_rest()
        };
        let mut out = c.step(&raw);
        for _ in 0..2000 {
            out = c.step(&raw);
        }
        let (x1, x2, r) = (520e-6f32, 500e-6f32, cfg.machine.pulley_radius_m);
        let theta = cfg.jae.c_pos_rad_m * x2;
        let tau = r
            * (cfg.stretch.cable1_n_m * (x1 - r * theta)
                - cfg.stretch.cable2_n_m * (r * theta - x2));
        let want = tau / cfg.machine.gripper_length_m;
        assert!(
            (out.est.f_ext_stretch_n - want).abs() < 1e-3 * want.abs().max(1.0),
            "{} vs {want}",
            out.est.f_ext_stretch_n
        );
    }

    #[test]
    fn adc_rail_is_a_fault() {
        let mut c = Controller::new(Config::default()).unwrap();
        c.set_command(Command {
            mode: Mode::JointClosedLoop,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        });
        let out = c.step(&RawSample {
            current: AdcCode(4095),
            ..Default::default()
        });
        assert_eq!(out.fault, Some(Fault::AdcRail));
        assert_eq!(out.current_ref_a, 0.0);
    }

    #[test]
    fn motor_counter_wrap_is_not_a_jump() {
        let mut c = Controller::new(Config::default()).unwrap();
        let mut raw = at_rest();
        raw.motor = MotorCount(65530);
        c.step(&raw);
        c.set_origin(&raw);
        for k in 1..200u16 {
            raw.motor = MotorCount(65530u16.wrapping_add(k * 3));
            let out = c.step(&raw);
            assert_eq!(out.fault, None);
            assert!((out.est.phi_rad - c.config().scales.motor_rad(k as i32 * 3)).abs() < 1e-5);
        }
    }

    /// Homing restarts every estimator as a new controller would. After
    /// `set_origin` the state equals a fresh controller's, save what homing
    /// keeps: the tick, the winding's heat, a latched fault, and the probe's
    /// ring (rewritten before it is read). The two then step identically.
    #[test]
    fn homing_restarts_the_estimators_as_a_fresh_controller_would() {
        use crate::effects::{EffectKind, Term, TermState};
        let mut cfg = Config::default();
        cfg.probe.enabled = true;
        // The samples below are no plant: the current does not follow the
        // reference, and the cables' stretch is arbitrary.
        cfg.limits.max_current_error_a = 0.0;
        cfg.limits.min_tension_fraction = 0.0;
        let time = Term {
            kind: EffectKind::Time { scale_s: 1.0 },
            input: sig::X1_M,
            aux: 0,
        };
        let creep = Term {
            kind: EffectKind::Creep { tau_s: 0.5 },
            input: sig::X1_M,
            aux: 0,
        };
        assert!(cfg.jae.added.push(time, 1e-3));
        assert!(cfg.tension.added.push(creep, 10.0));
        let hold = Command {
            mode: Mode::JointClosedLoop,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        };
        // Slow motion on every sensor: the filters, signs, terms and the
        // probe (a hold, so it dithers) all leave their defaults.
        let sample = |k: u32| {
            let w = 0.002 * k as f32;
            RawSample {
                grating1: GratingCount((40.0 * math::sin(w)) as i32),
                grating2: GratingCount((60.0 * math::sin(1.3 * w)) as i32),
                motor: MotorCount((300.0 * math::sin(w)) as i32 as u16),
                magnetic: MagneticCount((20.0 * math::sin(1.3 * w)) as i32 as u16),
                current: AdcCode((2048 + (30.0 * math::sin(3.0 * w)) as i32) as u16),
            }
        };
        let mut used = Controller::new(cfg).unwrap();
        used.set_command(hold);
        for k in 0..3000 {
            used.step(&sample(k));
        }
        assert_eq!(used.state.fault, None);
        assert_ne!(used.state.probe, ProbeState::default(), "the probe ran");
        assert_ne!(used.state.jae_terms[0], TermState::default());
        let mut restarted_probe = used.state.probe;
        restarted_probe.restart();
        let origin = sample(3000);
        used.set_origin(&origin);
        used.set_command(hold);
        let mut fresh = Controller::new(cfg).unwrap();
        fresh.set_origin(&origin);
        fresh.set_command(hold);
        let mut expected = fresh.state;
        expected.tick = used.state.tick;
        expected.command_tick = used.state.tick;
        expected.i2t_a2 = used.state.i2t_a2;
        expected.fault = used.state.fault;
        expected.probe = restarted_probe;
        assert_eq!(used.state, expected);
        for k in 3000..6000 {
            let (a, mut b) = (used.step(&sample(k)), fresh.step(&sample(k)));
            b.est.t_s = a.est.t_s; // the controllers' clocks differ
            assert_eq!(
                (a.est, a.current_ref_a),
                (b.est, b.current_ref_a),
                "tick {k}"
            );
        }
    }

    /// A sample at rest with the current monitor reading `amps`.
    fn reading(c: &Controller, amps: f32) -> RawSample {
        let s = &c.config().scales;
        RawSample {
            current: AdcCode((amps / s.adc_a_per_code + s.adc_zero_code).round() as u16),
            ..Default::default()
        }
    }

    fn holding(config: Config) -> Controller {
        let mut c = Controller::new(config).unwrap();
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        });
        c
    }

    /// A command that starts away from the reference in force (sent late,
    /// or a hold far from the joint) is reached by a minimum-jerk transfer
    /// whose speed stays within a quarter of the motor-velocity limit's
    /// joint speed, not by a step; one that starts where the reference is
    /// takes over at once.
    #[test]
    fn a_command_that_starts_away_from_the_reference_is_reached_without_a_step() {
        let mut config = Config::default();
        // The readings stay at rest whatever the drive asks.
        config.limits.max_current_error_a = 0.0;
        config.limits.min_tension_fraction = 0.0;
        let joint_speed = config
            .machine
            .joint_rad_from_motor_rad(0.25 * config.cascade.vel_limit_rad_s);
        let period = config.period_s();
        let mut c = holding(config);
        for _ in 0..20 {
            c.step(&at_rest());
        }
        let target = 0.3;
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Hold { angle_rad: target },
        });
        let transfer_ticks = (1.875 * target / joint_speed / period).ceil() as usize;
        let mut last = 0.0f32;
        let mut peak_speed = 0.0f32;
        for k in 0..transfer_ticks + 2 {
            let o = c.step(&at_rest());
            let step = o.est.theta_ref_rad - last;
            peak_speed = peak_speed.max(step.abs() / period);
            assert!(
                step.abs() <= 1.01 * joint_speed * period,
                "tick {k}: the reference stepped {step} rad"
            );
            last = o.est.theta_ref_rad;
        }
        assert_eq!(last, target, "the transfer ends on the command's angle");
        assert!(peak_speed > 0.9 * joint_speed, "{peak_speed} rad/s");
        // A sine that starts where the reference is: no transfer, the
        // trajectory itself from its first tick.
        let sine = Trajectory::Sine {
            offset_rad: target,
            amplitude_rad: 0.1,
            freq_hz: 0.5,
        };
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: sine,
        });
        for k in 0..50 {
            let o = c.step(&at_rest());
            let want = sine.at(k as f32 * period).angle_rad;
            assert_eq!(o.est.theta_ref_rad, want, "tick {k}");
        }
    }

    /// Homing restarts only the active effect terms' state; the slots past
    /// the bank stay at rest, also after a bank with more terms was
    /// replaced by a shorter one (`install` retires what it used).
    #[test]
    fn homing_after_a_shorter_term_bank_leaves_no_term_state_behind() {
        use crate::effects::{EffectKind, Term, TermState};
        let mut two = Config::default();
        two.limits.max_current_error_a = 0.0;
        two.limits.min_tension_fraction = 0.0;
        let creep = |tau_s| Term {
            kind: EffectKind::Creep { tau_s },
            input: sig::X2_M,
            aux: 0,
        };
        let mut one = two;
        assert!(two.jae.added.push(creep(0.5), 1e-3));
        assert!(two.jae.added.push(creep(2.0), 1e-3));
        assert!(one.jae.added.push(creep(0.5), 1e-3));
        let sample = |k: u32| RawSample {
            grating2: GratingCount((60.0 * math::sin(0.003 * k as f32)) as i32),
            ..RawSample::default()
        };
        let mut c = Controller::new(two).unwrap();
        for k in 0..500 {
            c.step(&sample(k));
        }
        assert_ne!(c.state.jae_terms[1], TermState::default(), "term 2 ran");
        c.set_config(one).unwrap();
        assert_eq!(c.state.jae_terms[1], TermState::default(), "retired");
        assert_ne!(c.state.jae_terms[0], TermState::default(), "kept");
        c.set_origin(&sample(500));
        assert!(c.state.jae_terms.iter().all(|t| *t == TermState::default()));
    }

    #[test]
    fn probing_dithers_only_a_held_reference_and_publishes_after_a_settling_period() {
        let mut config = Config::default();
        config.probe.enabled = true;
        // The readings stay at rest whatever the drive asks: no tracking check.
        config.limits.max_current_error_a = 0.0;
        let period_ticks = crate::probe::Probe::block_ticks(&config.probe, config.period_s())
            * crate::probe::BLOCKS as u32;
        let mut c = holding(config);
        // The current that holds the preload: the DOB reads no load, so the
        // fused bound holds zero and the probe may grow its dither.
        let m = &config.machine;
        let hold_a =
            config.tension.f_0_n * m.rope_wheel_radius_m / (m.gear_ratio * m.torque_constant_nm_a);
        let still = reading(&c, hold_a);
        let probed = |o: &Output| o.est.fusion_flags & crate::fusion::flags::PROBED != 0;
        // The first tick primes the estimators from the measurements: no
        // dither there.
        let first = c.step(&still);
        assert!(!probed(&first) && first.est.theta_ref_rad == 0.0);
        let mut range = [(f32::MAX, f32::MIN); 2];
        for k in 0..2 * period_ticks - 1 {
            let o = c.step(&still);
            assert!(
                !probed(&o),
                "published at tick {k}, before two whole periods"
            );
            let (lo, hi) = &mut range[(k / period_ticks) as usize];
            *lo = lo.min(o.est.theta_ref_rad);
            *hi = hi.max(o.est.theta_ref_rad);
        }
        // The readings stand still: the first period dithers at the
        // configured amplitude, the second at twice it (the probe's growth
        // on a joint that does not follow).
        let amp = config.probe.amplitude_rad;
        for ((lo, hi), a) in range.into_iter().zip([amp, 2.0 * amp]) {
            assert!(
                (hi - a).abs() < 0.01 * a && (lo + a).abs() < 0.01 * a,
                "{lo}..{hi} against ±{a}"
            );
        }
        let o = c.step(&still);
        assert!(
            probed(&o),
            "the mean is published after the settling period"
        );
        assert!(
            o.est.fusion_flags & crate::fusion::flags::PROBE_STUCK != 0,
            "a mean over a joint that never moved says so"
        );
        assert!(o.est.f_ext_lo_n <= o.est.f_ext_fused_n && o.est.f_ext_fused_n <= o.est.f_ext_hi_n);
        // A moving reference is not dithered, and the mean starts over.
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Sine {
                offset_rad: 0.0,
                amplitude_rad: 0.1,
                freq_hz: 0.5,
            },
        });
        for _ in 0..10 {
            let o = c.step(&at_rest());
            assert!(!probed(&o), "a moving reference is not probed");
        }
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        });
        let o = c.step(&at_rest());
        assert!(!probed(&o), "a new hold settles again before publishing");
        // Off by default: no dither at all.
        let mut off = holding(Config::default());
        for _ in 0..period_ticks {
            assert_eq!(off.step(&at_rest()).est.theta_ref_rad, 0.0);
        }
    }

    #[test]
    fn over_current_is_a_fault_only_with_the_drive_enabled() {
        let mut idle = Controller::new(Config::default()).unwrap();
        let high = reading(&idle, 2.4);
        for _ in 0..10 {
            assert_eq!(idle.step(&high).fault, None, "not ours to judge");
        }
        let mut c = holding(Config::default());
        let out = c.step(&reading(&c, 0.0));
        assert!(out.drive_enable);
        let out = c.step(&reading(&c, 2.2));
        assert_eq!(out.fault, None, "below the 2.25 A limit");
        let out = c.step(&high);
        assert_eq!(out.fault, Some(Fault::OverCurrent));
        assert!(!out.drive_enable);
        assert_eq!(out.current_ref_a, 0.0);
    }

    /// From cold at a constant 1.5 A (continuous 1.2 A, tau 12 s) the I²t
    /// state crosses 1.2² at `-12 ln(1 - (1.2 / 1.5)²)` = 12.26 s; after the
    /// fault a clear waits until the winding has cooled below 90 % of its
    /// rating.
    #[test]
    fn i2t_trips_when_the_winding_would_overheat_and_blocks_the_clear() {
        let mut cfg = Config::default();
        cfg.limits.max_current_error_a = 0.0; // the monitor is not the drive here
        let mut c = holding(cfg);
        let hot = reading(&c, 1.5);
        let amps = c.config().scales.adc_a(hot.current);
        let expected_s = -12.0 * libm::logf(1.0 - (1.2 / amps) * (1.2 / amps));
        let mut tripped_s = None;
        for k in 0..40_000u32 {
            let out = c.step(&hot);
            if out.fault.is_some() {
                assert_eq!(out.fault, Some(Fault::I2t));
                assert!(!out.drive_enable);
                tripped_s = Some(k as f32 * c.period_s());
                break;
            }
        }
        let t = tripped_s.expect("I²t must trip");
        assert!(
            (t - expected_s).abs() < 0.05,
            "{t} s, expected {expected_s} s"
        );
        assert!(c.fault_cause_persists(), "still hot");
        let cold = reading(&c, 0.0);
        let mut cooled_s = None;
        for k in 0..20_000u32 {
            c.step(&cold);
            if !c.fault_cause_persists() {
                cooled_s = Some(k as f32 * c.period_s());
                break;
            }
        }
        // 1.44 A² decays to (0.9 · 1.2)² = 1.1664 A² in 12 ln(1.44 / 1.1664) s.
        let cooled = cooled_s.expect("the winding cools");
        assert!((cooled - 2.53).abs() < 0.05, "{cooled} s");
    }

    #[test]
    fn a_current_that_does_not_follow_the_reference_is_a_fault() {
        // A drive that follows: the monitor reads the last reference back.
        let mut c = holding(Config::default());
        let mut raw = reading(&c, 0.0);
        raw.motor = MotorCount(500); // away from the hold: the loop pushes
        for _ in 0..2000 {
            let out = c.step(&raw);
            assert_eq!(out.fault, None);
            raw.current = reading(&c, out.current_ref_a).current;
        }
        // A broken lead: the monitor reads zero while the loop asks for
        // current. Low-passed over 20 ms, the 0.5 A limit is crossed within
        // -0.02 ln(1 - 0.5 / |i_ref|) s.
        let mut c = holding(Config::default());
        let mut broken = reading(&c, 0.0);
        broken.motor = MotorCount(500);
        let mut at = None;
        let mut i_ref = 0.0f32;
        for k in 0..200u32 {
            let out = c.step(&broken);
            if out.fault.is_some() {
                assert_eq!(out.fault, Some(Fault::CurrentTracking));
                assert!(!out.drive_enable);
                at = Some(k);
                break;
            }
            i_ref = out.current_ref_a;
        }
        let k = at.expect("the tracking check must trip");
        assert!(i_ref.abs() > 0.5, "the loop asked for {i_ref} A");
        // At the predicted tick, not merely within 20 ms: a filter several
        // times too slow would still trip inside that.
        let cfg = Config::default();
        let limit = cfg.limits.max_current_error_a;
        let trip_s = -cfg.limits.current_error_time_s * libm::logf(1.0 - limit / i_ref.abs());
        let predicted = trip_s * cfg.control_rate_hz;
        assert!(
            (k as f32 - predicted).abs() <= 2.0 + 0.1 * predicted,
            "tick {k}, predicted {predicted:.1} ({limit} A limit, {i_ref} A asked)"
        );
    }

    #[test]
    fn external_fault_latches() {
        let mut c = Controller::new(Config::default()).unwrap();
        c.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        });
        c.step(&at_rest());
        c.report_fault(Fault::DriveFault);
        let out = c.step(&at_rest());
        assert_eq!(out.fault, Some(Fault::DriveFault));
        assert!(!out.drive_enable);
    }
}
