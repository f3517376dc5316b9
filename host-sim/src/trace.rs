//! `host-sim trace`: record the sensor trace that the QEMU firmware replays.
//!
//! QEMU models neither the encoder timers nor the ADC, so the `qemu` firmware
//! variant plays back what the board would have read. The trace must come
//! from a closed-loop run of the *firmware's* logic, or the replayed sensors
//! would not answer the firmware's commands: this generator runs the
//! simulated prototype ([`crate::plant::Plant`]) in closed loop with
//! [`cable_joint::board::Harness`], the same start-up sequencer, fault
//! handlers and control tick the firmware runs, with the firmware's
//! configuration ([`firmware_config`](cable_joint::board::firmware_config))
//! and program ([`Program::default`]).
//! Tick order is [`crate::sim::Sim::step`]'s: sample, control, drive
//! command, then the plant integrates one period in whole sub-steps.
//!
//! The run (defaults):
//!
//! 1. power off (not recorded, `--relax-s` 1.5 s): with the drive disabled
//!    the cable preload back-drives the gearhead and the mechanism comes to
//!    rest relaxed, on the negative side of the origin;
//! 2. boot: the timers restart from zero, the drive is disabled, the
//!    firmware checks its sensors for 50 ms, then homes: it winds the cables
//!    in (positive search) until the photoelectric origin switch (asserted
//!    while the joint angle is >= 0) rises, zeroes the counters there, and
//!    runs its program (joint to 30° in one second, then hold);
//! 3. a weight (`--load-n`, 0.49 N = 50 g) is hung on the tip at
//!    `--load-at-s` (1.0 s, while the joint moves), so the DOB sees a load;
//! 4. the drive's fault line is asserted at `--drive-fault-at-s` (2.5 s), so
//!    the fault path (drive cut, fault latched) is in the trace too.
//!
//! Output: the binary trace (layout in [`cable_joint::board::trace`]) and,
//! with `--csv`, the firmware logic's own telemetry as a project CSV log.

use cable_joint::board::trace::{trace_header, TRACE_FLAG_PROBING};
use cable_joint::board::{
    firmware_config_probing, ControlLoop, Harness, Program, Request, TickOutcome, TraceSample,
};
use cable_joint::telemetry::{Inputs, OriginRecord, Record, TickRecord};
use cable_joint::units::{GratingCount, MagneticCount, MotorCount};
use cable_joint::RawSample;

use crate::plant::{PlantParams, Tensions, TipObject};
use crate::sim::check_ticks;
use crate::sim::{NullRecorder, Sim};

/// What the recorded run does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceOptions {
    /// Seconds recorded after boot (at most [`crate::sim::MAX_TICKS`]
    /// control ticks).
    pub duration_s: f64,
    /// Seconds the mechanism relaxes with the drive off before boot.
    pub relax_s: f64,
    /// Weight hung on the tip during the hold, N.
    pub load_n: f64,
    /// When the weight is hung (ramped in over 50 ms), s after boot.
    pub load_at_s: f64,
    /// When the drive's fault line is asserted, s after boot (negative:
    /// never).
    pub drive_fault_at_s: f64,
    /// Noise seed.
    pub seed: u64,
    /// Probing on (`probe.enabled`, the core's default dither): the trace's
    /// header says so, and the QEMU firmware replays it with the same
    /// configuration.
    pub probing: bool,
    /// An object at the tip for the whole run (for a grip sent over the
    /// link, `host-sim link --scenario grip`); its push is part of the
    /// recorded true force.
    pub object: Option<TipObject>,
}

impl Default for TraceOptions {
    fn default() -> Self {
        Self {
            duration_s: 2.6,
            relax_s: 1.5,
            load_n: 0.49,
            load_at_s: 1.0,
            drive_fault_at_s: 2.5,
            seed: 1,
            probing: false,
            object: None,
        }
    }
}

impl TraceOptions {
    /// The firmware's configuration, with probing on if asked
    /// ([`firmware_config_probing`]).
    pub fn config(&self) -> cable_joint::Config {
        firmware_config_probing(self.probing)
    }
}

/// A recorded run: what the board read, what the firmware logic did, and the
/// plant's truth.
#[derive(Debug, Clone, Default)]
pub struct Recorded {
    /// Control rate, Hz.
    pub control_rate_hz: f32,
    /// The run had probing on (the trace header's flag).
    pub probing: bool,
    /// One sample per tick (boot-relative counters, input lines).
    pub samples: Vec<TraceSample>,
    /// The firmware logic's outcome per tick.
    pub outcomes: Vec<Ticked>,
    /// True joint angle at each sample, rad.
    pub theta_true_rad: Vec<f64>,
    /// Applied tip force at each sample, N.
    pub f_ext_true_n: Vec<f64>,
    /// True cable tensions at each sample.
    pub tensions_true: Vec<Tensions>,
}

impl Recorded {
    /// The trace file's bytes.
    pub fn trace_bytes(&self) -> Vec<u8> {
        let mut v = Vec::with_capacity(16 + 17 * self.samples.len());
        v.extend_from_slice(&trace_header(
            self.control_rate_hz,
            self.samples.len() as u32,
            if self.probing { TRACE_FLAG_PROBING } else { 0 },
        ));
        for s in &self.samples {
            v.extend_from_slice(&s.to_bytes());
        }
        v
    }

    /// The outcomes as the firmware's telemetry stream (start, origins,
    /// every tick).
    pub fn telemetry(&self) -> Vec<Record> {
        let mut out = Vec::with_capacity(self.outcomes.len() + 3);
        out.push(Record::Start(cable_joint::telemetry::StartRecord {
            version: cable_joint::telemetry::FORMAT_VERSION,
            control_rate_hz: self.control_rate_hz,
            decimation: 1,
        }));
        for o in &self.outcomes {
            if let Some(origin) = o.origin {
                out.push(Record::Origin(origin));
            }
            out.push(Record::Tick(o.record));
        }
        out
    }
}

/// Counters as the board reads them after a reset at `boot`.
fn boot_relative(raw: &RawSample, boot: &RawSample) -> RawSample {
    RawSample {
        grating1: GratingCount(raw.grating1.0.wrapping_sub(boot.grating1.0)),
        grating2: GratingCount(raw.grating2.0.wrapping_sub(boot.grating2.0)),
        motor: MotorCount(raw.motor.0.wrapping_sub(boot.motor.0)),
        magnetic: MagneticCount(raw.magnetic.0.wrapping_sub(boot.magnetic.0)),
        current: raw.current,
    }
}

/// What one tick of the firmware did, as the plant and the recorder see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ticked {
    /// The tick's telemetry record (DAC code, drive enable, estimates).
    pub record: TickRecord,
    /// Homing took this tick's sample as the origin.
    pub origin: Option<OriginRecord>,
    /// The drive enable line after the tick.
    pub drive_enabled: bool,
}

/// The firmware a closed-loop run drives: its logic on the host
/// ([`Harness`]), or the firmware binary on QEMU ([`crate::pil::Pil`]).
pub trait Firmware {
    /// Run tick `k` on `sample`, with the operator's `request` queued
    /// before it.
    fn tick(
        &mut self,
        k: usize,
        sample: &TraceSample,
        request: Option<Request>,
    ) -> anyhow::Result<Ticked>;
    /// The host harness, for fault injections that reach into it between
    /// ticks (none for a remote firmware).
    fn harness(&mut self) -> Option<&mut Harness> {
        None
    }
}

impl Firmware for Harness {
    fn tick(
        &mut self,
        _k: usize,
        sample: &TraceSample,
        request: Option<Request>,
    ) -> anyhow::Result<Ticked> {
        let o: TickOutcome = Harness::tick(self, sample, request);
        Ok(Ticked {
            record: o.record,
            origin: o.origin,
            drive_enabled: self.drive_enabled(),
        })
    }

    fn harness(&mut self) -> Option<&mut Harness> {
        Some(self)
    }
}

/// What a scenario does to the closed loop, tick by tick: fault injection
/// for the fault tests. Every method has the neutral default.
pub trait Inject {
    /// Change what the board reads this tick (a counter glitch, an ADC
    /// stuck at a rail, an input line).
    fn sample(&mut self, _tick: usize, _t_s: f64, _sample: &mut TraceSample) {}
    /// The operator's request this tick (default: the built-in program at
    /// tick 0).
    fn request(&mut self, tick: usize) -> Option<Request> {
        (tick == 0).then_some(Request::Program(Program::default()))
    }
    /// Before the tick runs (e.g. the previous tick overran).
    fn before_tick(&mut self, _tick: usize, _harness: &mut Harness) {}
    /// The current the winding really gets for the drive's `commanded_a`
    /// (a broken lead: none).
    fn applied_current(&mut self, _tick: usize, commanded_a: f64) -> f64 {
        commanded_a
    }
}

/// The closed loop as it is.
pub struct NoInjection;

impl Inject for NoInjection {}

/// What a closed-loop run calls after each tick: the tick's number
/// (from 1), the run's length in ticks and the tick's outcome. An error
/// stops the run (the live view's `q`).
pub type Progress<'a> = dyn FnMut(usize, usize, &Ticked) -> anyhow::Result<()> + 'a;

/// Run the closed loop and record it.
pub fn record(plant: PlantParams, opts: &TraceOptions) -> anyhow::Result<Recorded> {
    record_with(plant, opts, opts.config(), &mut NoInjection)
}

/// Run the closed loop with `config` in the firmware logic and `inject`
/// acting on it, and record it.
pub fn record_with(
    plant: PlantParams,
    opts: &TraceOptions,
    config: cable_joint::Config,
    inject: &mut dyn Inject,
) -> anyhow::Result<Recorded> {
    record_watched(plant, opts, config, inject, &mut |_, _, _| Ok(()))
}

/// [`record_with`], calling `progress` after each tick.
pub fn record_watched(
    plant: PlantParams,
    opts: &TraceOptions,
    config: cable_joint::Config,
    inject: &mut dyn Inject,
    progress: &mut Progress,
) -> anyhow::Result<Recorded> {
    let control = ControlLoop::new(config, 1).map_err(|e| anyhow::anyhow!("{e}"))?;
    record_on(
        plant,
        opts,
        config,
        inject,
        &mut Harness::new(control),
        progress,
    )
}

/// Run the closed loop on `firmware` (whose configuration is `config`)
/// with `inject` acting on it, and record it, calling `progress` after
/// each tick.
pub fn record_on(
    plant: PlantParams,
    opts: &TraceOptions,
    config: cable_joint::Config,
    inject: &mut dyn Inject,
    firmware: &mut dyn Firmware,
    progress: &mut Progress,
) -> anyhow::Result<Recorded> {
    anyhow::ensure!(
        opts.duration_s.is_finite() && opts.duration_s > 0.0,
        "--duration-s must be > 0"
    );
    anyhow::ensure!(
        opts.relax_s.is_finite() && opts.relax_s >= 0.0,
        "--relax-s must be >= 0"
    );
    let rate_hz = f64::from(config.control_rate_hz);
    check_ticks("--duration-s", opts.duration_s, rate_hz)?;
    check_ticks("--relax-s", opts.relax_s, rate_hz)?;
    // Power off: the drive is disabled and the preload back-drives the
    // gearhead until the mechanism rests, relaxed.
    let mut sim = Sim::new(plant, config, opts.seed)?;
    sim.run_for(opts.relax_s, &mut NullRecorder);
    let period_s = sim.period_s();
    let substeps = sim.substeps();
    let scales = sim.plant().params().sensors.scales;
    let plant = sim.plant_mut();
    plant.set_object(opts.object);

    let boot = plant.sample();
    let n = (opts.duration_s / period_s).round() as usize;
    let mut rec = Recorded {
        control_rate_hz: config.control_rate_hz,
        probing: config.probe.enabled,
        ..Default::default()
    };
    let load = |t_s: f64| -> f64 {
        let u = ((t_s - opts.load_at_s) / 0.05).clamp(0.0, 1.0);
        opts.load_n * u
    };
    for k in 0..n {
        let t_s = k as f64 * period_s;
        let raw = boot_relative(&plant.sample(), &boot);
        let theta = plant.state().theta_rad;
        let inputs = Inputs::new(
            theta >= 0.0,
            opts.drive_fault_at_s >= 0.0 && t_s >= opts.drive_fault_at_s,
        );
        let mut sample = TraceSample { raw, inputs };
        inject.sample(k, t_s, &mut sample);
        let request = inject.request(k);
        if let Some(harness) = firmware.harness() {
            inject.before_tick(k, harness);
        }
        let outcome = firmware.tick(k, &sample, request)?;
        let current_a = if outcome.drive_enabled {
            inject.applied_current(k, scales.dac_a(outcome.record.dac) as f64)
        } else {
            0.0
        };
        rec.samples.push(sample);
        progress(k + 1, n, &outcome)?;
        rec.outcomes.push(outcome);
        rec.theta_true_rad.push(theta);
        rec.f_ext_true_n
            .push(plant.external_force_n() + plant.contact_force_n());
        rec.tensions_true.push(plant.tensions());
        plant.set_current_command(current_a);
        let dt = period_s / substeps as f64;
        for j in 0..substeps {
            plant.set_external_force(load(t_s + j as f64 * dt));
            plant.step();
        }
    }
    Ok(rec)
}

/// Origins and ticks of a stream, for writers.
pub fn split(records: &[Record]) -> (Vec<OriginRecord>, Vec<TickRecord>) {
    let mut origins = Vec::new();
    let mut ticks = Vec::new();
    for r in records {
        match r {
            Record::Origin(o) => origins.push(*o),
            Record::Tick(t) => ticks.push(*t),
            Record::Start(_) => {}
        }
    }
    (origins, ticks)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cable_joint::board::Phase;
    use cable_joint::Fault;

    /// A record every tick carries the last tick's current as the current
    /// applied since the record before; a record every 10th tick the mean
    /// of the ten currents the stream does not carry, which is not the
    /// current of any one of them. The decimation changes what is sent,
    /// not what the loop does.
    #[test]
    fn each_record_carries_the_mean_current_applied_since_the_record_before() {
        let opts = TraceOptions::default();
        let config = opts.config();
        let every = record(PlantParams::default(), &opts).unwrap();
        let mut tenth_fw = Harness::new(ControlLoop::new(config, 10).unwrap());
        let tenth = record_on(
            PlantParams::default(),
            &opts,
            config,
            &mut NoInjection,
            &mut tenth_fw,
            &mut |_, _, _| Ok(()),
        )
        .unwrap();
        let current = |r: &Recorded, k: usize| r.outcomes[k].record.current_ref_a;
        let n = every.outcomes.len();
        assert_eq!(tenth.outcomes.len(), n);
        for k in 0..n {
            assert_eq!(current(&every, k).to_bits(), current(&tenth, k).to_bits());
        }
        for k in 1..n {
            assert_eq!(
                every.outcomes[k].record.current_applied_a.to_bits(),
                current(&every, k - 1).to_bits(),
                "tick {k}"
            );
        }
        let mut apart = 0;
        for k in (10..n).step_by(10) {
            let mean = (k - 10..k).map(|j| current(&tenth, j)).sum::<f32>() / 10.0;
            let sent = tenth.outcomes[k].record.current_applied_a;
            assert_eq!(sent.to_bits(), mean.to_bits(), "tick {k}");
            apart += usize::from((sent - current(&tenth, k - 1)).abs() > 1e-3);
        }
        assert!(
            apart > n / 100,
            "the mean differs from the last current on {apart} records"
        );
    }

    /// A record dropped from the firmware's full queue leaves its ticks to
    /// the next record sent: that record's applied current is the mean
    /// over both steps (the ticks since the last record that was sent).
    #[test]
    fn a_record_after_a_dropped_one_carries_the_mean_over_both_steps() {
        let opts = TraceOptions::default();
        let run = record(PlantParams::default(), &opts).unwrap();
        let mut fw = Harness::new(ControlLoop::new(opts.config(), 10).unwrap());
        let dropped = |k: usize| k % 30 == 20;
        let mut out = Vec::new();
        for (k, s) in run.samples.iter().enumerate() {
            let request = NoInjection.request(k);
            out.push(fw.tick_queued(s, request, !dropped(k)).record);
        }
        let current = |k: usize| out[k].current_ref_a;
        for (k, o) in out.iter().enumerate() {
            // The same samples, the same loop: the same currents.
            assert_eq!(
                o.current_ref_a.to_bits(),
                run.outcomes[k].record.current_ref_a.to_bits()
            );
        }
        let mut checked = 0;
        for k in (30..out.len()).step_by(30) {
            // Record k - 20 was sent, k - 10 dropped: k covers twenty ticks.
            let mean = (k - 20..k).map(current).sum::<f32>() / 20.0;
            let sent = out[k].current_applied_a;
            assert!(
                (sent - mean).abs() <= 1e-6 * (1.0 + mean.abs()),
                "tick {k}: {sent} vs {mean}"
            );
            let last_ten = (k - 10..k).map(current).sum::<f32>() / 10.0;
            checked += usize::from((sent - last_ten).abs() > 1e-3);
        }
        assert!(
            checked > 5,
            "the mean over twenty ticks differs from the last ten's on {checked}"
        );
    }

    /// What the firmware logic must do on the simulated prototype whatever
    /// the controller's tuning: check with the drive off, home on the
    /// switch edge, cut the drive on the fault line. (Tracking and force
    /// accuracy are the core's and the simulator's tests.)
    #[test]
    fn recorded_run_checks_homes_on_the_edge_and_cuts_on_the_fault_line() {
        let opts = TraceOptions::default();
        let rec = record(PlantParams::default(), &opts).unwrap();
        let period = 1.0 / rec.control_rate_hz as f64;
        assert_eq!(
            rec.outcomes.len(),
            (opts.duration_s / period).round() as usize
        );
        // Boot: relaxed on the negative side, switch released, drive off.
        assert!(
            rec.theta_true_rad[0] < -0.1,
            "relaxed at {}",
            rec.theta_true_rad[0]
        );
        let check = (0.05 / period) as usize;
        for o in &rec.outcomes[..check] {
            assert_eq!(o.record.phase, Phase::Check.code());
            assert!(!o.record.drive_enable, "drive off during the check");
        }
        // Homed on the tick the switch rose: the true angle just crossed zero.
        let homed = rec
            .outcomes
            .iter()
            .position(|o| o.record.phase == Phase::Running.code())
            .expect("homing completes");
        assert!(rec.samples[homed].inputs.origin() && !rec.samples[homed - 1].inputs.origin());
        let origin = rec.outcomes[homed]
            .origin
            .expect("origin record on the edge");
        assert_eq!(origin.raw, rec.samples[homed].raw);
        assert!(
            (0.0..0.01).contains(&rec.theta_true_rad[homed]),
            "homed at {} rad",
            rec.theta_true_rad[homed]
        );
        // The weight was hung while recording.
        let loaded = ((opts.load_at_s + 0.06) / period) as usize;
        assert!((rec.f_ext_true_n[loaded] - opts.load_n).abs() < 1e-9);
        // From the fault line on: latched fault, drive off, zero current.
        let fault_tick = (opts.drive_fault_at_s / period).ceil() as usize;
        assert!(rec.samples[fault_tick].inputs.drive_fault());
        for o in &rec.outcomes[fault_tick..] {
            assert_ne!(o.record.fault, 0);
            assert!(!o.record.drive_enable && o.record.current_ref_a == 0.0);
        }
        // And the fault line is what cut it: no fault before it, the drive
        // on until then, and the line's own fault code on that tick.
        let first_fault = rec
            .outcomes
            .iter()
            .position(|o| o.record.fault != 0)
            .unwrap();
        assert_eq!(first_fault, fault_tick, "the first fault latched elsewhere");
        assert_eq!(
            rec.outcomes[fault_tick].record.fault,
            Fault::DriveFault.code()
        );
        assert!(rec.outcomes[fault_tick - 1].record.drive_enable);
        // The trace round-trips.
        let bytes = rec.trace_bytes();
        let t = cable_joint::board::Trace::parse(&bytes).unwrap();
        assert_eq!(t.iter().collect::<Vec<_>>(), rec.samples);
    }
}
