//! One control tick, as the firmware's control task runs it.
//!
//! [`ControlLoop::tick`] is the body of the TIM6 task: sample the front end,
//! latch what the fault tasks left in [`Events`], apply at most one operator
//! [`Request`], advance the start-up [`Sequencer`], run
//! [`Controller::step_timed`], write the DAC and the drive line, and build the
//! raw [`TickRecord`]. The trace generator and the QEMU replay test call the
//! same function, so the firmware's sequence is not written twice.

use embedded_hal::digital::OutputPin;

use crate::config::{Config, ConfigError};
use crate::controller::{Command, Controller, Output, PreparedConfig};
use crate::fault::Fault;
use crate::telemetry::{OriginRecord, StartRecord, TickRecord, FORMAT_VERSION};

use super::io::{DriveEnable, Events, SensorFrontEnd};
use super::sequencer::{Phase, Program, Sequencer};
use super::timing::{CycleCounter, StageStamps};

/// An operator request, validated by the priority-1 command task and applied
/// by the control task at the start of a tick (one per tick).
#[derive(Clone, Copy, Debug, PartialEq)]
// No allocator: a request (a whole `Config` at most) is copied through a
// short queue, so the size difference is accepted.
#[allow(clippy::large_enum_variant)]
pub enum Request {
    /// Run a program: sensor check, homing, then its command.
    Program(Program),
    /// A new mode and trajectory (accepted only once homed).
    SetCommand(Command),
    /// New parameters (e.g. identified ones), validated and with the filters
    /// designed by the sender (`PreparedConfig::new`, outside the tick);
    /// filters keep their state.
    SetConfig(PreparedConfig),
    /// Clear the latched fault and start again from the check and homing.
    /// Refused while a cause persists: the drive's fault line asserted, a
    /// fault waiting to be latched, the winding's I²t above its rating.
    ClearFault,
    /// One telemetry record every this many ticks (at least 1).
    SetDecimation(u32),
    /// Nothing but "the host is still there" (resets a program's command
    /// timeout, as every request does).
    Heartbeat,
}

impl Request {
    /// The command task's check before queueing (the hot path never fails).
    pub fn validate(&self) -> Result<(), ConfigError> {
        match self {
            // Validated when it was prepared.
            Request::SetConfig(_) => Ok(()),
            Request::SetDecimation(0) => Err(ConfigError {
                field: "telemetry.decimation",
                expected: ">= 1",
            }),
            Request::SetCommand(c) => c.trajectory.validate().map_err(|expected| ConfigError {
                field: "command.trajectory",
                expected,
            }),
            Request::Program(p) => p.validate(),
            Request::ClearFault | Request::SetDecimation(_) | Request::Heartbeat => Ok(()),
        }
    }
}

/// What one tick produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickOutcome {
    /// The controller's output.
    pub output: Output,
    /// The raw telemetry record of this tick.
    pub record: TickRecord,
    /// The decimation selects this record for telemetry.
    pub telemetry_due: bool,
    /// Homing took this tick's sample as the origin.
    pub origin: Option<OriginRecord>,
}

/// The control task's state: controller, start-up sequencer, telemetry
/// decimation and tick counter.
#[derive(Clone, Debug, PartialEq)]
pub struct ControlLoop {
    ctrl: Controller,
    seq: Sequencer,
    decimation: u32,
    tick: u32,
    rejected: u32,
    /// Sum of the current references output since the last tick whose
    /// record was queued (that tick's included), A, and how many.
    applied_sum_a: f32,
    applied_ticks: u32,
    /// The last tick's current reference, A.
    last_current_a: f32,
}

impl ControlLoop {
    /// A loop in [`Phase::Waiting`] (drive disabled until a program arrives).
    pub fn new(config: Config, decimation: u32) -> Result<Self, ConfigError> {
        Request::SetDecimation(decimation).validate()?;
        Ok(Self {
            ctrl: Controller::new(config)?,
            seq: Sequencer::default(),
            decimation,
            tick: 0,
            rejected: 0,
            applied_sum_a: 0.0,
            applied_ticks: 0,
            last_current_a: 0.0,
        })
    }

    /// The controller.
    pub fn controller(&self) -> &Controller {
        &self.ctrl
    }

    /// Start-up phase.
    pub fn phase(&self) -> Phase {
        self.seq.phase()
    }

    /// Ticks run so far.
    pub fn ticks(&self) -> u32 {
        self.tick
    }

    /// Requests refused so far (a command before homing or, in a
    /// motor-only program, one that drives the joint; a configuration with
    /// another control rate).
    pub fn rejected_requests(&self) -> u32 {
        self.rejected
    }

    /// The record the firmware logs once at boot.
    pub fn start_record(&self) -> StartRecord {
        StartRecord {
            version: FORMAT_VERSION,
            control_rate_hz: self.ctrl.config().control_rate_hz,
            decimation: self.decimation,
        }
    }

    /// Latch a fault found at boot (the reset's cause: a panic, a HardFault
    /// or the watchdog, see [`super::boot`]): the drive stays off until an
    /// operator clears it.
    pub fn report_boot_fault(&mut self, fault: Fault) {
        self.ctrl.report_fault(fault);
    }

    fn apply(&mut self, request: Request, events: &Events) {
        self.seq.request_seen();
        let accepted = match request {
            Request::Program(p) => {
                self.seq.start(&mut self.ctrl, p);
                true
            }
            Request::SetCommand(c) => {
                let taken = self.seq.accepts(&c);
                if taken {
                    self.ctrl.set_command(c);
                }
                taken
            }
            Request::SetConfig(c) => {
                // The control timer's period is set at boot: another rate
                // would make every filter wrong. Validated by the command
                // task; a failure leaves the old configuration.
                c.config().control_rate_hz == self.ctrl.config().control_rate_hz
                    && self.seq.set_config(&mut self.ctrl, c).is_ok()
            }
            Request::ClearFault => {
                // A clear never clears what it did not see: a fault still
                // waiting in `events` is latched right after this request.
                let cause_persists = events.drive_fault_level()
                    || events.fault_pending()
                    || self.ctrl.fault_cause_persists();
                if !cause_persists {
                    self.ctrl.clear_fault();
                    self.seq.restart(&mut self.ctrl);
                }
                !cause_persists
            }
            Request::SetDecimation(n) => {
                self.decimation = n.max(1);
                true
            }
            Request::Heartbeat => true,
        };
        if !accepted {
            self.rejected = self.rejected.saturating_add(1);
        }
    }

    /// One control tick (the body of the control task).
    pub fn tick<F, P, C>(
        &mut self,
        fe: &mut F,
        drive: &mut DriveEnable<P>,
        events: &Events,
        request: Option<Request>,
        counter: &mut C,
    ) -> TickOutcome
    where
        F: SensorFrontEnd,
        P: OutputPin,
        C: CycleCounter,
    {
        let t0 = counter.now();
        let raw = fe.sample();
        // Level-sensitive: the EXTI task sees edges only, and a line that
        // stays asserted (or was asserted at a clear) raises no new edge.
        events.set_drive_fault_level(fe.drive_fault_asserted());
        // The request first, then the faults: a fault that arrived before a
        // clear is latched after it, never cleared with it.
        if let Some(r) = request {
            self.apply(r, events);
        }
        if let Some(fault) = events.take_fault() {
            self.ctrl.report_fault(fault);
        }
        let edge = events.take_origin_edge();
        let origin = self
            .seq
            .before_step(&mut self.ctrl, &raw, edge, events.origin_level())
            .map(|raw| OriginRecord {
                tick: self.tick,
                raw,
            });
        let mut stamps = StageStamps::new(&mut *counter);
        let out = self.ctrl.step_timed(&raw, &mut stamps);
        let stage_cycles = stamps.stages_u16();
        self.seq.after_step(&mut self.ctrl, &out, events);
        fe.write_current(out.dac);
        let enabled = drive.apply(out.drive_enable, events);
        let cycles = counter.now().wrapping_sub(t0);

        // The current applied over the periods since the last record
        // queued: the outputs of the ticks from that record's on, this
        // one's excluded. A record dropped from a full queue leaves its
        // ticks to the next one sent.
        let current_applied_a = if self.applied_ticks > 0 {
            self.applied_sum_a / self.applied_ticks as f32
        } else {
            0.0
        };
        self.applied_sum_a += out.current_ref_a;
        self.applied_ticks = self.applied_ticks.saturating_add(1);
        self.last_current_a = out.current_ref_a;
        let telemetry_due = self.tick.is_multiple_of(self.decimation);
        let record = TickRecord {
            tick: self.tick,
            raw,
            inputs: events.inputs(),
            dac: out.dac,
            current_ref_a: out.current_ref_a,
            current_applied_a,
            theta_ref_rad: out.est.theta_ref_rad,
            theta_hat_rad: out.est.theta_hat_rad,
            f_ext_hat_n: out.est.f_ext_hat_n,
            f_ext_fused_n: out.est.f_ext_fused_n,
            f_ext_lo_n: out.est.f_ext_lo_n,
            f_ext_hi_n: out.est.f_ext_hi_n,
            mode: out.mode.code(),
            fault: Fault::code_of(out.fault),
            drive_enable: enabled,
            phase: self.seq.phase().code(),
            cycles,
            stage_cycles,
        };
        self.tick = self.tick.wrapping_add(1);
        TickOutcome {
            output: out,
            record,
            telemetry_due,
            origin,
        }
    }

    /// The last tick's record was queued for telemetry: the next record's
    /// applied current ([`TickRecord::current_applied_a`]) is the mean from
    /// that tick on. Not called for a record dropped from a full queue, so
    /// the next record sent covers the dropped one's ticks too.
    pub fn record_queued(&mut self) {
        self.applied_sum_a = self.last_current_a;
        self.applied_ticks = 1;
    }

    /// The control task missed its deadline: latch [`Fault::Overrun`] and cut
    /// the drive now (the controller outputs zero from the next tick on).
    pub fn overrun<P: OutputPin>(&mut self, drive: &mut DriveEnable<P>) {
        self.ctrl.report_fault(Fault::Overrun);
        drive.disable();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::mock::MockOut;
    use crate::board::timing::NoCycles;
    use crate::controller::{Mode, RawSample};
    use crate::units::{AdcCode, DacCode};

    /// A front end that holds still and counts DAC writes.
    #[derive(Default)]
    struct Still {
        samples: u32,
        dac: Option<DacCode>,
        writes: u32,
        /// Level of the drive's fault line.
        fault_line: bool,
    }

    impl SensorFrontEnd for Still {
        fn sample(&mut self) -> RawSample {
            self.samples += 1;
            // A drive that follows its reference: the monitor reads the last
            // DAC code back (ADC and DAC share their default scales).
            RawSample {
                current: AdcCode(self.dac.map_or(2048, |d| d.0)),
                ..Default::default()
            }
        }
        fn write_current(&mut self, dac: DacCode) {
            self.dac = Some(dac);
            self.writes += 1;
        }
        fn drive_fault_asserted(&mut self) -> bool {
            self.fault_line
        }
    }

    #[test]
    fn each_tick_samples_once_writes_the_dac_once_and_drives_the_line() {
        let mut cl = ControlLoop::new(Config::default(), 4).unwrap();
        let mut fe = Still::default();
        let pin = MockOut::default();
        let mut drive = DriveEnable::new(pin.clone());
        let events = Events::new();
        let zero = cl.controller().config().scales.dac_code(0.0);
        let mut due = 0;
        for k in 0..8u32 {
            let req = (k == 0).then_some(Request::Program(Program::default()));
            let o = cl.tick(&mut fe, &mut drive, &events, req, &mut NoCycles);
            assert_eq!(o.record.tick, k);
            assert_eq!(o.record.dac, zero, "idle during the check");
            assert!(!o.record.drive_enable);
            assert_eq!(o.record.phase, Phase::Check.code());
            due += o.telemetry_due as u32;
        }
        assert_eq!((fe.samples, fe.writes), (8, 8));
        assert_eq!(due, 2, "decimation 4 over 8 ticks");
        assert_eq!(pin.high_count(), 0);
        assert_eq!(pin.low_count(), 9, "constructor + one write per tick");
    }

    #[test]
    fn fault_left_by_a_fault_task_is_latched_at_the_next_tick() {
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        let mut fe = Still::default();
        let pin = MockOut::default();
        let mut drive = DriveEnable::new(pin.clone());
        let events = Events::new();
        start_driving(&mut cl, &mut fe, &mut drive, &events, Program::default());
        assert_eq!(cl.controller().command().mode, Mode::MotorPosition);
        assert!(pin.is_high());
        events.raise(Fault::DriveFault);
        let o = cl.tick(&mut fe, &mut drive, &events, None, &mut NoCycles);
        assert_eq!(o.output.fault, Some(Fault::DriveFault));
        assert_eq!(o.record.fault, Fault::DriveFault.code());
        assert!(!o.record.drive_enable && !pin.is_high());
        assert_eq!(o.output.current_ref_a, 0.0);
        assert_eq!(cl.phase(), Phase::Failed);
        // Clearing re-runs the check.
        let o = cl.tick(
            &mut fe,
            &mut drive,
            &events,
            Some(Request::ClearFault),
            &mut NoCycles,
        );
        assert_eq!((o.output.fault, cl.phase()), (None, Phase::Check));
    }

    /// Program the loop and tick until homing enables the drive (the
    /// `Still` front end never shows an origin edge, so homing runs its
    /// search with the drive on).
    fn start_driving(
        cl: &mut ControlLoop,
        fe: &mut Still,
        drive: &mut DriveEnable<MockOut>,
        events: &Events,
        program: Program,
    ) {
        cl.tick(
            fe,
            drive,
            events,
            Some(Request::Program(program)),
            &mut NoCycles,
        );
        for _ in 0..200 {
            if cl
                .tick(fe, drive, events, None, &mut NoCycles)
                .record
                .drive_enable
            {
                return;
            }
        }
        panic!("homing should enable the drive within 200 ticks");
    }

    #[test]
    fn clear_is_refused_while_the_drive_fault_line_stays_asserted() {
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        let mut fe = Still::default();
        let pin = MockOut::default();
        let mut drive = DriveEnable::new(pin.clone());
        let events = Events::new();
        start_driving(&mut cl, &mut fe, &mut drive, &events, Program::default());
        let highs = pin.high_count();
        // The line goes low and stays low; its one edge is long handled (no
        // event waits): only the level tells.
        fe.fault_line = true;
        let o = cl.tick(&mut fe, &mut drive, &events, None, &mut NoCycles);
        assert_eq!(
            o.output.fault,
            Some(Fault::DriveFault),
            "latched from the level"
        );
        assert!(!o.record.drive_enable && !pin.is_high());
        for k in 0..300 {
            let req = (k % 50 == 0).then_some(Request::ClearFault);
            let o = cl.tick(&mut fe, &mut drive, &events, req, &mut NoCycles);
            assert_eq!(o.output.fault, Some(Fault::DriveFault), "tick {k}");
            assert!(!o.record.drive_enable);
        }
        assert_eq!(pin.high_count(), highs, "never re-enabled while asserted");
        assert_eq!(cl.rejected_requests(), 6, "every clear refused");
        // The line releases: the clear is accepted and homing starts over.
        fe.fault_line = false;
        cl.tick(&mut fe, &mut drive, &events, None, &mut NoCycles);
        let o = cl.tick(
            &mut fe,
            &mut drive,
            &events,
            Some(Request::ClearFault),
            &mut NoCycles,
        );
        assert_eq!((o.output.fault, cl.phase()), (None, Phase::Check));
        assert_eq!(cl.rejected_requests(), 6);
    }

    #[test]
    fn a_fault_arriving_just_before_a_clear_is_latched_after_it() {
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        let mut fe = Still::default();
        let mut drive = DriveEnable::new(MockOut::default());
        let events = Events::new();
        start_driving(&mut cl, &mut fe, &mut drive, &events, Program::default());
        cl.overrun(&mut drive);
        // A fault task leaves a fault between the last tick and the one that
        // carries the operator's clear.
        events.raise(Fault::OriginDuringMotion);
        let o = cl.tick(
            &mut fe,
            &mut drive,
            &events,
            Some(Request::ClearFault),
            &mut NoCycles,
        );
        assert_eq!(cl.rejected_requests(), 1, "refused: a fault was waiting");
        assert_eq!(o.output.fault, Some(Fault::Overrun));
        assert!(!o.record.drive_enable);
        // Nothing waits now: the next clear goes through, and the pending
        // fault was not lost before it (first fault wins in the latch).
        let o = cl.tick(
            &mut fe,
            &mut drive,
            &events,
            Some(Request::ClearFault),
            &mut NoCycles,
        );
        assert_eq!(o.output.fault, None);
        assert_eq!(cl.phase(), Phase::Check);
    }

    #[test]
    fn a_host_program_without_requests_times_out_with_the_drive_off() {
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        let mut fe = Still::default();
        let pin = MockOut::default();
        let mut drive = DriveEnable::new(pin.clone());
        let events = Events::new();
        let program = Program {
            command_timeout_s: 0.1,
            ..Program::default()
        };
        start_driving(&mut cl, &mut fe, &mut drive, &events, program);
        // Heartbeats every 0.05 s keep it going for a second.
        for k in 0..2000u32 {
            let req = (k % 100 == 99).then_some(Request::Heartbeat);
            let o = cl.tick(&mut fe, &mut drive, &events, req, &mut NoCycles);
            assert_eq!(o.output.fault, None, "tick {k}");
        }
        // Silence: the fault comes after 0.1 s (200 ticks), not before.
        let mut faulted_at = None;
        for k in 0..400u32 {
            let o = cl.tick(&mut fe, &mut drive, &events, None, &mut NoCycles);
            if o.output.fault.is_some() {
                assert_eq!(o.output.fault, Some(Fault::CommandTimeout));
                assert!(!o.record.drive_enable && !pin.is_high());
                faulted_at = Some(k);
                break;
            }
        }
        let k = faulted_at.expect("the timeout must trip");
        assert!((195..=205).contains(&k), "after 0.1 s: tick {k}");
        assert_eq!(cl.phase(), Phase::Failed);
        // The built-in program has no timeout.
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        start_driving(&mut cl, &mut fe, &mut drive, &events, Program::default());
        for _ in 0..1000 {
            let o = cl.tick(&mut fe, &mut drive, &events, None, &mut NoCycles);
            assert_eq!(o.output.fault, None);
        }
    }

    #[test]
    fn a_fault_from_before_the_reset_keeps_the_drive_off_until_cleared() {
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        let mut fe = Still::default();
        let pin = MockOut::default();
        let mut drive = DriveEnable::new(pin.clone());
        let events = Events::new();
        let boot = crate::board::boot::boot_fault(None, true);
        cl.report_boot_fault(boot.unwrap());
        cl.tick(
            &mut fe,
            &mut drive,
            &events,
            Some(Request::Program(Program::default())),
            &mut NoCycles,
        );
        for _ in 0..400 {
            let o = cl.tick(&mut fe, &mut drive, &events, None, &mut NoCycles);
            assert_eq!(o.record.fault, Fault::Watchdog.code());
            assert!(!o.record.drive_enable);
        }
        assert_eq!(cl.phase(), Phase::Failed);
        assert_eq!(pin.high_count(), 0);
        let o = cl.tick(
            &mut fe,
            &mut drive,
            &events,
            Some(Request::ClearFault),
            &mut NoCycles,
        );
        assert_eq!((o.output.fault, cl.phase()), (None, Phase::Check));
    }

    #[test]
    fn overrun_latches_and_cuts_the_drive() {
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        let pin = MockOut::default();
        let mut drive = DriveEnable::new(pin.clone());
        drive.apply(true, &Events::new());
        assert!(pin.is_high());
        cl.overrun(&mut drive);
        assert!(!pin.is_high());
        assert_eq!(cl.controller().fault(), Some(Fault::Overrun));
    }

    #[test]
    fn requests_are_validated_and_commands_wait_for_homing() {
        assert!(Request::SetDecimation(0).validate().is_err());
        let nan_hold = Command {
            mode: Mode::JointClosedLoop,
            trajectory: crate::trajectory::Trajectory::Hold {
                angle_rad: f32::NAN,
            },
        };
        assert_eq!(
            Request::SetCommand(nan_hold).validate().unwrap_err().field,
            "command.trajectory"
        );
        let mut p = Program::default();
        p.homing.speed_rad_s = 0.0;
        assert_eq!(
            Request::Program(p).validate().unwrap_err().field,
            "homing.speed_rad_s"
        );
        p = Program {
            command_timeout_s: -1.0,
            ..Program::default()
        };
        assert_eq!(
            Request::Program(p).validate().unwrap_err().field,
            "program.command_timeout_s"
        );
        assert!(Request::Program(Program::default()).validate().is_ok());
        let mut bad = Config::default();
        bad.machine.gear_ratio = 0.0;
        assert_eq!(
            PreparedConfig::new(bad).unwrap_err().field,
            "machine.gear_ratio"
        );
        assert!(ControlLoop::new(Config::default(), 0).is_err());
        let mut cl = ControlLoop::new(Config::default(), 1).unwrap();
        let mut fe = Still::default();
        let mut drive = DriveEnable::new(MockOut::default());
        let cmd = Command {
            mode: Mode::JointClosedLoop,
            trajectory: crate::trajectory::Trajectory::Hold { angle_rad: 0.2 },
        };
        let o = cl.tick(
            &mut fe,
            &mut drive,
            &Events::new(),
            Some(Request::SetCommand(cmd)),
            &mut NoCycles,
        );
        assert_eq!(o.output.mode, Mode::Idle, "not homed: refused");
        assert_eq!(cl.rejected_requests(), 1);
        let fast = Config {
            control_rate_hz: 4000.0,
            ..Config::default()
        };
        let fast = PreparedConfig::new(fast).unwrap();
        assert!(Request::SetConfig(fast).validate().is_ok());
        cl.tick(
            &mut fe,
            &mut drive,
            &Events::new(),
            Some(Request::SetConfig(fast)),
            &mut NoCycles,
        );
        assert_eq!(cl.controller().config().control_rate_hz, 2000.0);
        assert_eq!(cl.rejected_requests(), 2, "the timer rate is fixed at boot");
        let mut tuned = Config::default();
        tuned.jae.offset_rad = 0.02;
        cl.tick(
            &mut fe,
            &mut drive,
            &Events::new(),
            Some(Request::SetConfig(PreparedConfig::new(tuned).unwrap())),
            &mut NoCycles,
        );
        assert_eq!(cl.controller().config().jae.offset_rad, 0.02);
        assert_eq!(cl.rejected_requests(), 2);
    }
}
