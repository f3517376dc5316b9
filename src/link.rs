//! The host ↔ firmware link's wire format: one versioned, checksummed frame
//! per message, for any byte stream (a serial port, an RTT channel, QEMU's
//! emulated USART).
//!
//! A frame on the wire is `COBS(version, seq, body, crc16) 0x00`:
//!
//! | field | bytes | content |
//! |---|---|---|
//! | version | 1 | [`LINK_VERSION`]; a frame of another version is refused, never guessed at |
//! | seq | 1 | the sender's sequence number, echoed in the answer |
//! | body | n | the message, `postcard` (serde) |
//! | crc16 | 2 | CRC-16/CCITT-FALSE of version, seq and body, little-endian |
//!
//! COBS removes every zero byte from the frame, so a zero byte always ends
//! one and a receiver that joins mid-stream (or after line noise) resyncs at
//! the next zero. Nothing here allocates or panics: encoding writes into the
//! caller's buffer and says when it is too small, and [`FrameReader`]
//! accumulates bytes in a fixed buffer, dropping a frame that outgrows it.
//!
//! What a frame carries is checked twice on the MCU: the frame itself (size,
//! COBS, CRC, version, body) here, and the message's content by
//! [`Down::into_request`], which validates a configuration and prepares its
//! filters (outside the control tick) as [`crate::board::Request`] requires,
//! and checks every other request as [`crate::board::Request::validate`]
//! does. A configuration travels in its binary serde form (effect terms as
//! their slots; see `model.rs`), the same fields as its TOML file.
//!

use core::fmt;

use serde::{Deserialize, Serialize};

use crate::board::{Program, Request, TraceSample};
use crate::config::{Config, ConfigError};
use crate::controller::{Command, PreparedConfig};

/// Version of the wire format. Raise it on any change of the frame layout
/// or of a message's encoding (2: `Trajectory::Grip`; 3: the
/// configuration's `fusion.stiffness_tolerance`; 4: its
/// `cascade.kd_on_observer_rate`, `jae.sign_travel_m` and the Bouc–Wen
/// effect kind; 5: the program's `homing.motor_only`; 6: the
/// configuration's `fusion.pin_identified`; 7: its `stretch.cable0_n_m`;
/// 8: its `cascade.payout_stop`; 9: its `probe.max_amplitude_rad`).
pub const LINK_VERSION: u8 = 9;

/// The host link's baud rate on the prototype's serial port (USART2, 8N1:
/// ten bits a byte on the line).
pub const SERIAL_BAUD: u32 = 460_800;

/// Largest decoded frame, bytes (version, seq, body and CRC): a whole
/// [`Config`] with an added term in each model takes 381 on the wire
/// (measured in a test that keeps it below [`MAX_WIRE_LEN`]).
pub const MAX_FRAME_LEN: usize = 1024;

/// Largest encoded frame on the wire, bytes: COBS adds one byte per 254 and
/// one more, then the delimiter.
pub const MAX_WIRE_LEN: usize = MAX_FRAME_LEN + MAX_FRAME_LEN / 254 + 2;

/// A message from the host to the firmware.
// A configuration is large and there is no allocator to box it; a message
// lives once, in the command task, as `Request` does.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Down {
    /// Run a program: sensor check, homing, then its command.
    Program(Program),
    /// A new mode and trajectory (accepted only once homed).
    SetCommand(Command),
    /// New parameters: validated, and their filters designed, on the MCU
    /// (in its command task) before they reach the control task.
    SetConfig(Config),
    /// Clear the latched fault (refused while its cause persists).
    ClearFault,
    /// One telemetry record every this many ticks (at least 1).
    SetDecimation(u32),
    /// "The host is still there".
    Heartbeat,
}

impl Down {
    /// The firmware's request for this message, checked as the command task
    /// checks every request: a configuration is validated and prepared here
    /// (tens of thousands of instructions; never in the control tick).
    pub fn into_request(self) -> Result<Request, ConfigError> {
        let request = match self {
            Down::Program(p) => Request::Program(p),
            Down::SetCommand(c) => Request::SetCommand(c),
            Down::SetConfig(c) => Request::SetConfig(PreparedConfig::new(c)?),
            Down::ClearFault => Request::ClearFault,
            Down::SetDecimation(n) => Request::SetDecimation(n),
            Down::Heartbeat => Request::Heartbeat,
        };
        request.validate()?;
        Ok(request)
    }
}

/// A message from the firmware to the host.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Up<'a> {
    /// The answer to the host's frame `seq`: accepted, or refused with the
    /// reason.
    Ack {
        /// The host frame's sequence number.
        seq: u8,
        /// Why it was refused (`None`: accepted and queued).
        refused: Option<Refusal>,
    },
    /// One telemetry record in [`crate::telemetry::Record::encode`]'s bytes.
    Telemetry(&'a [u8]),
}

/// Why the firmware refused a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Refusal {
    /// The frame was damaged or not understood ([`LinkError::code`]).
    Frame(u8),
    /// The content failed validation (the field's name is in the
    /// firmware's log).
    Invalid,
    /// The request queue is full: send it again.
    Busy,
}

impl Refusal {
    /// Whether the same frame sent again can be accepted: it arrived
    /// damaged (COBS, too short, CRC: noise on the line), or the queue was
    /// full. A frame too long, of another version or with a body this
    /// firmware does not read, and content that fails validation, are
    /// refused again whatever the line does.
    pub fn worth_resending(self) -> bool {
        match self {
            Refusal::Frame(code) => {
                // (A CRC error's code does not depend on the two CRCs.)
                let crc = LinkError::Crc {
                    found: 0,
                    computed: 0,
                };
                [LinkError::Cobs, LinkError::TooShort, crc]
                    .iter()
                    .any(|e| e.code() == code)
            }
            Refusal::Invalid => false,
            Refusal::Busy => true,
        }
    }
}

/// Why bytes are not a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkError {
    /// The frame is longer than [`MAX_FRAME_LEN`] (or the buffer given).
    TooLong,
    /// COBS decoding failed (a zero inside, or a code past the end).
    Cobs,
    /// Shorter than version, seq and CRC.
    TooShort,
    /// The CRC does not match: the frame was damaged on the way.
    Crc {
        /// CRC in the frame.
        found: u16,
        /// CRC of the frame's bytes.
        computed: u16,
    },
    /// Another wire-format version.
    Version(u8),
    /// The body is not a message of this version.
    Body,
}

impl LinkError {
    /// Stable code, carried in [`Refusal::Frame`].
    pub const fn code(self) -> u8 {
        match self {
            LinkError::TooLong => 1,
            LinkError::Cobs => 2,
            LinkError::TooShort => 3,
            LinkError::Crc { .. } => 4,
            LinkError::Version(_) => 5,
            LinkError::Body => 6,
        }
    }
}

impl fmt::Display for LinkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkError::TooLong => write!(f, "frame longer than {MAX_FRAME_LEN} bytes"),
            LinkError::Cobs => f.write_str("frame is not valid COBS"),
            LinkError::TooShort => f.write_str("frame shorter than its header and CRC"),
            LinkError::Crc { found, computed } => write!(
                f,
                "frame CRC {found:#06x} does not match its bytes ({computed:#06x}): damaged"
            ),
            LinkError::Version(v) => write!(
                f,
                "link version {v}, this build speaks {LINK_VERSION}: update the host or the firmware"
            ),
            LinkError::Body => f.write_str("frame body is not a message of this link version"),
        }
    }
}

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final
/// XOR): `crc16(b"123456789") == 0x29B1`.
pub fn crc16(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in bytes {
        crc ^= u16::from(b) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// COBS-encode `data` into `out` followed by the 0x00 delimiter; the number
/// of bytes written, or `None` if `out` is too small.
pub fn cobs_encode(data: &[u8], out: &mut [u8]) -> Option<usize> {
    let mut code_at = 0;
    let mut w = 1;
    let mut code: u8 = 1;
    for &b in data {
        if b == 0 {
            *out.get_mut(code_at)? = code;
            code_at = w;
            w += 1;
            code = 1;
        } else {
            *out.get_mut(w)? = b;
            w += 1;
            code += 1;
            if code == 0xFF {
                *out.get_mut(code_at)? = code;
                code_at = w;
                w += 1;
                code = 1;
            }
        }
    }
    *out.get_mut(code_at)? = code;
    *out.get_mut(w)? = 0;
    Some(w + 1)
}

/// COBS-decode `buf[..len]` (without its delimiter) in place; the decoded
/// length.
pub fn cobs_decode_in_place(buf: &mut [u8], len: usize) -> Result<usize, LinkError> {
    let data = buf.get_mut(..len).ok_or(LinkError::TooLong)?;
    let (mut r, mut w) = (0, 0);
    while r < data.len() {
        let code = data[r] as usize;
        if code == 0 || r + code > data.len() {
            return Err(LinkError::Cobs);
        }
        r += 1;
        for _ in 1..code {
            let b = data[r];
            if b == 0 {
                return Err(LinkError::Cobs);
            }
            data[w] = b;
            w += 1;
            r += 1;
        }
        if code < 0xFF && r < data.len() {
            data[w] = 0;
            w += 1;
        }
    }
    Ok(w)
}

/// Encode `msg` as frame `seq` into `out` (at least [`MAX_WIRE_LEN`] bytes
/// for any message); the bytes to send, delimiter included.
pub fn encode<'o, M: Serialize>(
    msg: &M,
    seq: u8,
    out: &'o mut [u8],
) -> Result<&'o [u8], LinkError> {
    let mut raw = [0u8; MAX_FRAME_LEN];
    raw[0] = LINK_VERSION;
    raw[1] = seq;
    let body_len = postcard::to_slice(msg, &mut raw[2..MAX_FRAME_LEN - 2])
        .map_err(|_| LinkError::TooLong)?
        .len();
    let end = 2 + body_len;
    let crc = crc16(&raw[..end]);
    raw[end..end + 2].copy_from_slice(&crc.to_le_bytes());
    let n = cobs_encode(&raw[..end + 2], out).ok_or(LinkError::TooLong)?;
    Ok(&out[..n])
}

/// Check and decode one frame's COBS bytes (without the delimiter), in
/// place: its sequence number and message. The message may borrow from
/// `buf` ([`Up::Telemetry`]).
pub fn decode<'b, M: Deserialize<'b>>(buf: &'b mut [u8], len: usize) -> Result<(u8, M), LinkError> {
    let n = cobs_decode_in_place(buf, len)?;
    decode_raw(&buf[..n])
}

/// [`decode`] after the COBS step: check the CRC and the version, then
/// read the body.
fn decode_raw<'b, M: Deserialize<'b>>(frame: &'b [u8]) -> Result<(u8, M), LinkError> {
    let n = frame.len();
    if n < 4 {
        return Err(LinkError::TooShort);
    }
    let (head, crc_bytes) = frame.split_at(n - 2);
    let found = u16::from_le_bytes([crc_bytes[0], crc_bytes[1]]);
    let computed = crc16(head);
    if found != computed {
        return Err(LinkError::Crc { found, computed });
    }
    if head[0] != LINK_VERSION {
        return Err(LinkError::Version(head[0]));
    }
    let msg = postcard::from_bytes(&head[2..]).map_err(|_| LinkError::Body)?;
    Ok((head[1], msg))
}

/// Why an operator frame was refused, with what the firmware logs about it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// The frame itself ([`LinkError`]).
    Frame(LinkError),
    /// The content ([`Down::into_request`]'s error: the field and what it
    /// must be).
    Invalid(ConfigError),
}

impl Refused {
    /// What the acknowledgement carries.
    pub const fn refusal(&self) -> Refusal {
        match self {
            Refused::Frame(e) => Refusal::Frame(e.code()),
            Refused::Invalid(_) => Refusal::Invalid,
        }
    }
}

/// One operator frame, checked as the firmware's link task checks it.
#[derive(Clone, Debug, PartialEq)]
pub struct Received {
    /// The frame's sequence number, for the acknowledgement (0 when the
    /// frame was too damaged to carry one).
    pub seq: u8,
    /// The frame's CRC (0 when the frame was too damaged to carry one):
    /// with `seq`, what tells a resend from a new frame ([`Repeats`]).
    pub crc: u16,
    /// The request to queue, or why not.
    pub outcome: Result<Request, Refused>,
}

/// At-most-once delivery over a line that loses frames.
///
/// The host resends a frame, byte for byte (same sequence number, same
/// CRC), when its acknowledgement does not come back. If the frame was
/// lost, the resend is the first copy the firmware sees; if only the
/// acknowledgement was lost, the firmware has queued the request already
/// and must acknowledge the copy without applying it again (a second
/// `Program` would restart the sequence). The firmware remembers the last
/// request it queued; a frame with the same sequence number and CRC is
/// that request's resend. A refused frame is not remembered, so its resend
/// is judged afresh (a `Busy` request is queued when there is room).
///
/// A host that connects anew starts with a heartbeat (`host-sim link`
/// does): were it taken for a resend of the previous session's last frame
/// (same sequence number and bytes), skipping it changes nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Repeats {
    last: Option<(u8, u16)>,
}

impl Repeats {
    /// Nothing queued yet.
    pub const fn new() -> Self {
        Self { last: None }
    }

    /// Whether `r` is a resend of the last request queued: acknowledge it,
    /// do not queue it again.
    pub fn is_repeat(&self, r: &Received) -> bool {
        r.outcome.is_ok() && self.last == Some((r.seq, r.crc))
    }

    /// The request of the frame `seq` with CRC `crc` was queued.
    pub fn queued(&mut self, seq: u8, crc: u16) {
        self.last = Some((seq, crc));
    }
}

/// Check an operator frame's COBS bytes (in place) down to the request it
/// asks for: frame, version, body, then the content
/// ([`Down::into_request`]). Runs in the firmware's priority-1 link task
/// (a configuration's filters are designed here, never in the tick).
pub fn receive(buf: &mut [u8], len: usize) -> Received {
    let n = match cobs_decode_in_place(buf, len) {
        Ok(n) => n,
        Err(e) => {
            return Received {
                seq: 0,
                crc: 0,
                outcome: Err(Refused::Frame(e)),
            }
        }
    };
    let frame = &buf[..n];
    let seq = frame.get(1).copied().unwrap_or(0);
    let crc = match frame {
        [.., lo, hi] if n >= 4 => u16::from_le_bytes([*lo, *hi]),
        _ => 0,
    };
    let outcome = match decode_raw::<Down>(frame) {
        Err(e) => Err(Refused::Frame(e)),
        Ok((_, down)) => down.into_request().map_err(Refused::Invalid),
    };
    Received { seq, crc, outcome }
}

/// Processor-in-the-loop only: what the board would have read at one tick,
/// sent by the host's simulated plant over the PIL build's sensor bus
/// (QEMU's third serial port). The firmware answers each with the tick's
/// telemetry record ([`Up::Telemetry`]), which carries the DAC code and
/// the drive enable line the plant needs for the next period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SensorFrame {
    /// The host's tick number (the firmware's own count is in the answer).
    pub tick: u32,
    /// Counters, ADC code and input lines.
    pub sample: TraceSample,
}

/// Collects a byte stream into frames: push bytes as they arrive; at each
/// delimiter the frame's COBS bytes are ready for [`decode`]. A frame that
/// outgrows the buffer is dropped up to its delimiter and reported once.
pub struct FrameReader<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflowed: bool,
}

impl<const N: usize> Default for FrameReader<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// What one byte completed.
#[derive(Debug, PartialEq, Eq)]
pub enum Pushed {
    /// Nothing yet.
    Pending,
    /// A frame of this many COBS bytes is in [`FrameReader::frame`].
    Frame(usize),
    /// A frame longer than the buffer ended here and was dropped.
    Dropped,
}

impl<const N: usize> FrameReader<N> {
    /// An empty reader.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            overflowed: false,
        }
    }

    /// One received byte.
    pub fn push(&mut self, byte: u8) -> Pushed {
        if byte == 0 {
            let len = core::mem::take(&mut self.len);
            if core::mem::take(&mut self.overflowed) {
                return Pushed::Dropped;
            }
            return if len == 0 {
                Pushed::Pending
            } else {
                Pushed::Frame(len)
            };
        }
        if self.overflowed {
            return Pushed::Pending;
        }
        match self.buf.get_mut(self.len) {
            Some(slot) => {
                *slot = byte;
                self.len += 1;
            }
            None => {
                self.overflowed = true;
                self.len = 0;
            }
        }
        Pushed::Pending
    }

    /// The buffer holding the frame a [`Pushed::Frame`] announced (decode
    /// it before pushing the next byte).
    pub fn frame(&mut self) -> &mut [u8] {
        &mut self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::Mode;
    use crate::trajectory::Trajectory;
    use std::vec::Vec;

    fn wire<M: Serialize>(msg: &M, seq: u8) -> Vec<u8> {
        let mut out = [0u8; MAX_WIRE_LEN];
        encode(msg, seq, &mut out).unwrap().to_vec()
    }

    /// Feed bytes to a reader and decode every frame.
    fn read_all(bytes: &[u8]) -> Vec<Result<(u8, Down), LinkError>> {
        let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
        let mut got = Vec::new();
        for &b in bytes {
            match reader.push(b) {
                Pushed::Pending => {}
                Pushed::Dropped => got.push(Err(LinkError::TooLong)),
                Pushed::Frame(n) => got.push(decode(reader.frame(), n)),
            }
        }
        got
    }

    /// A frame's COBS bytes as a reader hands them over (no delimiter).
    fn received(frame: &[u8]) -> Received {
        let mut buf = frame.to_vec();
        let n = buf.len() - 1;
        receive(&mut buf, n)
    }

    /// Only noise on the line and a full queue are worth a resend.
    #[test]
    fn only_damage_and_a_full_queue_are_worth_resending() {
        let crc = LinkError::Crc {
            found: 1,
            computed: 2,
        };
        for e in [LinkError::Cobs, LinkError::TooShort, crc] {
            assert!(Refused::Frame(e).refusal().worth_resending(), "{e:?}");
        }
        for e in [LinkError::TooLong, LinkError::Version(2), LinkError::Body] {
            assert!(!Refused::Frame(e).refusal().worth_resending(), "{e:?}");
        }
        assert!(Refusal::Busy.worth_resending());
        assert!(!Refusal::Invalid.worth_resending());
    }

    /// A resend (same sequence number, same bytes) of the request last
    /// queued is recognised; a new frame with the same sequence number, a
    /// refused frame's resend and a resend after another request are not.
    #[test]
    fn repeats_recognise_only_a_resend_of_the_request_last_queued() {
        let mut repeats = Repeats::new();
        let program = wire(&Down::ClearFault, 3);
        let first = received(&program);
        assert!(!repeats.is_repeat(&first));
        repeats.queued(first.seq, first.crc);
        // Its acknowledgement was lost: the host sends the same bytes.
        assert!(repeats.is_repeat(&received(&program)));
        // Same sequence number, other content (a new session's frame).
        assert!(!repeats.is_repeat(&received(&wire(&Down::Heartbeat, 3))));
        // A refused frame is never a repeat, even with a remembered seq.
        let zero = wire(&Down::SetDecimation(0), 4);
        assert!(!repeats.is_repeat(&received(&zero)));
        // After the next request is queued, the old frame is new again.
        let next = received(&wire(&Down::SetDecimation(5), 4));
        repeats.queued(next.seq, next.crc);
        assert!(!repeats.is_repeat(&received(&program)));
        assert!(repeats.is_repeat(&next));
    }

    #[test]
    fn receive_queues_valid_requests_and_names_what_it_refuses() {
        let ok = received(&wire(&Down::ClearFault, 7));
        assert_eq!((ok.seq, ok.outcome), (7, Ok(Request::ClearFault)));
        // The content: a decimation of zero, a configuration out of range.
        let zero = received(&wire(&Down::SetDecimation(0), 8));
        match zero.outcome {
            Err(Refused::Invalid(e)) => assert_eq!(e.field, "telemetry.decimation"),
            other => panic!("{other:?}"),
        }
        assert_eq!(
            (
                zero.seq,
                Refused::Invalid(ConfigError {
                    field: "",
                    expected: ""
                })
                .refusal()
            ),
            (8, Refusal::Invalid)
        );
        let bad_rate = Config {
            control_rate_hz: 0.0,
            ..Config::default()
        };
        match received(&wire(&Down::SetConfig(bad_rate), 9)).outcome {
            Err(Refused::Invalid(e)) => assert_eq!(e.field, "control_rate_hz"),
            other => panic!("{other:?}"),
        }
        // The frame: one body bit flipped on the way is a CRC error, acked
        // with the frame's own sequence number.
        let mut damaged = wire(&Down::SetDecimation(5), 10);
        damaged[3] ^= 0x40;
        let r = received(&damaged);
        assert_eq!(r.seq, 10);
        match r.outcome {
            Err(Refused::Frame(e @ LinkError::Crc { .. })) => {
                assert_eq!(Refused::Frame(e).refusal(), Refusal::Frame(4))
            }
            other => panic!("{other:?}"),
        }
        // Another version, and bytes that are not COBS at all.
        let mut v2 = [0u8; MAX_WIRE_LEN];
        let other = LINK_VERSION + 1;
        let mut raw = std::vec![other, 11, 4, 0, 0];
        let crc = crc16(&raw[..3]);
        raw[3..].copy_from_slice(&crc.to_le_bytes());
        let n = cobs_encode(&raw, &mut v2).unwrap();
        let r = received(&v2[..n]);
        assert_eq!(
            (r.seq, r.outcome),
            (11, Err(Refused::Frame(LinkError::Version(other))))
        );
        let r = received(&[5, 1, 0]);
        assert_eq!(
            (r.seq, r.outcome),
            (0, Err(Refused::Frame(LinkError::Cobs)))
        );
    }

    #[test]
    fn sensor_frames_round_trip() {
        let frame = SensorFrame {
            tick: 123_456,
            sample: TraceSample {
                raw: crate::controller::RawSample {
                    grating1: crate::units::GratingCount(-5),
                    grating2: crate::units::GratingCount(70_000),
                    motor: crate::units::MotorCount(65_535),
                    magnetic: crate::units::MagneticCount(12),
                    current: crate::units::AdcCode(2047),
                },
                inputs: crate::telemetry::Inputs(3),
            },
        };
        let mut w = wire(&frame, 3);
        let n = w.len() - 1;
        assert_eq!(decode::<SensorFrame>(&mut w, n).unwrap(), (3, frame));
    }

    #[test]
    fn crc16_is_ccitt_false() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
    }

    #[test]
    fn cobs_round_trips_zeros_and_long_runs() {
        let cases: [&[u8]; 5] = [&[], &[0], &[0, 0], &[1, 2, 0, 3], &[7; 600]];
        for data in cases {
            let mut out = [0u8; 700];
            let n = cobs_encode(data, &mut out).unwrap();
            assert!(!out[..n - 1].contains(&0), "no zero before the delimiter");
            assert_eq!(out[n - 1], 0);
            let m = cobs_decode_in_place(&mut out, n - 1).unwrap();
            assert_eq!(&out[..m], data);
        }
        let mut small = [0u8; 3];
        assert_eq!(cobs_encode(&[1, 2, 3], &mut small), None, "too small");
    }

    #[test]
    fn every_message_round_trips_through_the_stream() {
        let msgs = [
            Down::Program(Program::default()),
            Down::SetCommand(Command {
                mode: Mode::JointClosedLoop,
                trajectory: Trajectory::Sine {
                    offset_rad: 0.1,
                    amplitude_rad: 0.5,
                    freq_hz: 0.3,
                },
            }),
            Down::SetConfig(Config::default()),
            Down::SetConfig(with_terms()),
            Down::ClearFault,
            Down::SetDecimation(10),
            Down::Heartbeat,
        ];
        let mut stream = Vec::new();
        for (seq, m) in msgs.iter().enumerate() {
            stream.extend(wire(m, seq as u8));
        }
        let got = read_all(&stream);
        assert_eq!(got.len(), msgs.len());
        for (seq, (g, m)) in got.into_iter().zip(&msgs).enumerate() {
            assert_eq!(g, Ok((seq as u8, m.clone())));
        }
        let config_len = wire(&Down::SetConfig(with_terms()), 0).len();
        assert!(config_len < MAX_WIRE_LEN, "{config_len} bytes");
    }

    #[test]
    fn a_damaged_frame_is_refused_and_the_next_one_reads() {
        let good = wire(&Down::Heartbeat, 7);
        for i in 0..good.len() - 1 {
            for bit in 0..8 {
                let mut bad = good.clone();
                bad[i] ^= 1 << bit;
                bad.extend(&good);
                let got = read_all(&bad);
                // The damaged frame is refused (or, if the flip made a zero,
                // split into pieces that are all refused); the good one reads.
                assert_eq!(
                    got.last(),
                    Some(&Ok((7, Down::Heartbeat))),
                    "byte {i} bit {bit}"
                );
                assert!(
                    got[..got.len() - 1].iter().all(|g| g.is_err()),
                    "byte {i} bit {bit}: {got:?}"
                );
            }
        }
    }

    #[test]
    fn another_version_and_a_foreign_body_are_named() {
        let other = LINK_VERSION + 1;
        let mut raw = [other, 0, 0, 0, 0];
        let crc = crc16(&raw[..3]);
        raw[3..].copy_from_slice(&crc.to_le_bytes());
        let mut out = [0u8; 16];
        let n = cobs_encode(&raw, &mut out).unwrap();
        assert_eq!(read_all(&out[..n]), [Err(LinkError::Version(other))]);
        let mut raw = [LINK_VERSION, 0, 200, 0, 0];
        let crc = crc16(&raw[..3]);
        raw[3..].copy_from_slice(&crc.to_le_bytes());
        let n = cobs_encode(&raw, &mut out).unwrap();
        assert_eq!(read_all(&out[..n]), [Err(LinkError::Body)], "variant 200");
    }

    #[test]
    fn an_oversized_frame_is_dropped_once_and_the_stream_resyncs() {
        let mut stream = std::vec![1u8; MAX_WIRE_LEN + 10];
        stream.push(0);
        stream.extend(wire(&Down::ClearFault, 3));
        assert_eq!(
            read_all(&stream),
            [Err(LinkError::TooLong), Ok((3, Down::ClearFault))]
        );
    }

    /// The default configuration with two effect terms on each model.
    fn with_terms() -> Config {
        use crate::effects::{EffectKind, Term};
        let mut c = Config::default();
        for added in [&mut c.jae.added, &mut c.tension.added] {
            let creep = EffectKind::Creep { tau_s: 0.5 };
            assert!(added.push(
                Term {
                    kind: creep,
                    input: 1,
                    aux: 0
                },
                0.25
            ));
            assert!(added.push(
                Term {
                    kind: EffectKind::Constant,
                    input: 0,
                    aux: 0
                },
                -1.5
            ));
        }
        c
    }

    #[test]
    fn a_configuration_is_validated_and_prepared_on_the_way_in() {
        let ok = Down::SetConfig(with_terms()).into_request();
        assert!(matches!(ok, Ok(Request::SetConfig(_))));
        let mut bad = Config::default();
        bad.dob.cutoff_rad_s = -1.0;
        let err = Down::SetConfig(bad).into_request().unwrap_err();
        assert_eq!(err.field, "dob.cutoff_rad_s");
    }

    #[test]
    fn a_message_is_validated_as_a_request_on_the_way_in() {
        let ok = Down::SetDecimation(5).into_request();
        assert_eq!(ok, Ok(Request::SetDecimation(5)));
        let nan = Down::SetCommand(Command {
            mode: Mode::JointClosedLoop,
            trajectory: Trajectory::Hold {
                angle_rad: f32::NAN,
            },
        });
        assert!(nan.into_request().is_err(), "a NaN reference is refused");
        assert_eq!(
            Down::SetDecimation(0).into_request().unwrap_err().field,
            "telemetry.decimation"
        );
    }

    #[test]
    fn telemetry_goes_up_borrowed() {
        let record = [5u8, 0, 1, 2];
        let mut out = [0u8; 64];
        let bytes = encode(&Up::Telemetry(&record), 9, &mut out)
            .unwrap()
            .to_vec();
        let mut buf = bytes.clone();
        let (seq, up): (u8, Up) = decode(&mut buf, bytes.len() - 1).unwrap();
        assert_eq!((seq, up), (9, Up::Telemetry(&record)));
        let ack = Up::Ack {
            seq: 4,
            refused: Some(Refusal::Frame(
                LinkError::Crc {
                    found: 0,
                    computed: 1,
                }
                .code(),
            )),
        };
        let bytes = encode(&ack, 0, &mut out).unwrap().to_vec();
        let mut buf = bytes.clone();
        let (_, up): (u8, Up) = decode(&mut buf, bytes.len() - 1).unwrap();
        assert_eq!(up, ack);
    }
}
