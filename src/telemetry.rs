//! Raw telemetry records: captured in the control interrupt, sent as bytes,
//! converted to SI units on the host.
//!
//! The firmware's control task fills a [`TickRecord`] every tick (raw counts,
//! the command, two estimates, mode, fault, the measured cycle counts) and
//! pushes every N-th one (the decimation) into a queue; a priority-1 task
//! encodes it with [`Record::encode`] and logs the bytes with defmt as
//!
//! ```text
//! tlm [1, 42, 0, 0, 0, ...]
//! ```
//!
//! (`defmt::info!("tlm {=[u8]}", bytes)`). The host (`host-sim ingest`) finds
//! such lines in the text that `probe-rs run` or `defmt-print` prints, parses
//! them with [`parse_line`] and decodes them with [`Record::decode`]. Floats
//! travel as their IEEE bits, so a decoded record is bit-identical to the one
//! the firmware built.
//!
//! Three record kinds share the stream, told apart by their first byte:
//! [`StartRecord`] (once at boot: format version, control rate, decimation),
//! [`OriginRecord`] (homing set the origin: the raw sample taken as zero) and
//! [`TickRecord`]. All integers are little-endian.

use core::fmt;

use crate::controller::{Mode, RawSample};
use crate::fault::Fault;
use crate::units::{AdcCode, DacCode, GratingCount, MagneticCount, MotorCount};

/// Version of the byte layout (carried by [`StartRecord`]).
pub const FORMAT_VERSION: u8 = 3;

/// Marker that starts a telemetry line in the decoded defmt text.
pub const LINE_MARKER: &str = "tlm ";

/// Longest encoded record, bytes.
pub const MAX_RECORD_LEN: usize = TickRecord::LEN;

/// Digital inputs as read at the tick (bit set = line asserted).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Inputs(pub u8);

impl Inputs {
    /// The photoelectric origin switch sees its flag.
    pub const ORIGIN: u8 = 1 << 0;
    /// The drive reports a fault.
    pub const DRIVE_FAULT: u8 = 1 << 1;

    /// Build from the two lines.
    pub const fn new(origin: bool, drive_fault: bool) -> Self {
        Self(((origin as u8) * Self::ORIGIN) | ((drive_fault as u8) * Self::DRIVE_FAULT))
    }

    /// Origin switch asserted.
    pub const fn origin(self) -> bool {
        self.0 & Self::ORIGIN != 0
    }

    /// Drive fault line asserted.
    pub const fn drive_fault(self) -> bool {
        self.0 & Self::DRIVE_FAULT != 0
    }
}

/// One control tick, raw (what the control interrupt captures).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickRecord {
    /// Tick number since boot (the control task's counter).
    pub tick: u32,
    /// Counters and ADC code exactly as sampled.
    pub raw: RawSample,
    /// Digital inputs as the fault tasks last saw them.
    pub inputs: Inputs,
    /// DAC code written to the drive's current reference.
    pub dac: DacCode,
    /// Current reference, A (the controller's `current_ref_a`).
    pub current_ref_a: f32,
    /// Mean current reference applied over the control periods since the
    /// tick of the previous record sent, A (since format version 3): at a
    /// record every tick, the last tick's `current_ref_a`; at a record
    /// every N ticks, or after records dropped from a full queue, the mean
    /// of the currents the stream does not carry, which a replay holds over
    /// the ticks between rows (the cascade's current changes from tick to
    /// tick, and one sample of N is not its mean).
    pub current_applied_a: f32,
    /// Joint-angle reference, rad.
    pub theta_ref_rad: f32,
    /// Estimated joint angle (JAE), rad.
    pub theta_hat_rad: f32,
    /// Estimated external tip force (DOB), N.
    pub f_ext_hat_n: f32,
    /// Fused tip-force estimate, N (since format version 2).
    pub f_ext_fused_n: f32,
    /// Lower end of the fused estimate's bound, N (version 2).
    pub f_ext_lo_n: f32,
    /// Upper end of the fused estimate's bound, N (version 2).
    pub f_ext_hi_n: f32,
    /// Mode in force ([`Mode::code`]).
    pub mode: u8,
    /// Latched fault ([`Fault::code_of`], 0 = none).
    pub fault: u8,
    /// Drive enable line as written.
    pub drive_enable: bool,
    /// Start-up sequence phase (`board::Phase::code`).
    pub phase: u8,
    /// Whole tick, from task entry to DAC write and drive line: CPU cycles
    /// (DWT) on hardware, guest instructions (TIM2 under `-icount`) in QEMU.
    pub cycles: u32,
    /// The four stages of `Controller::step_timed` (sensing, JAE, DOB,
    /// cascade), same unit as `cycles`, saturated at 65535.
    pub stage_cycles: [u16; 4],
}

/// Firmware start: layout version, control rate and telemetry decimation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StartRecord {
    /// [`FORMAT_VERSION`] of the firmware that wrote the stream.
    pub version: u8,
    /// Control rate, Hz.
    pub control_rate_hz: f32,
    /// One [`TickRecord`] every this many ticks.
    pub decimation: u32,
}

/// Homing set the origin: this raw sample is the new zero of every counter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OriginRecord {
    /// Tick at which the origin was taken.
    pub tick: u32,
    /// The sample taken as zero.
    pub raw: RawSample,
}

/// Any record of the stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Record {
    /// See [`StartRecord`].
    Start(StartRecord),
    /// See [`OriginRecord`].
    Origin(OriginRecord),
    /// See [`TickRecord`].
    Tick(TickRecord),
}

/// Why bytes or a line could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// Empty input.
    Empty,
    /// First byte names no record kind.
    UnknownKind(u8),
    /// Wrong length for the kind.
    Length {
        /// Record kind byte.
        kind: u8,
        /// Bytes expected.
        expected: usize,
        /// Bytes found.
        found: usize,
    },
    /// A start record of another layout version.
    Version(u8),
    /// The byte list after the marker is malformed.
    Syntax,
    /// More bytes than any record has.
    TooLong,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Empty => f.write_str("empty telemetry record"),
            DecodeError::UnknownKind(k) => write!(f, "unknown telemetry record kind {k}"),
            DecodeError::Length {
                kind,
                expected,
                found,
            } => write!(
                f,
                "telemetry record kind {kind} has {found} bytes, expected {expected}"
            ),
            DecodeError::Version(v) => write!(
                f,
                "telemetry format version {v}, this tool reads version {FORMAT_VERSION}"
            ),
            DecodeError::Syntax => f.write_str("malformed byte list after `tlm`"),
            DecodeError::TooLong => f.write_str("telemetry record longer than any kind"),
        }
    }
}

const KIND_START: u8 = 1;
const KIND_ORIGIN: u8 = 2;
const KIND_TICK: u8 = 3;

/// Little-endian writer over a fixed buffer (lengths are fixed per kind).
struct Writer<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) {
        if let Some(dst) = self.buf.get_mut(self.at..self.at + b.len()) {
            dst.copy_from_slice(b);
        }
        self.at += b.len();
    }
    fn u8(&mut self, v: u8) {
        self.bytes(&[v]);
    }
    fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.bytes(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
    fn raw(&mut self, r: &RawSample) {
        self.i32(r.grating1.0);
        self.i32(r.grating2.0);
        self.u16(r.motor.0);
        self.u16(r.magnetic.0);
        self.u16(r.current.0);
    }
}

/// Little-endian reader; callers check the length first.
struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(src) = self.buf.get(self.at..self.at + N) {
            out.copy_from_slice(src);
        }
        self.at += N;
        out
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take())
    }
    fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }
    fn raw(&mut self) -> RawSample {
        RawSample {
            grating1: GratingCount(self.i32()),
            grating2: GratingCount(self.i32()),
            motor: MotorCount(self.u16()),
            magnetic: MagneticCount(self.u16()),
            current: AdcCode(self.u16()),
        }
    }
}

const RAW_LEN: usize = 4 + 4 + 2 + 2 + 2;

impl StartRecord {
    /// Encoded length, bytes.
    pub const LEN: usize = 1 + 1 + 4 + 4;
}

impl OriginRecord {
    /// Encoded length, bytes.
    pub const LEN: usize = 1 + 4 + RAW_LEN;
}

impl TickRecord {
    /// Encoded length, bytes.
    pub const LEN: usize = 1 + 4 + RAW_LEN + 1 + 2 + 8 * 4 + 4 + 4 + 2 * 4;

    /// Mode decoded from [`TickRecord::mode`].
    pub fn mode(&self) -> Option<Mode> {
        Mode::from_code(self.mode)
    }

    /// Fault decoded from [`TickRecord::fault`].
    pub fn fault(&self) -> Option<Fault> {
        Fault::from_code(self.fault)
    }

    /// Sum of the four stage counts (the whole `step_timed`).
    pub fn step_cycles(&self) -> u32 {
        self.stage_cycles.iter().map(|&c| c as u32).sum()
    }
}

impl Record {
    /// Encoded length of this record, bytes.
    pub const fn len(&self) -> usize {
        match self {
            Record::Start(_) => StartRecord::LEN,
            Record::Origin(_) => OriginRecord::LEN,
            Record::Tick(_) => TickRecord::LEN,
        }
    }

    /// Never empty (every kind has a fixed, non-zero length).
    pub const fn is_empty(&self) -> bool {
        false
    }

    /// Encode into `buf`; returns the used prefix.
    pub fn encode<'a>(&self, buf: &'a mut [u8; MAX_RECORD_LEN]) -> &'a [u8] {
        let len = self.len();
        let mut w = Writer {
            buf: &mut buf[..],
            at: 0,
        };
        match self {
            Record::Start(s) => {
                w.u8(KIND_START);
                w.u8(s.version);
                w.f32(s.control_rate_hz);
                w.u32(s.decimation);
            }
            Record::Origin(o) => {
                w.u8(KIND_ORIGIN);
                w.u32(o.tick);
                w.raw(&o.raw);
            }
            Record::Tick(t) => {
                w.u8(KIND_TICK);
                w.u32(t.tick);
                w.raw(&t.raw);
                w.u8(t.inputs.0);
                w.u16(t.dac.0);
                w.f32(t.current_ref_a);
                w.f32(t.current_applied_a);
                w.f32(t.theta_ref_rad);
                w.f32(t.theta_hat_rad);
                w.f32(t.f_ext_hat_n);
                w.f32(t.f_ext_fused_n);
                w.f32(t.f_ext_lo_n);
                w.f32(t.f_ext_hi_n);
                w.u8(t.mode);
                w.u8(t.fault);
                w.u8(t.drive_enable as u8);
                w.u8(t.phase);
                w.u32(t.cycles);
                for c in t.stage_cycles {
                    w.u16(c);
                }
            }
        }
        &buf[..len]
    }

    /// Decode one record.
    pub fn decode(bytes: &[u8]) -> Result<Record, DecodeError> {
        let kind = *bytes.first().ok_or(DecodeError::Empty)?;
        let expected = match kind {
            KIND_START => StartRecord::LEN,
            KIND_ORIGIN => OriginRecord::LEN,
            KIND_TICK => TickRecord::LEN,
            k => return Err(DecodeError::UnknownKind(k)),
        };
        if bytes.len() != expected {
            return Err(DecodeError::Length {
                kind,
                expected,
                found: bytes.len(),
            });
        }
        let mut r = Reader { buf: bytes, at: 1 };
        Ok(match kind {
            KIND_START => {
                let version = r.u8();
                if version != FORMAT_VERSION {
                    return Err(DecodeError::Version(version));
                }
                Record::Start(StartRecord {
                    version,
                    control_rate_hz: r.f32(),
                    decimation: r.u32(),
                })
            }
            KIND_ORIGIN => Record::Origin(OriginRecord {
                tick: r.u32(),
                raw: r.raw(),
            }),
            _ => Record::Tick(TickRecord {
                tick: r.u32(),
                raw: r.raw(),
                inputs: Inputs(r.u8()),
                dac: DacCode(r.u16()),
                current_ref_a: r.f32(),
                current_applied_a: r.f32(),
                theta_ref_rad: r.f32(),
                theta_hat_rad: r.f32(),
                f_ext_hat_n: r.f32(),
                f_ext_fused_n: r.f32(),
                f_ext_lo_n: r.f32(),
                f_ext_hi_n: r.f32(),
                mode: r.u8(),
                fault: r.u8(),
                drive_enable: r.u8() != 0,
                phase: r.u8(),
                cycles: r.u32(),
                stage_cycles: [r.u16(), r.u16(), r.u16(), r.u16()],
            }),
        })
    }
}

/// Find a telemetry record in one line of decoded defmt text.
///
/// Returns `None` for a line without [`LINE_MARKER`] followed by `[`
/// (ordinary log output), otherwise the decoded record or why it failed.
/// Bytes may be decimal or `0x` hexadecimal (defmt's `{=[u8]}` and
/// `{=[u8]:x}`); anything defmt-print puts before the marker (timestamps,
/// level) is skipped.
pub fn parse_line(line: &str) -> Option<Result<Record, DecodeError>> {
    let start = line.find("tlm [")?;
    let rest = &line[start + LINE_MARKER.len() + 1..];
    Some(parse_bytes(rest).and_then(|(buf, n)| Record::decode(&buf[..n])))
}

fn parse_bytes(rest: &str) -> Result<([u8; MAX_RECORD_LEN], usize), DecodeError> {
    let end = rest.find(']').ok_or(DecodeError::Syntax)?;
    let mut buf = [0u8; MAX_RECORD_LEN];
    let mut n = 0;
    for item in rest[..end].split(',') {
        let item = item.trim();
        if item.is_empty() {
            if n == 0 && rest[..end].trim().is_empty() {
                break;
            }
            return Err(DecodeError::Syntax);
        }
        let value = match item.strip_prefix("0x") {
            Some(hex) => u8::from_str_radix(hex, 16),
            None => item.parse::<u8>(),
        }
        .map_err(|_| DecodeError::Syntax)?;
        let slot = buf.get_mut(n).ok_or(DecodeError::TooLong)?;
        *slot = value;
        n += 1;
    }
    Ok((buf, n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::format;
    use std::string::String;

    fn tick() -> TickRecord {
        TickRecord {
            tick: 0xDEAD_BEEF,
            raw: RawSample {
                grating1: GratingCount(-123_456),
                grating2: GratingCount(7_654_321),
                motor: MotorCount(65_535),
                magnetic: MagneticCount(4_095),
                current: AdcCode(2_048),
            },
            inputs: Inputs::new(true, false),
            dac: DacCode(4_095),
            current_ref_a: -1.234_567_8,
            current_applied_a: 0.987_654_3,
            theta_ref_rad: 0.25,
            theta_hat_rad: f32::from_bits(0x0000_0001), // a denormal survives
            f_ext_hat_n: -0.0,
            f_ext_fused_n: 1.5,
            f_ext_lo_n: f32::NEG_INFINITY,
            f_ext_hi_n: 3.25,
            mode: Mode::JointClosedLoop.code(),
            fault: Fault::Overrun.code(),
            drive_enable: true,
            phase: 3,
            cycles: 2_345,
            stage_cycles: [100, 200, 300, 65_535],
        }
    }

    /// What defmt-print prints for `{=[u8]}`: `[1, 2, 3]`.
    fn as_defmt_line(bytes: &[u8], hex: bool) -> String {
        let items: std::vec::Vec<String> = bytes
            .iter()
            .map(|b| {
                if hex {
                    format!("{b:#04x}")
                } else {
                    format!("{b}")
                }
            })
            .collect();
        format!(
            "0.001234 INFO  tlm [{}]\n└─ firmware::app::telemetry @ src/bin/firmware.rs:1",
            items.join(", ")
        )
    }

    #[test]
    fn every_kind_round_trips_bit_for_bit() {
        let records = [
            Record::Start(StartRecord {
                version: FORMAT_VERSION,
                control_rate_hz: 2000.0,
                decimation: 10,
            }),
            Record::Origin(OriginRecord {
                tick: 77,
                raw: tick().raw,
            }),
            Record::Tick(tick()),
        ];
        let mut buf = [0u8; MAX_RECORD_LEN];
        for rec in records {
            let bytes = rec.encode(&mut buf);
            assert_eq!(bytes.len(), rec.len());
            let back = Record::decode(bytes).unwrap();
            assert_eq!(back, rec);
            if let (Record::Tick(a), Record::Tick(b)) = (back, rec) {
                assert_eq!(a.theta_hat_rad.to_bits(), b.theta_hat_rad.to_bits());
                assert_eq!(
                    a.f_ext_hat_n.to_bits(),
                    b.f_ext_hat_n.to_bits(),
                    "-0.0 kept"
                );
            }
            for hex in [false, true] {
                let line = as_defmt_line(bytes, hex);
                let parsed = parse_line(line.lines().next().unwrap()).unwrap().unwrap();
                assert_eq!(parsed, rec, "through the text line (hex {hex})");
            }
        }
    }

    #[test]
    fn tick_record_fields_decode_to_core_types() {
        let t = tick();
        assert_eq!(t.mode(), Some(Mode::JointClosedLoop));
        assert_eq!(t.fault(), Some(Fault::Overrun));
        assert_eq!(t.step_cycles(), 100 + 200 + 300 + 65_535);
        assert!(t.inputs.origin() && !t.inputs.drive_fault());
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        assert_eq!(parse_line("INFO  homed at tick 12"), None);
        assert_eq!(parse_line("tlm [3, 1,"), Some(Err(DecodeError::Syntax)));
        assert_eq!(parse_line("tlm [3, 300]"), Some(Err(DecodeError::Syntax)));
        assert_eq!(parse_line("tlm []"), Some(Err(DecodeError::Empty)));
        assert_eq!(
            parse_line("tlm [9, 1]"),
            Some(Err(DecodeError::UnknownKind(9)))
        );
        assert_eq!(
            parse_line("tlm [3, 1, 2]"),
            Some(Err(DecodeError::Length {
                kind: 3,
                expected: TickRecord::LEN,
                found: 3
            }))
        );
        assert_eq!(
            Record::decode(&[1, 99, 0, 0, 0, 0, 0, 0, 0, 0]),
            Err(DecodeError::Version(99))
        );
        let long = format!("tlm [{}]", ["1"; MAX_RECORD_LEN + 1].join(","));
        assert_eq!(parse_line(&long), Some(Err(DecodeError::TooLong)));
    }
}
