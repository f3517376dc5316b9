//! Recorded sensor traces: what the QEMU firmware replays instead of reading
//! encoder timers and the ADC (QEMU models neither), and what the host replay
//! test feeds through the same [`ControlLoop`].
//!
//! A trace is a closed-loop run recorded on the host (`host-sim trace`): per
//! control tick the raw counters, the ADC code and the two digital inputs the
//! firmware would have read. Layout (little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 0..4 | magic `CJTR` |
//! | 4 | layout version (1) |
//! | 5..8 | flags, 24 bits little-endian: bit 0 ([`TRACE_FLAG_PROBING`]) the run had probing on; every other bit zero |
//! | 8..12 | control rate, Hz (`f32`) |
//! | 12..16 | number of samples `n` (`u32`) |
//! | 16.. | `n` samples of 17 bytes: grating 1 `i32`, grating 2 `i32`, motor `u16`, magnetic `u16`, ADC `u16`, inputs `u8` ([`Inputs`]) |

use core::convert::Infallible;
use core::fmt;

use embedded_hal::digital::{ErrorType, InputPin, OutputPin};

use crate::controller::RawSample;
use crate::telemetry::Inputs;
use crate::units::{AdcCode, DacCode, GratingCount, MagneticCount, MotorCount};

use super::control::{ControlLoop, Request, TickOutcome};
use super::io::{
    on_drive_fault_edge, on_origin_edge, DriveEnable, DriveKill, Events, InputLine, SensorFrontEnd,
};
use super::timing::NoCycles;

/// Magic bytes at the start of a trace.
pub const TRACE_MAGIC: [u8; 4] = *b"CJTR";
/// Layout version.
pub const TRACE_VERSION: u8 = 1;
/// Header length, bytes.
pub const TRACE_HEADER_LEN: usize = 16;
/// Bytes per sample.
pub const TRACE_SAMPLE_LEN: usize = 17;
/// Header flag: the trace was recorded with probing on (`probe.enabled`),
/// and the firmware replaying it must run with the same configuration.
pub const TRACE_FLAG_PROBING: u8 = 1;

/// What the board reads at one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TraceSample {
    /// Counters and ADC code.
    pub raw: RawSample,
    /// Origin switch and drive fault line (asserted = bit set).
    pub inputs: Inputs,
}

impl TraceSample {
    /// Encode one sample.
    pub fn to_bytes(&self) -> [u8; TRACE_SAMPLE_LEN] {
        let mut b = [0u8; TRACE_SAMPLE_LEN];
        b[0..4].copy_from_slice(&self.raw.grating1.0.to_le_bytes());
        b[4..8].copy_from_slice(&self.raw.grating2.0.to_le_bytes());
        b[8..10].copy_from_slice(&self.raw.motor.0.to_le_bytes());
        b[10..12].copy_from_slice(&self.raw.magnetic.0.to_le_bytes());
        b[12..14].copy_from_slice(&self.raw.current.0.to_le_bytes());
        b[14] = self.inputs.0;
        b
    }

    /// Decode one sample.
    pub fn from_bytes(b: &[u8; TRACE_SAMPLE_LEN]) -> Self {
        let i32_at = |i: usize| i32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
        Self {
            raw: RawSample {
                grating1: GratingCount(i32_at(0)),
                grating2: GratingCount(i32_at(4)),
                motor: MotorCount(u16_at(8)),
                magnetic: MagneticCount(u16_at(10)),
                current: AdcCode(u16_at(12)),
            },
            inputs: Inputs(b[14]),
        }
    }
}

/// Header of a trace with `count` samples at `control_rate_hz`, recorded
/// with `flags` ([`TRACE_FLAG_PROBING`] or 0).
pub fn trace_header(control_rate_hz: f32, count: u32, flags: u8) -> [u8; TRACE_HEADER_LEN] {
    let mut h = [0u8; TRACE_HEADER_LEN];
    h[0..4].copy_from_slice(&TRACE_MAGIC);
    h[4] = TRACE_VERSION;
    h[5] = flags;
    h[8..12].copy_from_slice(&control_rate_hz.to_bits().to_le_bytes());
    h[12..16].copy_from_slice(&count.to_le_bytes());
    h
}

/// Why bytes are not a trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceError {
    /// Shorter than the header, or no `CJTR` magic.
    NotATrace,
    /// Another layout version.
    Version(u8),
    /// Header flag bits this firmware does not know (a newer recorder).
    Flags(u32),
    /// The length disagrees with the sample count in the header.
    Length {
        /// Bytes the header implies.
        expected: usize,
        /// Bytes present.
        found: usize,
    },
}

impl fmt::Display for TraceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TraceError::NotATrace => f.write_str("not a sensor trace (no CJTR header)"),
            TraceError::Version(v) => {
                write!(f, "trace layout version {v}, expected {TRACE_VERSION}")
            }
            TraceError::Flags(b) => write!(
                f,
                "trace header flag bits {b:#08x} unknown: only {TRACE_FLAG_PROBING:#04x} (probing) is known"
            ),
            TraceError::Length { expected, found } => write!(
                f,
                "trace has {found} bytes, its header announces {expected}"
            ),
        }
    }
}

/// A parsed trace over borrowed bytes (`include_bytes!` on the target).
#[derive(Clone, Copy, Debug)]
pub struct Trace<'a> {
    samples: &'a [u8],
    control_rate_hz: f32,
    count: usize,
    flags: u8,
}

impl<'a> Trace<'a> {
    /// Check the header and the length.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, TraceError> {
        let header = bytes.get(..TRACE_HEADER_LEN).ok_or(TraceError::NotATrace)?;
        if header[0..4] != TRACE_MAGIC {
            return Err(TraceError::NotATrace);
        }
        if header[4] != TRACE_VERSION {
            return Err(TraceError::Version(header[4]));
        }
        let flags = u32::from_le_bytes([header[5], header[6], header[7], 0]);
        let unknown = flags & !u32::from(TRACE_FLAG_PROBING);
        if unknown != 0 {
            return Err(TraceError::Flags(unknown));
        }
        let rate = f32::from_bits(u32::from_le_bytes([
            header[8], header[9], header[10], header[11],
        ]));
        let count = u32::from_le_bytes([header[12], header[13], header[14], header[15]]) as usize;
        // Saturating: on a 32-bit target a forged count would wrap the product
        // and could make a short buffer look the right length.
        let expected = count
            .saturating_mul(TRACE_SAMPLE_LEN)
            .saturating_add(TRACE_HEADER_LEN);
        if bytes.len() != expected {
            return Err(TraceError::Length {
                expected,
                found: bytes.len(),
            });
        }
        Ok(Self {
            samples: &bytes[TRACE_HEADER_LEN..],
            control_rate_hz: rate,
            count,
            // Only bit 0 is left (checked above).
            flags: header[5],
        })
    }

    /// Number of samples (ticks).
    pub fn len(&self) -> usize {
        self.count
    }

    /// No samples at all.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Control rate the trace was recorded at, Hz.
    pub fn control_rate_hz(&self) -> f32 {
        self.control_rate_hz
    }

    /// The trace was recorded with probing on.
    pub fn probing(&self) -> bool {
        self.flags & TRACE_FLAG_PROBING != 0
    }

    /// The configuration the trace was recorded with, which its replay must
    /// use: the firmware's ([`super::firmware_config`]), with probing on if
    /// the header says so.
    pub fn config(&self) -> crate::Config {
        super::firmware_config_probing(self.probing())
    }

    /// Sample `k`.
    pub fn get(&self, k: usize) -> Option<TraceSample> {
        let start = k.checked_mul(TRACE_SAMPLE_LEN)?;
        let bytes: &[u8; TRACE_SAMPLE_LEN] = self
            .samples
            .get(start..start + TRACE_SAMPLE_LEN)?
            .try_into()
            .ok()?;
        Some(TraceSample::from_bytes(bytes))
    }

    /// All samples in order.
    pub fn iter(&self) -> impl Iterator<Item = TraceSample> + 'a {
        let t = *self;
        (0..t.count).filter_map(move |k| t.get(k))
    }
}

/// A [`SensorFrontEnd`] that plays a trace back, one sample per tick (the
/// QEMU board). `on_inputs(previous, now)` is called from `sample` when the
/// replayed digital inputs change, so the board can raise the EXTI
/// interrupts the real lines would.
pub struct ReplayFrontEnd<'a, S> {
    trace: Trace<'a>,
    next: usize,
    prev: Inputs,
    on_inputs: S,
    last_dac: Option<DacCode>,
}

impl<'a, S: FnMut(Inputs, Inputs)> ReplayFrontEnd<'a, S> {
    /// Start at the first sample; all inputs released.
    pub fn new(trace: Trace<'a>, on_inputs: S) -> Self {
        Self {
            trace,
            next: 0,
            prev: Inputs::default(),
            on_inputs,
            last_dac: None,
        }
    }

    /// Every sample has been played (further samples repeat the last one).
    pub fn finished(&self) -> bool {
        self.next >= self.trace.len()
    }

    /// Samples played so far.
    pub fn position(&self) -> usize {
        self.next
    }

    /// Last DAC code written.
    pub fn last_dac(&self) -> Option<DacCode> {
        self.last_dac
    }
}

impl<S: FnMut(Inputs, Inputs)> SensorFrontEnd for ReplayFrontEnd<'_, S> {
    fn sample(&mut self) -> RawSample {
        let k = self.next.min(self.trace.len().saturating_sub(1));
        let s = self.trace.get(k).unwrap_or_default();
        self.next = self.next.saturating_add(1);
        if s.inputs != self.prev {
            (self.on_inputs)(self.prev, s.inputs);
            self.prev = s.inputs;
        }
        s.raw
    }

    fn write_current(&mut self, dac: DacCode) {
        self.last_dac = Some(dac);
    }

    fn drive_fault_asserted(&mut self) -> bool {
        // The levels of the sample just played.
        self.prev.drive_fault()
    }
}

/// An input pin whose level the [`Harness`] sets.
#[derive(Clone, Copy, Debug, Default)]
pub struct LevelPin(pub bool);

impl ErrorType for LevelPin {
    type Error = Infallible;
}

impl InputPin for LevelPin {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.0)
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0)
    }
}

/// An output pin that remembers its level.
#[derive(Clone, Copy, Debug, Default)]
pub struct LevelOut(pub bool);

impl ErrorType for LevelOut {
    type Error = Infallible;
}

impl OutputPin for LevelOut {
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.0 = true;
        Ok(())
    }
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.0 = false;
        Ok(())
    }
}

/// Counts drive kills by the fault handlers.
#[derive(Clone, Copy, Debug, Default)]
pub struct KillCount(pub u32);

impl DriveKill for KillCount {
    fn kill(&mut self) {
        self.0 += 1;
    }
}

/// One tick's sensors and the DAC code written back.
struct OneShot {
    raw: RawSample,
    dac: Option<DacCode>,
    drive_fault: bool,
}

impl SensorFrontEnd for OneShot {
    fn sample(&mut self) -> RawSample {
        self.raw
    }
    fn write_current(&mut self, dac: DacCode) {
        self.dac = Some(dac);
    }
    fn drive_fault_asserted(&mut self) -> bool {
        self.drive_fault
    }
}

/// The firmware's tasks run single-threaded in the firmware's order: for each
/// sample, the EXTI tasks of the inputs that changed (drive fault before
/// origin: lower interrupt number at equal priority), then the control tick.
/// The trace generator closes the loop through it; the replay test compares
/// its output with the QEMU firmware's.
pub struct Harness {
    /// The control task's state.
    pub control: ControlLoop,
    /// Shared with the fault "tasks".
    pub events: Events,
    drive: DriveEnable<LevelOut>,
    origin: InputLine<LevelPin>,
    drive_fault: InputLine<LevelPin>,
    kills: KillCount,
    prev: Inputs,
}

impl Harness {
    /// Wrap a control loop; inputs released, drive disabled.
    pub fn new(control: ControlLoop) -> Self {
        Self {
            control,
            events: Events::new(),
            drive: DriveEnable::new(LevelOut::default()),
            origin: InputLine::new(LevelPin(false), false),
            drive_fault: InputLine::new(LevelPin(false), false),
            kills: KillCount::default(),
            prev: Inputs::default(),
        }
    }

    /// Drive kills by the fault handlers so far.
    pub fn kills(&self) -> u32 {
        self.kills.0
    }

    /// Level of the drive enable line.
    pub fn drive_enabled(&self) -> bool {
        self.drive.is_enabled()
    }

    /// The control task overran its deadline (the firmware's check after a
    /// tick): latch [`crate::Fault::Overrun`] and cut the drive.
    pub fn overrun(&mut self) {
        self.control.overrun(&mut self.drive);
    }

    /// One tick on `sample`, with an optional operator request; a record
    /// due is sent (a replay's queue never fills).
    pub fn tick(&mut self, sample: &TraceSample, request: Option<Request>) -> TickOutcome {
        self.tick_queued(sample, request, true)
    }

    /// [`Harness::tick`], where a record due finds room in the firmware's
    /// telemetry queue only if `room` (else it is dropped, as from a full
    /// queue, and the next record sent covers its ticks).
    pub fn tick_queued(
        &mut self,
        sample: &TraceSample,
        request: Option<Request>,
        room: bool,
    ) -> TickOutcome {
        let now = sample.inputs;
        if now.drive_fault() != self.prev.drive_fault() {
            self.drive_fault.pin_mut().0 = now.drive_fault();
            on_drive_fault_edge(&mut self.drive_fault, &mut self.kills, &self.events);
        }
        if now.origin() != self.prev.origin() {
            self.origin.pin_mut().0 = now.origin();
            on_origin_edge(&mut self.origin, &mut self.kills, &self.events);
        }
        self.prev = now;
        let mut fe = OneShot {
            raw: sample.raw,
            dac: None,
            drive_fault: now.drive_fault(),
        };
        let outcome = self.control.tick(
            &mut fe,
            &mut self.drive,
            &self.events,
            request,
            &mut NoCycles,
        );
        if outcome.telemetry_due && room {
            self.control.record_queued();
        }
        outcome
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::Program;
    use crate::Config;
    use std::vec::Vec;

    fn sample(k: i32, inputs: u8) -> TraceSample {
        TraceSample {
            raw: RawSample {
                grating1: GratingCount(-k),
                grating2: GratingCount(k * 1000),
                motor: MotorCount((k as u16).wrapping_mul(700)),
                magnetic: MagneticCount(k as u16),
                current: AdcCode(2048 + k as u16),
            },
            inputs: Inputs(inputs),
        }
    }

    fn trace_bytes(samples: &[TraceSample]) -> Vec<u8> {
        let mut v = Vec::from(trace_header(2000.0, samples.len() as u32, 0));
        for s in samples {
            v.extend_from_slice(&s.to_bytes());
        }
        v
    }

    #[test]
    fn trace_round_trips_and_rejects_bad_bytes() {
        let samples: Vec<_> = (0..5).map(|k| sample(k, (k % 4) as u8)).collect();
        let bytes = trace_bytes(&samples);
        let t = Trace::parse(&bytes).unwrap();
        assert_eq!((t.len(), t.control_rate_hz()), (5, 2000.0));
        assert_eq!(t.iter().collect::<Vec<_>>(), samples);
        assert_eq!(t.get(5), None);
        assert_eq!(
            Trace::parse(&bytes[..bytes.len() - 1]).unwrap_err(),
            TraceError::Length {
                expected: bytes.len(),
                found: bytes.len() - 1
            }
        );
        assert_eq!(Trace::parse(b"nope").unwrap_err(), TraceError::NotATrace);
        let mut v2 = bytes.clone();
        v2[4] = 9;
        assert_eq!(Trace::parse(&v2).unwrap_err(), TraceError::Version(9));
        let mut probed = bytes.clone();
        probed[5] = TRACE_FLAG_PROBING;
        let t = Trace::parse(&probed).unwrap();
        assert!(t.probing() && t.config().probe.enabled);
        assert!(!Trace::parse(&bytes).unwrap().config().probe.enabled);
        for (at, byte) in [(5, 0x02), (6, 0x01), (7, 0x80)] {
            let mut unknown = bytes.clone();
            unknown[at] = byte;
            let bit = u32::from(byte) << (8 * (at - 5));
            assert_eq!(
                Trace::parse(&unknown).unwrap_err(),
                TraceError::Flags(bit),
                "byte {at} = {byte:#04x}"
            );
        }
    }

    #[test]
    fn a_forged_sample_count_is_a_length_error_not_a_wrapped_one() {
        let mut v = Vec::from(trace_header(2000.0, u32::MAX, 0));
        v.extend_from_slice(&sample(0, 0).to_bytes());
        let expected = (u32::MAX as usize)
            .saturating_mul(TRACE_SAMPLE_LEN)
            .saturating_add(TRACE_HEADER_LEN);
        assert_eq!(
            Trace::parse(&v).unwrap_err(),
            TraceError::Length {
                expected,
                found: v.len()
            }
        );
    }

    #[test]
    fn replay_reports_input_changes_and_holds_the_last_sample() {
        let samples = [
            sample(0, 0),
            sample(1, Inputs::ORIGIN),
            sample(2, Inputs::ORIGIN),
        ];
        let bytes = trace_bytes(&samples);
        let mut changes = Vec::new();
        let mut fe =
            ReplayFrontEnd::new(Trace::parse(&bytes).unwrap(), |a, b| changes.push((a, b)));
        assert_eq!(fe.sample(), samples[0].raw);
        assert_eq!(fe.sample(), samples[1].raw);
        assert_eq!(fe.sample(), samples[2].raw);
        assert!(fe.finished());
        assert_eq!(fe.sample(), samples[2].raw, "held");
        fe.write_current(DacCode(7));
        assert_eq!(fe.last_dac(), Some(DacCode(7)));
        assert_eq!(changes, [(Inputs(0), Inputs(Inputs::ORIGIN))]);
    }

    #[test]
    fn harness_homes_on_the_replayed_origin_edge() {
        let cl = ControlLoop::new(Config::default(), 1).unwrap();
        let mut h = Harness::new(cl);
        let rest = TraceSample {
            raw: RawSample {
                current: AdcCode(2048),
                ..Default::default()
            },
            inputs: Inputs(0),
        };
        let mut origins = Vec::new();
        // The drive follows its reference: the monitor reads the last DAC
        // code back (same scales by default).
        let mut dac = 2048;
        for k in 0..400u32 {
            let mut s = rest;
            s.raw.current = AdcCode(dac);
            if k >= 300 {
                s.inputs = Inputs(Inputs::ORIGIN);
            }
            let req = (k == 0).then_some(Request::Program(Program::default()));
            let o = h.tick(&s, req);
            dac = o.record.dac.0;
            if let Some(o) = o.origin {
                origins.push(o.tick);
            }
        }
        assert_eq!(origins, [100, 300], "end of the check, then the edge");
        assert_eq!(h.kills(), 0);
        assert!(h.drive_enabled(), "running the program");
        // A drive fault edge cuts and latches.
        let mut s = rest;
        s.raw.current = AdcCode(dac);
        s.inputs = Inputs(Inputs::ORIGIN | Inputs::DRIVE_FAULT);
        let o = h.tick(&s, None);
        assert_eq!(h.kills(), 1);
        assert_eq!(o.output.fault, Some(crate::Fault::DriveFault));
        assert!(!h.drive_enabled());
    }
}
