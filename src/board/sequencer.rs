//! Start-up sequence, run inside the control tick (tick-deterministic, so the
//! trace generator, the QEMU firmware and the replay test see the same
//! commands at the same ticks):
//!
//! 1. **Check** (drive disabled, [`Mode::Idle`]): the controller runs its
//!    estimators for [`HomingConfig::check_s`]; any latched fault (ADC rail,
//!    encoder jump, drive fault line) or a current-monitor reading above
//!    [`HomingConfig::max_idle_current_a`] in the check's second half ends
//!    start-up with [`Fault::Homing`] (or the fault itself). The first
//!    half lets the current of a drive just disabled decay: a program
//!    that arrives while the joint moves restarts the sequence on a tick
//!    whose sample was taken with the drive still on.
//! 2. **Leaving** (only if the origin switch is already asserted): move away
//!    from the switch, opposite to the search direction, until it releases.
//! 3. **Homing**: in [`Mode::MotorPosition`], a smooth move of
//!    [`HomingConfig::search_rad`] (joint) at up to
//!    [`HomingConfig::speed_rad_s`]. The first rising edge of the origin
//!    switch zeroes every counter ([`Controller::set_origin`] with that
//!    tick's sample). No edge before the move ends (plus a margin) is
//!    [`Fault::Homing`].
//!
//! With the drive off the cable preload back-drives the gearhead, so the
//! joint boots relaxed, far on the negative side, with slack cables; homing
//! re-tensions them while it searches (positive direction by default).
//! Before homing the joint angle is unknown and the cables may be slack, so
//! while leaving and homing the controller's joint-angle range check is
//! widened by twice the search span and its slack check
//! (`limits.min_tension_fraction`) is off; the user's limits are restored on
//! the edge (one cheap `set_limits` each time).
//! 4. **Running**: the program's command. From now on a rising origin edge
//!    farther than [`HomingConfig::origin_tolerance_rad`] from zero (by the
//!    joint estimate) is [`Fault::OriginDuringMotion`].

use crate::config::within;
use crate::controller::{Command, Controller, Mode, Output, RawSample};
use crate::fault::Fault;
use crate::math;
use crate::trajectory::Trajectory;
use crate::units::GratingCount;

use super::io::Events;

/// Start-up and homing settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct HomingConfig {
    /// Sensor check with the drive disabled, s.
    pub check_s: f32,
    /// Largest current-monitor reading accepted with the drive disabled
    /// (judged in the second half of the check), A.
    pub max_idle_current_a: f32,
    /// Signed joint-angle span searched for the origin switch, rad.
    pub search_rad: f32,
    /// Peak joint speed while homing, rad/s.
    pub speed_rad_s: f32,
    /// After homing, an origin edge farther than this from zero (joint
    /// estimate) is a fault, rad.
    pub origin_tolerance_rad: f32,
    /// A motor-only program, the seed's no-load motor run (Sect. 4.2) for
    /// `B_m`: the rope wheel is unhooked and slider 1 clamped, so the
    /// origin switch on the joint side cannot be found and there is no
    /// homing. After the check the counters are zeroed where the mechanism
    /// rests, the slack checks are off (the motor holds no cable), and
    /// only [`Mode::MotorPosition`] commands run. Slider 1 moving more
    /// than [`MOTOR_ONLY_MAX_X1_M`] from where it rested is
    /// [`Fault::TransmissionHooked`], latched before that tick's step.
    pub motor_only: bool,
}

/// How far slider 1 may move in a motor-only program, m. Clamped, it moves
/// by its grating's noise (a count or two); hooked, it follows the rope
/// wheel at `r_m / z_i` = 0.17 mm per motor radian, so 50 µm is 0.29 motor
/// rad, or 0.7° of the joint on its 4 mm pulley.
pub const MOTOR_ONLY_MAX_X1_M: f32 = 50e-6;

impl Default for HomingConfig {
    fn default() -> Self {
        Self {
            check_s: 0.05,
            max_idle_current_a: 0.2,
            search_rad: 2.5,
            speed_rad_s: 2.0,
            origin_tolerance_rad: 0.1,
            motor_only: false,
        }
    }
}

impl HomingConfig {
    /// Check every field (the command task's check of a program).
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        within(
            "homing.check_s",
            self.check_s,
            0.0..=10.0,
            "within 0..=10 s",
        )?;
        within(
            "homing.max_idle_current_a",
            self.max_idle_current_a,
            0.0..=10.0,
            "within 0..=10 A",
        )?;
        within(
            "homing.search_rad",
            math::abs(self.search_rad),
            0.01..=5.0,
            "a magnitude within 0.01..=5 rad",
        )?;
        within(
            "homing.speed_rad_s",
            self.speed_rad_s,
            0.01..=20.0,
            "within 0.01..=20 rad/s",
        )?;
        within(
            "homing.origin_tolerance_rad",
            self.origin_tolerance_rad,
            0.0..=1.0,
            "within 0..=1 rad",
        )
    }
}

/// What the firmware does after start-up.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Program {
    /// Start-up and homing.
    pub homing: HomingConfig,
    /// Command run once homed.
    pub command: Command,
    /// A host-driven program sets this: with no request (any request,
    /// [`super::Request::Heartbeat`] at least) for this long, s, the program
    /// ends with [`Fault::CommandTimeout`] and the drive off. 0 = off, for
    /// autonomous programs (the built-in one).
    pub command_timeout_s: f32,
}

impl Default for Program {
    /// The seed's loading protocol: move the joint to 30° in one second and
    /// hold it there (weights are then hung on the tip).
    fn default() -> Self {
        Self {
            homing: HomingConfig::default(),
            command_timeout_s: 0.0,
            command: Command {
                mode: Mode::JointClosedLoop,
                trajectory: Trajectory::PointToPoint {
                    from_rad: 0.0,
                    to_rad: 30.0 * math::PI / 180.0,
                    duration_s: 1.0,
                },
            },
        }
    }
}

impl Program {
    /// Check the homing settings, the command's trajectory and the timeout.
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        self.homing.validate()?;
        if self.homing.motor_only && !motor_only_allows(&self.command) {
            return Err(crate::ConfigError {
                field: "program.command.mode",
                expected: "MotorPosition or Idle in a motor-only program (homing.motor_only): \
                           the joint is not driven with the rope wheel unhooked",
            });
        }
        self.command
            .trajectory
            .validate()
            .map_err(|expected| crate::ConfigError {
                field: "program.command.trajectory",
                expected,
            })?;
        within(
            "program.command_timeout_s",
            self.command_timeout_s,
            0.0..=3600.0,
            "within 0 (off)..=3600 s",
        )
    }
}

/// Phase of the start-up sequence.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Phase {
    /// No program yet (drive disabled).
    #[default]
    Waiting,
    /// Sensor check.
    Check,
    /// Moving off an already asserted origin switch.
    Leaving,
    /// Searching for the origin edge.
    Homing,
    /// Homed, running the program's command.
    Running,
    /// Start-up failed (a fault is latched).
    Failed,
}

impl Phase {
    /// Stable code for telemetry.
    pub const fn code(self) -> u8 {
        match self {
            Phase::Waiting => 0,
            Phase::Check => 1,
            Phase::Leaving => 2,
            Phase::Homing => 3,
            Phase::Running => 4,
            Phase::Failed => 5,
        }
    }

    /// Decode a telemetry code.
    pub const fn from_code(code: u8) -> Option<Phase> {
        Some(match code {
            0 => Phase::Waiting,
            1 => Phase::Check,
            2 => Phase::Leaving,
            3 => Phase::Homing,
            4 => Phase::Running,
            5 => Phase::Failed,
            _ => return None,
        })
    }
}

/// Whether a motor-only program ([`HomingConfig::motor_only`]) runs
/// `command`: the motor's own position loop, or nothing.
fn motor_only_allows(command: &Command) -> bool {
    matches!(command.mode, Mode::MotorPosition | Mode::Idle)
}

/// The start-up state machine (configuration: the [`Program`]; state: phase
/// and ticks in it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sequencer {
    program: Option<Program>,
    phase: Phase,
    ticks_in_phase: u32,
    limit_ticks: u32,
    last_ref_rad: f32,
    /// The user's joint-angle range and slack limit while homing widens them.
    user_limits: Option<(f32, f32)>,
    /// Ticks since the last operator request (command timeout).
    ticks_since_request: u32,
    /// In a motor-only program, slider 1's count where it rested.
    motor_only_rest: Option<GratingCount>,
}

/// Ticks in `s` seconds at `period_s`, at least one.
fn ticks(s: f32, period_s: f32) -> u32 {
    let n = s / period_s;
    if n >= 1.0 {
        n as u32
    } else {
        1
    }
}

impl Sequencer {
    /// Phase in force.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Program in force.
    pub fn program(&self) -> Option<&Program> {
        self.program.as_ref()
    }

    /// An operator request arrived (any request resets the command timeout).
    pub fn request_seen(&mut self) {
        self.ticks_since_request = 0;
    }

    /// (Re)start the sequence with `program`: drive disabled, check first.
    pub fn start(&mut self, ctrl: &mut Controller, program: Program) {
        self.program = Some(program);
        self.restart(ctrl);
    }

    /// Whether a command sent while running is taken: in a motor-only
    /// program only the motor's own position loop (or idle) is.
    pub fn accepts(&self, command: &Command) -> bool {
        self.phase == Phase::Running
            && (self.motor_only_rest.is_none() || motor_only_allows(command))
    }

    /// Start again from the check (after a cleared fault).
    pub fn restart(&mut self, ctrl: &mut Controller) {
        self.motor_only_rest = None;
        self.restore_range(ctrl);
        ctrl.set_command(Command::default());
        self.enter(if self.program.is_some() {
            Phase::Check
        } else {
            Phase::Waiting
        });
    }

    fn enter(&mut self, phase: Phase) {
        self.phase = phase;
        self.ticks_in_phase = 0;
    }

    /// Put a prepared configuration in force; while homing, the user's
    /// range is kept aside and the widened one stays in force. Cheap (no
    /// filter design): called on a control tick.
    pub fn set_config(
        &mut self,
        ctrl: &mut Controller,
        mut prepared: crate::PreparedConfig,
    ) -> Result<(), crate::ConfigError> {
        if let Some(user) = self.user_limits.as_mut() {
            let mut l = prepared.config().limits;
            *user = (l.max_joint_angle_rad, l.min_tension_fraction);
            l.max_joint_angle_rad = ctrl.config().limits.max_joint_angle_rad;
            l.min_tension_fraction = ctrl.config().limits.min_tension_fraction;
            prepared.set_limits(l)?;
        }
        ctrl.install(prepared);
        Ok(())
    }

    /// Widen the range check by `span_rad` each way and switch the slack
    /// checks off: for the search (unknown angle, possibly slack cables),
    /// or a motor-only run (span 0: the motor holds no cable).
    fn widen_range(&mut self, ctrl: &mut Controller, span_rad: f32) {
        if self.user_limits.is_some() {
            return;
        }
        let mut l = ctrl.config().limits;
        let user = (l.max_joint_angle_rad, l.min_tension_fraction);
        l.max_joint_angle_rad = user.0 + 2.0 * math::abs(span_rad);
        l.min_tension_fraction = 0.0;
        if ctrl.set_limits(l).is_ok() {
            self.user_limits = Some(user);
        }
    }

    /// Put the user's limits back.
    fn restore_range(&mut self, ctrl: &mut Controller) {
        if let Some((range, slack)) = self.user_limits.take() {
            let mut l = ctrl.config().limits;
            l.max_joint_angle_rad = range;
            l.min_tension_fraction = slack;
            // Both came from a validated configuration.
            let _ = ctrl.set_limits(l);
        }
    }

    /// A homing move of `span_rad` from the last reference, and the ticks it
    /// may take (its duration plus 20 %).
    fn move_by(&mut self, ctrl: &mut Controller, homing: &HomingConfig, span_rad: f32) {
        let from_rad = self.last_ref_rad;
        // A minimum-jerk move peaks at 1.875 times its mean speed.
        let duration_s = 1.875 * math::abs(span_rad) / homing.speed_rad_s;
        ctrl.set_command(Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::PointToPoint {
                from_rad,
                to_rad: from_rad + span_rad,
                duration_s,
            },
        });
        self.limit_ticks = ticks(1.2 * duration_s, ctrl.period_s());
    }

    /// Before the step. Returns the sample taken as the origin of the
    /// counters on this tick, if any: at the end of the check (the homing
    /// move starts from where the joint rests) and on the homing edge.
    pub fn before_step(
        &mut self,
        ctrl: &mut Controller,
        raw: &RawSample,
        origin_edge: bool,
        origin_level: bool,
    ) -> Option<RawSample> {
        let program = self.program?;
        let h = &program.homing;
        self.ticks_in_phase = self.ticks_in_phase.saturating_add(1);
        self.ticks_since_request = self.ticks_since_request.saturating_add(1);
        let active = !matches!(self.phase, Phase::Waiting | Phase::Failed);
        if active
            && program.command_timeout_s > 0.0
            && self.ticks_since_request > ticks(program.command_timeout_s, ctrl.period_s())
        {
            self.fail_with(ctrl, Fault::CommandTimeout);
            return None;
        }
        match self.phase {
            Phase::Running => {
                if let Some(rest) = self.motor_only_rest {
                    let moved = GratingCount(raw.grating1.0.wrapping_sub(rest.0));
                    if math::abs(ctrl.config().scales.grating_m(moved)) > MOTOR_ONLY_MAX_X1_M {
                        self.fail_with(ctrl, Fault::TransmissionHooked);
                    }
                }
                None
            }
            Phase::Waiting | Phase::Failed => None,
            Phase::Check => {
                if self.ticks_in_phase > ticks(h.check_s, ctrl.period_s()) {
                    // Counters relative to where the joint rests now.
                    ctrl.set_origin(raw);
                    self.last_ref_rad = 0.0;
                    if h.motor_only {
                        self.widen_range(ctrl, 0.0);
                        self.motor_only_rest = Some(raw.grating1);
                        ctrl.set_command(program.command);
                        self.enter(Phase::Running);
                        return Some(*raw);
                    }
                    self.widen_range(ctrl, h.search_rad);
                    if origin_level {
                        self.move_by(ctrl, h, -h.search_rad);
                        self.enter(Phase::Leaving);
                    } else {
                        self.move_by(ctrl, h, h.search_rad);
                        self.enter(Phase::Homing);
                    }
                    Some(*raw)
                } else {
                    None
                }
            }
            Phase::Leaving => {
                if !origin_level {
                    self.move_by(ctrl, h, h.search_rad);
                    self.enter(Phase::Homing);
                } else if self.ticks_in_phase > self.limit_ticks {
                    self.fail(ctrl);
                }
                None
            }
            Phase::Homing => {
                if origin_edge {
                    ctrl.set_origin(raw);
                    self.restore_range(ctrl);
                    ctrl.set_command(program.command);
                    self.enter(Phase::Running);
                    Some(*raw)
                } else {
                    if self.ticks_in_phase > self.limit_ticks {
                        self.fail(ctrl);
                    }
                    None
                }
            }
        }
    }

    fn fail(&mut self, ctrl: &mut Controller) {
        self.fail_with(ctrl, Fault::Homing);
    }

    /// End the program: `fault` latched (unless one already is), command
    /// idle, phase [`Phase::Failed`].
    fn fail_with(&mut self, ctrl: &mut Controller, fault: Fault) {
        self.restore_range(ctrl);
        ctrl.report_fault(fault);
        ctrl.set_command(Command::default());
        self.enter(Phase::Failed);
    }

    /// After the step: start-up checks, and whether an origin edge is
    /// expected before the next tick.
    pub fn after_step(&mut self, ctrl: &mut Controller, out: &Output, events: &Events) {
        self.last_ref_rad = out.est.theta_ref_rad;
        match self.phase {
            Phase::Check | Phase::Leaving | Phase::Homing => {
                if out.fault.is_some() {
                    self.fail(ctrl);
                } else if self.phase == Phase::Check {
                    if let Some(p) = &self.program {
                        let settled =
                            self.ticks_in_phase > ticks(0.5 * p.homing.check_s, ctrl.period_s());
                        if settled && math::abs(out.est.i_meas_a) > p.homing.max_idle_current_a {
                            self.fail(ctrl);
                        }
                    }
                }
            }
            Phase::Waiting | Phase::Running | Phase::Failed => {}
        }
        let expected = match (self.phase, &self.program) {
            (Phase::Running, Some(p)) => {
                math::abs(out.est.theta_hat_rad) < p.homing.origin_tolerance_rad
            }
            _ => true,
        };
        events.set_origin_expected(expected);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::{AdcCode, GratingCount};
    use crate::Config;

    /// The default configuration without the current-tracking check: these
    /// tests step the controller on a fixed sample, a motor that never
    /// draws the current it is given.
    fn config() -> Config {
        let mut c = Config::default();
        c.limits.max_current_error_a = 0.0;
        c
    }

    fn rest() -> RawSample {
        RawSample {
            current: AdcCode(2048),
            ..Default::default()
        }
    }

    /// Step the controller through the sequencer with a fixed sample.
    fn run(
        seq: &mut Sequencer,
        ctrl: &mut Controller,
        raw: &RawSample,
        edge: bool,
        level: bool,
        events: &Events,
    ) -> (Option<RawSample>, Output) {
        let origin = seq.before_step(ctrl, raw, edge, level);
        let out = ctrl.step(raw);
        seq.after_step(ctrl, &out, events);
        (origin, out)
    }

    #[test]
    fn check_then_homing_then_program_on_the_edge() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        let raw = rest();
        // Without a program nothing happens.
        let (_, out) = run(&mut seq, &mut ctrl, &raw, true, false, &events);
        assert_eq!((seq.phase(), out.mode), (Phase::Waiting, Mode::Idle));

        seq.start(&mut ctrl, Program::default());
        let check_ticks = (0.05 * 2000.0) as usize;
        for k in 0..check_ticks {
            let (origin, out) = run(&mut seq, &mut ctrl, &raw, false, false, &events);
            assert_eq!(seq.phase(), Phase::Check, "tick {k}");
            assert!(!out.drive_enable, "drive stays off during the check");
            assert_eq!(origin, None);
        }
        let (origin, out) = run(&mut seq, &mut ctrl, &raw, false, false, &events);
        assert_eq!(origin, Some(raw), "homing starts from the resting sample");
        assert_eq!(seq.phase(), Phase::Homing);
        assert_eq!(out.mode, Mode::MotorPosition);
        assert!(out.drive_enable);
        // The reference moves in the search direction (positive).
        let mut last_ref = out.est.theta_ref_rad;
        // 0.2 s into the minimum-jerk search of `search_rad` lasting
        // 1.875 |search| / speed: s = 0.2 / T, ref = search (10 s^3 - 15 s^4 + 6 s^5).
        let h = HomingConfig::default();
        let s = 0.2 / (1.875 * h.search_rad.abs() / h.speed_rad_s);
        let expected = h.search_rad * s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
        for _ in 0..400 {
            let (_, out) = run(&mut seq, &mut ctrl, &raw, false, false, &events);
            assert!(out.est.theta_ref_rad >= last_ref);
            last_ref = out.est.theta_ref_rad;
        }
        assert!(
            expected > 0.01 && (last_ref - expected).abs() < 1e-3,
            "homing move under way: {last_ref}, expected {expected}"
        );

        let mut at_origin = raw;
        at_origin.grating2 = GratingCount(12);
        let (origin, out) = run(&mut seq, &mut ctrl, &at_origin, true, true, &events);
        assert_eq!(origin, Some(at_origin));
        assert_eq!(seq.phase(), Phase::Running);
        assert_eq!(out.mode, Mode::JointClosedLoop);
        assert_eq!(out.est.x2_m, 0.0, "counters zeroed at the origin sample");
        assert!(events.origin_expected(), "joint at zero: edges expected");
    }

    /// The no-load motor run's program: a motor-position hold.
    fn motor_only() -> Program {
        Program {
            homing: HomingConfig {
                motor_only: true,
                ..HomingConfig::default()
            },
            command: Command {
                mode: Mode::MotorPosition,
                trajectory: Trajectory::Hold { angle_rad: 0.0 },
            },
            command_timeout_s: 0.0,
        }
    }

    #[test]
    fn a_motor_only_program_runs_after_the_check_without_homing_and_without_slack_checks() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        let slack = ctrl.config().limits.min_tension_fraction;
        assert!(slack > 0.0);
        seq.start(&mut ctrl, motor_only());
        let mut raw = rest();
        raw.grating1 = GratingCount(-1_000);
        for _ in 0..(0.05 * 2000.0) as usize {
            run(&mut seq, &mut ctrl, &raw, false, false, &events);
            assert_eq!(seq.phase(), Phase::Check);
        }
        let (origin, out) = run(&mut seq, &mut ctrl, &raw, false, false, &events);
        assert_eq!(origin, Some(raw), "the counters zeroed where it rests");
        assert_eq!(
            (seq.phase(), out.mode),
            (Phase::Running, Mode::MotorPosition)
        );
        assert!(out.drive_enable);
        assert_eq!(ctrl.config().limits.min_tension_fraction, 0.0);
        // Only the motor's own loop (or idle) is taken while it runs.
        let joint = Command {
            mode: Mode::JointClosedLoop,
            trajectory: Trajectory::Hold { angle_rad: 0.0 },
        };
        assert!(!seq.accepts(&joint));
        assert!(seq.accepts(&motor_only().command));
        assert!(seq.accepts(&Command::default()));
        // A homed program takes the joint's commands.
        let homed = Sequencer {
            phase: Phase::Running,
            ..Sequencer::default()
        };
        assert!(homed.accepts(&joint));
        // A restart puts the user's slack check back.
        seq.restart(&mut ctrl);
        assert_eq!(ctrl.config().limits.min_tension_fraction, slack);
        assert!(!seq.accepts(&motor_only().command));
    }

    #[test]
    fn slider_1_moving_in_a_motor_only_program_disables_the_drive_on_that_tick() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        seq.start(&mut ctrl, motor_only());
        let mut raw = rest();
        raw.grating1 = GratingCount(1_000);
        for _ in 0..=(0.05 * 2000.0) as usize {
            run(&mut seq, &mut ctrl, &raw, false, false, &events);
        }
        assert_eq!(seq.phase(), Phase::Running);
        let per_count = ctrl.config().scales.grating_m(GratingCount(1));
        let limit_counts = (MOTOR_ONLY_MAX_X1_M / per_count) as i32;
        // Within the limit either way: still running, drive on.
        for d in [limit_counts, -limit_counts] {
            raw.grating1 = GratingCount(1_000 + d);
            let (_, out) = run(&mut seq, &mut ctrl, &raw, false, false, &events);
            assert_eq!(seq.phase(), Phase::Running, "{d} counts");
            assert!(out.drive_enable && out.fault.is_none());
        }
        raw.grating1 = GratingCount(1_000 - limit_counts - 2);
        let (_, out) = run(&mut seq, &mut ctrl, &raw, false, false, &events);
        assert_eq!(seq.phase(), Phase::Failed);
        assert_eq!(out.fault, Some(Fault::TransmissionHooked));
        assert!(!out.drive_enable, "off on the tick that saw it");
        assert_eq!(
            ctrl.config().limits.min_tension_fraction,
            config().limits.min_tension_fraction
        );
    }

    #[test]
    fn a_motor_only_program_that_drives_the_joint_is_refused() {
        let mut p = motor_only();
        assert!(p.validate().is_ok());
        p.command.mode = Mode::JointClosedLoop;
        let e = p.validate().unwrap_err();
        assert_eq!(e.field, "program.command.mode");
        assert!(Program::default().validate().is_ok());
    }

    #[test]
    fn no_edge_within_the_search_is_a_homing_fault() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        let program = Program::default();
        seq.start(&mut ctrl, program);
        let h = program.homing;
        let limit = (0.05 * 2000.0) as usize
            + (1.2 * 1.875 * h.search_rad.abs() / h.speed_rad_s * 2000.0) as usize
            + 5;
        let mut failed_at = None;
        for k in 0..limit + 10 {
            let (_, out) = run(&mut seq, &mut ctrl, &rest(), false, false, &events);
            if seq.phase() == Phase::Failed {
                assert_eq!(out.fault, Some(Fault::Homing));
                assert!(!out.drive_enable);
                failed_at = Some(k);
                break;
            }
        }
        let k = failed_at.expect("homing must time out");
        assert!(k + 10 >= limit, "not before the search could end: {k}");
    }

    #[test]
    fn start_on_the_switch_leaves_it_first() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        seq.start(&mut ctrl, Program::default());
        for _ in 0..=100 {
            run(&mut seq, &mut ctrl, &rest(), false, true, &events);
        }
        assert_eq!(seq.phase(), Phase::Leaving);
        let mut last = 0.0;
        for _ in 0..100 {
            let (_, out) = run(&mut seq, &mut ctrl, &rest(), false, true, &events);
            assert!(out.est.theta_ref_rad <= last, "leaving moves negative");
            last = out.est.theta_ref_rad;
        }
        // A reference that stood still would pass the loop above.
        assert!(last < -1e-4, "left by {last} rad in 100 ticks");
        run(&mut seq, &mut ctrl, &rest(), false, false, &events);
        assert_eq!(seq.phase(), Phase::Homing);
    }

    #[test]
    fn current_with_the_drive_off_fails_the_check() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        seq.start(&mut ctrl, Program::default());
        let mut raw = rest();
        // About 0.49 A with the drive off. The first half of the check (50
        // ticks at 2 kHz) lets a current decay.
        raw.current = AdcCode(2048 + 400);
        for _ in 0..50 {
            run(&mut seq, &mut ctrl, &raw, false, false, &events);
            assert_eq!(seq.phase(), Phase::Check);
        }
        run(&mut seq, &mut ctrl, &raw, false, false, &events);
        assert_eq!(seq.phase(), Phase::Failed);
        let (_, out) = run(&mut seq, &mut ctrl, &raw, false, false, &events);
        assert_eq!(out.fault, Some(Fault::Homing));
    }

    #[test]
    fn a_program_arriving_with_the_drive_on_is_checked_once_its_current_decayed() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        seq.start(&mut ctrl, Program::default());
        // The sample of the restart's tick and a few after it still carry
        // the current the drive was giving (0.49 A), then it is gone.
        let mut driven = rest();
        driven.current = AdcCode(2048 + 400);
        for _ in 0..10 {
            run(&mut seq, &mut ctrl, &driven, false, false, &events);
        }
        for _ in 0..=90 {
            run(&mut seq, &mut ctrl, &rest(), false, false, &events);
        }
        assert_eq!(seq.phase(), Phase::Homing);
    }

    #[test]
    fn range_check_is_widened_while_homing_and_restored_on_the_edge() {
        let mut ctrl = Controller::new(config()).unwrap();
        let mut seq = Sequencer::default();
        let events = Events::new();
        let user = ctrl.config().limits;
        seq.start(&mut ctrl, Program::default());
        for _ in 0..=100 {
            run(&mut seq, &mut ctrl, &rest(), false, false, &events);
        }
        assert_eq!(seq.phase(), Phase::Homing);
        let widened = ctrl.config().limits;
        assert_eq!(
            widened.max_joint_angle_rad,
            user.max_joint_angle_rad + 2.0 * 2.5
        );
        assert_eq!(
            widened.min_tension_fraction, 0.0,
            "slack check off while homing"
        );
        assert!(user.min_tension_fraction > 0.0);
        // A parameter update while homing keeps the widened range in force
        // and becomes the range restored afterwards.
        let mut c = config();
        c.limits.max_joint_angle_rad = 1.2;
        c.limits.min_tension_fraction = 0.3;
        c.jae.offset_rad = 0.01;
        seq.set_config(&mut ctrl, crate::PreparedConfig::new(c).unwrap())
            .unwrap();
        assert_eq!(ctrl.config().limits, widened);
        assert_eq!(ctrl.config().jae.offset_rad, 0.01);
        run(&mut seq, &mut ctrl, &rest(), true, true, &events);
        assert_eq!(seq.phase(), Phase::Running);
        assert_eq!(ctrl.config().limits.max_joint_angle_rad, 1.2);
        assert_eq!(ctrl.config().limits.min_tension_fraction, 0.3);
        let mut bad = Config::default();
        bad.limits.max_joint_angle_rad = -1.0;
        assert_eq!(
            crate::PreparedConfig::new(bad).unwrap_err().field,
            "limits.max_joint_angle_rad"
        );
    }

    #[test]
    fn phase_codes_round_trip() {
        for code in 0..=255u8 {
            if let Some(p) = Phase::from_code(code) {
                assert_eq!(p.code(), code);
            }
        }
        assert_eq!(Phase::from_code(6), None);
    }
}
