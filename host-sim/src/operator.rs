//! The host's end of the firmware link (`cable_joint::link`): connect to a
//! port, send a request and wait for its acknowledgement, collect the
//! telemetry the firmware streams meanwhile.
//!
//! A port is `tcp:HOST:PORT` (QEMU's serial port as a socket, `host-sim
//! pil --link-port`; on the prototype, OpenOCD's RTT server for channel 1),
//! `rtt:HOST:PORT` (RTT channel 1 through QEMU's GDB stub, `host-sim pil
//! --gdb-port`; [`crate::gdb_rtt`]) or a serial device (`/dev/ttyACM0`: the
//! prototype's USART2 through a USB–serial adapter; set to 460 800 baud raw
//! with `stty` before it is opened).
//!
//! Requests are stop-and-wait: one frame, then its acknowledgement (the
//! firmware checks each one down to `validate()` before it answers), then
//! the next. A frame whose acknowledgement does not come back within
//! [`Client::resend_after`] is sent again byte for byte, as is one the
//! firmware found damaged or could not queue (`Busy`); the firmware
//! acknowledges a resend of a request it already queued without applying
//! it twice (`cable_joint::link::Repeats`). A refusal of the content comes
//! back with its reason; no answer within [`Client::ack_timeout`] is an
//! error naming the request and the copies sent.

use std::collections::{BTreeMap, VecDeque};
use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use cable_joint::board::Request;
use cable_joint::link::{self, Down, FrameReader, Pushed, Refusal, Up, MAX_WIRE_LEN};
use cable_joint::telemetry::Record;
use serde::Serialize;

/// A byte stream to the firmware with a read timeout.
pub trait Port: Read + Write + Send {
    /// Wait at most `timeout` in each read.
    fn set_timeout(&mut self, timeout: Duration) -> std::io::Result<()>;
}

impl Port for TcpStream {
    fn set_timeout(&mut self, timeout: Duration) -> std::io::Result<()> {
        self.set_read_timeout(Some(timeout))
    }
}

/// A serial device opened as a file (reads return what is there after the
/// line discipline's `VTIME`, set by `stty`).
struct Tty(std::fs::File);

impl Read for Tty {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl Write for Tty {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

impl Port for Tty {
    fn set_timeout(&mut self, _timeout: Duration) -> std::io::Result<()> {
        // `stty ... min 0 time 1`: a read returns after 0.1 s without data.
        Ok(())
    }
}

/// A port whose line loses chosen acknowledgements on their way up (the
/// `n`-th acknowledgement read, counted from 0): fault injection for the
/// link's resend path and the firmware's `Repeats` (`host-sim pil`'s
/// tests). Every other frame passes unchanged and in order.
pub struct LosesAcks {
    inner: Box<dyn Port>,
    lost: Vec<usize>,
    acks: usize,
    reader: FrameReader<MAX_WIRE_LEN>,
    /// Bytes passed on and not yet read.
    ready: VecDeque<u8>,
}

impl LosesAcks {
    /// `inner`, losing the acknowledgements numbered in `lost`.
    pub fn new(inner: Box<dyn Port>, lost: Vec<usize>) -> Self {
        Self {
            inner,
            lost,
            acks: 0,
            reader: FrameReader::new(),
            ready: VecDeque::new(),
        }
    }

    /// The frame of `len` COBS bytes in the reader arrived: pass it on
    /// unless it is an acknowledgement to lose.
    fn arrived(&mut self, len: usize) {
        let bytes = self.reader.frame()[..len].to_vec();
        if let Ok((_, Up::Ack { .. })) = link::decode::<Up>(self.reader.frame(), len) {
            self.acks += 1;
            if self.lost.contains(&(self.acks - 1)) {
                return;
            }
        }
        self.ready.extend(bytes);
        self.ready.push_back(0);
    }
}

impl Read for LosesAcks {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.ready.is_empty() {
            let mut raw = [0u8; 512];
            let n = self.inner.read(&mut raw)?;
            if n == 0 {
                return Ok(0);
            }
            for &b in &raw[..n] {
                if let Pushed::Frame(len) = self.reader.push(b) {
                    self.arrived(len);
                }
            }
            if self.ready.is_empty() {
                return Err(ErrorKind::WouldBlock.into());
            }
        }
        let n = buf.len().min(self.ready.len());
        for (slot, b) in buf.iter_mut().zip(self.ready.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

impl Write for LosesAcks {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.inner.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl Port for LosesAcks {
    fn set_timeout(&mut self, timeout: Duration) -> std::io::Result<()> {
        self.inner.set_timeout(timeout)
    }
}

/// Open `spec`: `tcp:HOST:PORT`, `rtt:HOST:PORT` (RTT channel 1 through
/// a GDB server that stops the target to poll: QEMU only,
/// [`crate::gdb_rtt`]) or a serial device path.
pub fn open(spec: &str) -> anyhow::Result<Box<dyn Port>> {
    if let Some(addr) = spec.strip_prefix("rtt:") {
        return Ok(Box::new(crate::gdb_rtt::GdbRtt::connect(addr)?));
    }
    if let Some(addr) = spec.strip_prefix("tcp:") {
        let stream = TcpStream::connect(addr)
            .with_context(|| format!("connecting to the firmware link at {addr}"))?;
        stream.set_nodelay(true)?;
        return Ok(Box::new(stream));
    }
    let baud = link::SERIAL_BAUD.to_string();
    let status = std::process::Command::new("stty")
        .args(["-F", spec, &baud, "raw", "-echo", "min", "0", "time", "1"])
        .status()
        .with_context(|| format!("running stty on {spec}"))?;
    if !status.success() {
        bail!("stty could not set {spec} to {baud} baud raw (is it a serial device?)");
    }
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(spec)
        .with_context(|| format!("opening the serial device {spec}"))?;
    Ok(Box::new(Tty(file)))
}

/// Whether `spec` names a serial device (not `tcp:` or `rtt:`).
pub fn is_serial(spec: &str) -> bool {
    !(spec.starts_with("tcp:") || spec.starts_with("rtt:"))
}

/// Bytes one tick record takes on the wire: its frame (version, sequence,
/// body, CRC) in COBS with the delimiter.
pub fn tick_frame_len() -> usize {
    let mut bytes = [0u8; cable_joint::telemetry::MAX_RECORD_LEN];
    let record = Record::Tick(cable_joint::telemetry::TickRecord::default());
    let mut wire = [0u8; MAX_WIRE_LEN];
    link::encode(&Up::Telemetry(record.encode(&mut bytes)), 0, &mut wire).map_or(0, <[u8]>::len)
}

/// A warning when a record every `decimation` ticks of a `rate_hz` loop
/// needs more than the serial link carries ([`link::SERIAL_BAUD`], ten bits
/// a byte): the share of records the firmware will drop from its full
/// queue, and the least decimation the link carries.
pub fn serial_shortfall(rate_hz: f64, decimation: u32) -> Option<String> {
    let frame_b = tick_frame_len() as f64;
    let link_b_s = f64::from(link::SERIAL_BAUD) / 10.0;
    let need_b_s = rate_hz / f64::from(decimation.max(1)) * frame_b;
    (need_b_s > link_b_s).then(|| {
        let least = (rate_hz * frame_b / link_b_s).ceil();
        format!(
            "a record every {decimation} ticks at {rate_hz:.0} Hz needs {:.1} kB/s of {frame_b:.0}-byte \
             frames; the serial link carries {:.1} kB/s at {} baud, so the firmware will drop about \
             {:.0} % of the records (the log's gaps, counted at the end): ask for --decimation \
             {least:.0} or more, or record over RTT",
            need_b_s / 1e3,
            link_b_s / 1e3,
            link::SERIAL_BAUD,
            100.0 * (1.0 - link_b_s / need_b_s)
        )
    })
}

/// The firmware's message for a request the host's own tools build (a
/// configuration goes as [`Down::SetConfig`] with its plain `Config`).
pub fn down_for(request: &Request) -> anyhow::Result<Down> {
    Ok(match request {
        Request::Program(p) => Down::Program(*p),
        Request::SetCommand(c) => Down::SetCommand(*c),
        Request::ClearFault => Down::ClearFault,
        Request::SetDecimation(n) => Down::SetDecimation(*n),
        Request::Heartbeat => Down::Heartbeat,
        Request::SetConfig(_) => {
            bail!("a prepared configuration cannot be sent: send its Config as Down::SetConfig")
        }
    })
}

/// Why the firmware refused a frame, in words.
pub fn refusal_text(r: Refusal) -> String {
    match r {
        Refusal::Frame(code) => format!(
            "the frame arrived damaged or not understood (link error {code}: 1 too long, 2 COBS, \
             3 too short, 4 CRC, 5 version, 6 body)"
        ),
        Refusal::Invalid => {
            "its content failed the firmware's validation (the field is named in the firmware's \
             defmt log)"
                .to_owned()
        }
        Refusal::Busy => "the firmware's request queue was full".to_owned(),
    }
}

/// The host's end of one link.
pub struct Client {
    port: Box<dyn Port>,
    reader: FrameReader<MAX_WIRE_LEN>,
    seq: u8,
    /// Frames read and not yet handed out.
    incoming: VecDeque<Frame>,
    /// Telemetry records received and not yet taken.
    pending: Vec<Record>,
    /// Frames that failed to decode (damaged on the way).
    pub damaged: u32,
    /// How long [`Client::request`] waits for its acknowledgement in all.
    pub ack_timeout: Duration,
    /// How long it waits for one copy's acknowledgement before it sends
    /// the frame again.
    pub resend_after: Duration,
    /// Frames sent again (no acknowledgement in time, damaged on the way,
    /// or the firmware's queue full).
    pub resent: u32,
}

/// Most bytes one read of the port takes (a quarter of a second of
/// telemetry at a record every tick of a 2 kHz loop).
const READ_CHUNK: usize = 32 * 1024;

/// Pause before a request the firmware could not queue is sent again (its
/// queue of four drains one request per control tick).
const BUSY_PAUSE: Duration = Duration::from_millis(10);

/// One frame from the firmware.
#[derive(Debug, Clone, PartialEq)]
pub enum Frame {
    /// The answer to the host's frame `seq`.
    Ack {
        /// The host frame's sequence number.
        seq: u8,
        /// Why it was refused (`None`: accepted).
        refused: Option<Refusal>,
    },
    /// A telemetry record.
    Telemetry(Record),
}

impl Client {
    /// A client on an open port.
    pub fn new(mut port: Box<dyn Port>) -> anyhow::Result<Self> {
        port.set_timeout(Duration::from_millis(50))?;
        Ok(Self {
            port,
            reader: FrameReader::new(),
            seq: 0,
            incoming: VecDeque::new(),
            pending: Vec::new(),
            damaged: 0,
            ack_timeout: Duration::from_secs(5),
            resend_after: Duration::from_millis(500),
            resent: 0,
        })
    }

    /// Send `msg` (`what` names it in errors) as the next frame, without
    /// waiting for an answer; its sequence number.
    pub fn send<M: Serialize>(&mut self, msg: &M, what: &str) -> anyhow::Result<u8> {
        let (seq, frame) = self.encode_next(msg, what)?;
        self.write_frame(&frame, what)?;
        Ok(seq)
    }

    /// `msg` as the next frame's bytes, with its sequence number.
    fn encode_next<M: Serialize>(&mut self, msg: &M, what: &str) -> anyhow::Result<(u8, Vec<u8>)> {
        self.seq = self.seq.wrapping_add(1);
        let mut wire = [0u8; MAX_WIRE_LEN];
        let frame = link::encode(msg, self.seq, &mut wire)
            .map_err(|e| anyhow::anyhow!("encoding {what}: {e}"))?;
        Ok((self.seq, frame.to_vec()))
    }

    fn write_frame(&mut self, frame: &[u8], what: &str) -> anyhow::Result<()> {
        self.port
            .write_all(frame)
            .with_context(|| format!("sending {what}"))?;
        self.port.flush()?;
        Ok(())
    }

    /// Send `msg` and wait for its acknowledgement, sending the same frame
    /// again while none comes, the firmware found it damaged or its queue
    /// was full; telemetry that arrives meanwhile is kept for
    /// [`Client::take_telemetry`].
    pub fn request(&mut self, msg: &Down) -> anyhow::Result<()> {
        let what = name(msg);
        let (seq, frame) = self.encode_next(msg, what)?;
        let deadline = Instant::now() + self.ack_timeout;
        let mut copies = 0u32;
        let mut busy = false;
        loop {
            if copies > 0 {
                self.resent += 1;
            }
            self.write_frame(&frame, what)?;
            copies += 1;
            match self.answer(seq, (Instant::now() + self.resend_after).min(deadline))? {
                Some(None) => return Ok(()),
                Some(Some(r)) if !r.worth_resending() => {
                    bail!("the firmware refused {what}: {}", refusal_text(r))
                }
                Some(Some(Refusal::Busy)) => {
                    busy = true;
                    std::thread::sleep(BUSY_PAUSE);
                }
                // Damaged on the way, or no answer: send it again.
                Some(Some(_)) | None => {}
            }
            if Instant::now() >= deadline {
                let secs = self.ack_timeout.as_secs_f64();
                if busy {
                    bail!(
                        "{what} was not applied: the firmware's request queue stayed full for \
                         {secs:.1} s ({copies} copies sent)"
                    );
                }
                bail!(
                    "no answer from the firmware to {what} within {secs:.1} s ({copies} copies \
                     sent; is it running, and the port right?)"
                );
            }
        }
    }

    /// The acknowledgement of frame `seq` if one arrives before `until`
    /// (`Some(refusal)`), keeping the telemetry that arrives meanwhile.
    fn answer(&mut self, seq: u8, until: Instant) -> anyhow::Result<Option<Option<Refusal>>> {
        while Instant::now() < until {
            match self.next_frame()? {
                Some(Frame::Ack { seq: s, refused }) if s == seq => return Ok(Some(refused)),
                Some(Frame::Ack { .. }) | None => {}
                Some(Frame::Telemetry(r)) => self.pending.push(r),
            }
        }
        Ok(None)
    }

    /// Read what has arrived (waiting up to the port's timeout once) and
    /// return the telemetry received so far.
    /// When the read fails (the link closed), the records already read
    /// stay for [`Client::take_telemetry`].
    pub fn poll(&mut self) -> anyhow::Result<Vec<Record>> {
        let filled = self.fill();
        // No request waits here: its acknowledgements are stale.
        self.incoming.retain(|f| matches!(f, Frame::Telemetry(_)));
        filled?;
        Ok(self.take_telemetry())
    }

    /// Read and drop whatever has arrived, without waiting (a link whose
    /// telemetry nobody wants must still be read, or the sender stalls
    /// once the socket's buffer is full).
    pub fn discard_waiting(&mut self) -> anyhow::Result<()> {
        self.port.set_timeout(Duration::from_micros(1))?;
        let read = self.fill();
        self.port.set_timeout(Duration::from_millis(50))?;
        read?;
        self.incoming.clear();
        self.pending.clear();
        Ok(())
    }

    /// The telemetry records received so far, those read while waiting for
    /// an acknowledgement included (the acknowledgements stay).
    pub fn take_telemetry(&mut self) -> Vec<Record> {
        let mut acks = VecDeque::with_capacity(self.incoming.len());
        for f in self.incoming.drain(..) {
            match f {
                Frame::Telemetry(r) => self.pending.push(r),
                ack => acks.push_back(ack),
            }
        }
        self.incoming = acks;
        std::mem::take(&mut self.pending)
    }

    /// The next frame, reading the port once (up to its timeout) when none
    /// is waiting; `None` if nothing complete arrived.
    pub fn next_frame(&mut self) -> anyhow::Result<Option<Frame>> {
        if self.incoming.is_empty() {
            self.fill()?;
        }
        Ok(self.incoming.pop_front())
    }

    /// Read the port once and decode every frame completed.
    fn fill(&mut self) -> anyhow::Result<()> {
        // One read takes everything that has arrived, up to READ_CHUNK: at
        // a record every tick the firmware sends about 140 kB/s, and a
        // reader that takes less per call falls behind, its socket fills
        // and the firmware's telemetry queue overflows (rows lost).
        let mut buf = [0u8; READ_CHUNK];
        let n = match self.port.read(&mut buf) {
            Ok(0) => bail!("the firmware link closed"),
            Ok(n) => n,
            // A signal (Ctrl-C asking `link` to stop, crate::interrupt)
            // cuts a read short: nothing read this time.
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) =>
            {
                0
            }
            Err(e) => return Err(e).context("reading the firmware link"),
        };
        for &b in &buf[..n] {
            let Pushed::Frame(len) = self.reader.push(b) else {
                continue;
            };
            match link::decode::<Up>(self.reader.frame(), len) {
                Ok((_, Up::Ack { seq, refused })) => {
                    self.incoming.push_back(Frame::Ack { seq, refused })
                }
                Ok((_, Up::Telemetry(bytes))) => match Record::decode(bytes) {
                    Ok(r) => self.incoming.push_back(Frame::Telemetry(r)),
                    Err(_) => self.damaged += 1,
                },
                Err(_) => self.damaged += 1,
            }
        }
        Ok(())
    }
}

/// Records a telemetry stream lost, counted from the firmware's tick
/// counter as the records arrive (the live view's footer and `host-sim
/// link`'s summary). The stream's decimation is the one the host asked for
/// (`requested`), counted from the first record after which every tick is
/// a multiple of it (the records before came at the boot's, every tick),
/// or else the smallest tick step seen. A tick counter that does not go
/// forward (the firmware restarted) starts the count over.
#[derive(Clone, Debug, Default)]
pub struct Losses {
    requested: Option<u32>,
    /// The first record counted: its tick and its index among the records
    /// pushed.
    first: Option<(u32, usize)>,
    /// Tick of the newest record.
    last: u32,
    /// Records pushed in all.
    pushed: usize,
    /// Every tick step since the first record counted: how often, and the
    /// index of the record after its first occurrence.
    steps: BTreeMap<u32, (u64, usize)>,
}

/// Where a stream lost records ([`Losses::gaps`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Gaps {
    /// The decimation the losses are counted at (a record every `decimation` ticks).
    pub decimation: u32,
    /// Gaps of the tick counter (a step longer than the decimation).
    pub count: u64,
    /// Records missing over all gaps.
    pub missing: u64,
    /// The longest step, in ticks (0 without a gap).
    pub longest_ticks: u32,
    /// Index of the record after the longest step's first occurrence.
    pub longest_after: usize,
    /// Index of the first record counted (0, or the first after the last
    /// record off the requested decimation).
    pub from: usize,
}

impl Losses {
    /// A count for a stream whose host asked for a record every
    /// `requested` ticks (`None` or 0: it did not ask).
    pub fn new(requested: Option<u32>) -> Self {
        Self {
            requested: requested.filter(|n| *n > 0),
            ..Self::default()
        }
    }

    /// Take in the next record's tick.
    pub fn push(&mut self, tick: u32) {
        let index = self.pushed;
        self.pushed += 1;
        let before = std::mem::replace(&mut self.last, tick);
        let off = self.requested.is_some_and(|n| !tick.is_multiple_of(n));
        match self.first {
            Some(_) if !off && tick > before => {
                self.steps.entry(tick - before).or_insert((0, index)).0 += 1;
            }
            _ => {
                self.steps.clear();
                self.first = (!off).then_some((tick, index));
            }
        }
    }

    /// The decimation the losses are counted at: the one asked for, else
    /// the smallest step seen (`None` before two records are counted).
    pub fn decimation(&self) -> Option<u32> {
        self.requested.or_else(|| self.steps.keys().next().copied())
    }

    /// Records lost since the first counted.
    pub fn lost(&self) -> u64 {
        self.gaps().missing
    }

    /// Where the records were lost: every step longer than the decimation
    /// is a gap of the tick counter missing the step in records, rounded,
    /// less one.
    pub fn gaps(&self) -> Gaps {
        let Some(((_, from), decimation)) = self.first.zip(self.decimation()) else {
            return Gaps::default();
        };
        let mut g = Gaps {
            decimation,
            from,
            ..Gaps::default()
        };
        for (&step, &(n, after)) in &self.steps {
            let records = (f64::from(step) / f64::from(decimation)).round() as u64;
            if records >= 2 {
                g.count += n;
                g.missing += n * (records - 1);
                if step > g.longest_ticks {
                    g.longest_ticks = step;
                    g.longest_after = after;
                }
            }
        }
        g
    }
}

/// A message's name for errors.
pub fn name(msg: &Down) -> &'static str {
    match msg {
        Down::Program(_) => "the program",
        Down::SetCommand(_) => "the command",
        Down::SetConfig(_) => "the configuration",
        Down::ClearFault => "the fault clear",
        Down::SetDecimation(_) => "the telemetry rate",
        Down::Heartbeat => "the heartbeat",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cable_joint::board::Request;
    use cable_joint::link::{encode, receive, Repeats};
    use cable_joint::telemetry::{StartRecord, FORMAT_VERSION, MAX_RECORD_LEN};
    use std::net::TcpListener;

    /// What the line between host and stand-in firmware loses: the
    /// frames (counted from 0 as they arrive, resends included) that never
    /// arrive, and those whose acknowledgement never comes back.
    #[derive(Clone, Copy, Default)]
    struct Dropped {
        frames: &'static [usize],
        acks: &'static [usize],
    }

    /// A stand-in for the firmware's link tasks on a socket: every frame
    /// goes through the core's `receive` and `Repeats` (as the `link_frame`
    /// task does), a telemetry record goes up before each acknowledgement,
    /// and a decimation of 7 is answered "busy". `losses` are dropped.
    fn fake_firmware(listener: TcpListener, losses: Dropped) -> Vec<Request> {
        let (mut s, _) = listener.accept().unwrap();
        let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
        let mut queued = Vec::new();
        let mut buf = [0u8; 256];
        let mut up_seq = 0u8;
        let mut repeats = Repeats::new();
        let mut arrived = 0usize;
        let mut send = |s: &mut TcpStream, msg: &Up| {
            let mut wire = [0u8; MAX_WIRE_LEN];
            s.write_all(encode(msg, up_seq, &mut wire).unwrap())
                .unwrap();
            up_seq = up_seq.wrapping_add(1);
        };
        loop {
            let n = s.read(&mut buf).unwrap();
            if n == 0 {
                return queued;
            }
            for &b in &buf[..n] {
                let Pushed::Frame(len) = reader.push(b) else {
                    continue;
                };
                arrived += 1;
                if losses.frames.contains(&(arrived - 1)) {
                    continue;
                }
                let r = receive(reader.frame(), len);
                let mut bytes = [0u8; MAX_RECORD_LEN];
                let record = Record::Start(StartRecord {
                    version: FORMAT_VERSION,
                    control_rate_hz: 2000.0,
                    decimation: 1,
                });
                send(&mut s, &Up::Telemetry(record.encode(&mut bytes)));
                let (seq, crc) = (r.seq, r.crc);
                let refused = match r.outcome {
                    Ok(_) if repeats.is_repeat(&r) => None,
                    Ok(Request::SetDecimation(7)) => Some(Refusal::Busy),
                    Ok(req) => {
                        queued.push(req);
                        repeats.queued(seq, crc);
                        None
                    }
                    Err(e) => Some(e.refusal()),
                };
                if losses.acks.contains(&(arrived - 1)) {
                    continue;
                }
                send(&mut s, &Up::Ack { seq, refused });
            }
        }
    }

    /// A stand-in firmware on a local port: the port's spec and the thread
    /// that returns what it queued.
    fn stand_in(losses: Dropped) -> (String, std::thread::JoinHandle<Vec<Request>>) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let firmware = std::thread::spawn(move || fake_firmware(listener, losses));
        (format!("tcp:127.0.0.1:{port}"), firmware)
    }

    /// The four requests of the loss tests, each acknowledged.
    const FOUR: [Request; 4] = [
        Request::Heartbeat,
        Request::SetDecimation(10),
        Request::ClearFault,
        Request::Heartbeat,
    ];

    fn send_four(c: &mut Client) {
        for r in &FOUR {
            c.request(&down_for(r).unwrap()).unwrap();
        }
    }

    /// Telemetry read in the same chunk as an acknowledgement waits in the
    /// client's queue; when the link then closes, `poll` fails but those
    /// records are still handed over (a run that ends early keeps them).
    #[test]
    fn records_read_before_the_link_closed_are_kept() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let firmware = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
            let mut buf = [0u8; 256];
            let seq = 'request: loop {
                let n = s.read(&mut buf).unwrap();
                for &b in &buf[..n] {
                    if let Pushed::Frame(len) = reader.push(b) {
                        break 'request receive(reader.frame(), len).seq;
                    }
                }
            };
            // The acknowledgement and three records in one write, then close.
            let mut out = Vec::new();
            let mut wire = [0u8; MAX_WIRE_LEN];
            out.extend_from_slice(encode(&Up::Ack { seq, refused: None }, 0, &mut wire).unwrap());
            for k in 0..3u8 {
                let mut bytes = [0u8; MAX_RECORD_LEN];
                let record = Record::Start(StartRecord {
                    version: FORMAT_VERSION,
                    control_rate_hz: 2000.0,
                    decimation: u32::from(k) + 1,
                });
                let up = Up::Telemetry(record.encode(&mut bytes));
                out.extend_from_slice(encode(&up, k + 1, &mut wire).unwrap());
            }
            s.write_all(&out).unwrap();
        });
        let mut c = Client::new(open(&format!("tcp:127.0.0.1:{port}")).unwrap()).unwrap();
        c.request(&Down::Heartbeat).unwrap();
        firmware.join().unwrap();
        let mut got = Vec::new();
        let closed = loop {
            match c.poll() {
                Ok(r) => got.extend(r),
                Err(e) => break e.to_string(),
            }
        };
        assert!(closed.contains("closed"), "{closed}");
        got.extend(c.take_telemetry());
        assert_eq!(got.len(), 3, "{got:?}");
    }

    #[test]
    fn client_gets_acknowledgements_refusals_and_the_telemetry_between() {
        let (spec, firmware) = stand_in(Dropped::default());
        let mut c = Client::new(open(&spec).unwrap()).unwrap();
        c.ack_timeout = Duration::from_secs(1);
        c.request(&Down::Heartbeat).unwrap();
        c.request(&Down::SetDecimation(10)).unwrap();
        // Refused on the way in, with the reason in words.
        let e = c.request(&Down::SetDecimation(0)).unwrap_err().to_string();
        assert!(
            e.contains("the telemetry rate") && e.contains("validation"),
            "{e}"
        );
        // Busy is sent again until the deadline, then named.
        let e = c.request(&Down::SetDecimation(7)).unwrap_err().to_string();
        assert!(
            e.contains("the telemetry rate was not applied") && e.contains("queue stayed full"),
            "{e}"
        );
        let busy_copies = c.resent + 1;
        assert!(busy_copies > 2, "{busy_copies}");
        c.request(&Down::ClearFault).unwrap();
        // One record came up before each answer.
        assert_eq!(c.take_telemetry().len() as u32, 4 + busy_copies);
        assert_eq!(c.damaged, 0);
        drop(c);
        assert_eq!(
            firmware.join().unwrap(),
            [
                Request::Heartbeat,
                Request::SetDecimation(10),
                Request::ClearFault
            ]
        );
    }

    /// Over a line that loses a request frame and, later, an
    /// acknowledgement, every request is applied exactly once and in
    /// order: the lost frame is sent again, and the resend of the frame
    /// whose acknowledgement was lost is acknowledged without being queued
    /// twice.
    #[test]
    fn a_lost_frame_or_acknowledgement_is_resent_and_applied_once() {
        // Arrivals: 0 heartbeat, 1 decimation (lost), 2 its resend,
        // 3 fault clear (its acknowledgement lost), 4 its resend,
        // 5 heartbeat.
        let (spec, firmware) = stand_in(Dropped {
            frames: &[1],
            acks: &[3],
        });
        let mut c = Client::new(open(&spec).unwrap()).unwrap();
        c.resend_after = Duration::from_millis(150);
        send_four(&mut c);
        assert_eq!(c.resent, 2);
        drop(c);
        assert_eq!(firmware.join().unwrap(), FOUR);
    }

    /// `LosesAcks` (the PIL's link fault) loses exactly the acknowledgements
    /// it is told to, and the telemetry around them passes.
    #[test]
    fn loses_acks_drops_the_chosen_acknowledgements_only() {
        let (spec, firmware) = stand_in(Dropped::default());
        let lossy = LosesAcks::new(open(&spec).unwrap(), vec![1]);
        let mut c = Client::new(Box::new(lossy)).unwrap();
        c.resend_after = Duration::from_millis(150);
        send_four(&mut c);
        // Acknowledgement 1 (the decimation's) was lost and its frame sent
        // again; the record before each of the five answers came through.
        assert_eq!(c.resent, 1);
        assert_eq!(c.take_telemetry().len(), 5);
        assert_eq!(c.damaged, 0);
        drop(c);
        assert_eq!(firmware.join().unwrap(), FOUR);
    }

    #[test]
    fn no_firmware_is_a_clear_error() {
        // A port nobody listens on.
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let e = open(&format!("tcp:127.0.0.1:{port}")).err().unwrap();
        assert!(
            format!("{e:#}").contains("connecting to the firmware link"),
            "{e:#}"
        );
        // A listener that never answers.
        let silent = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = silent.local_addr().unwrap().port();
        let mut c = Client::new(open(&format!("tcp:127.0.0.1:{port}")).unwrap()).unwrap();
        c.ack_timeout = Duration::from_millis(200);
        c.resend_after = Duration::from_millis(50);
        let e = c.request(&Down::Heartbeat).unwrap_err().to_string();
        assert!(
            e.contains("no answer from the firmware to the heartbeat") && e.contains("copies sent"),
            "{e}"
        );
        assert!(c.resent >= 1, "sent again before giving up");
    }

    fn count(requested: Option<u32>, ticks: impl IntoIterator<Item = u32>) -> super::Losses {
        let mut l = super::Losses::new(requested);
        for t in ticks {
            l.push(t);
        }
        l
    }

    #[test]
    fn losses_are_the_gaps_of_the_tick_counter_at_the_smallest_step() {
        // A record every 4th tick; ticks 40..52 lost (3 records), then 100
        // (1 record).
        let ticks = (0..200)
            .step_by(4)
            .filter(|k| !(40..52).contains(k) && *k != 100);
        let g = count(None, ticks).gaps();
        assert_eq!(
            g,
            Gaps {
                decimation: 4,
                count: 2,
                missing: 4,
                longest_ticks: 16,
                longest_after: 10,
                from: 0,
            }
        );
    }

    #[test]
    fn losses_after_a_decimation_request_are_counted_from_its_first_record() {
        // Every tick at boot, every 5th from tick 23 (the first multiple
        // after the last record off it, 22, is 25: record 23).
        let ticks = (0..23).chain((25..300).step_by(5));
        let l = count(Some(5), ticks.clone());
        assert_eq!((l.lost(), l.gaps().from), (0, 23));
        // Without the request the boot's every tick is the decimation.
        assert_eq!(count(None, ticks).lost(), 296 - 23 - 55);
    }

    #[test]
    fn a_tick_counter_that_goes_back_starts_the_count_over() {
        let l = count(None, (0..100).step_by(2).chain([10, 11, 14, 15]));
        assert_eq!((l.lost(), l.gaps().count, l.gaps().from), (2, 1, 50));
    }

    #[test]
    fn a_serial_link_cannot_carry_a_record_every_tick_at_2khz_and_says_what_it_can() {
        // 70 bytes of record, 8 of frame (docs/firmware.md).
        assert_eq!(tick_frame_len(), 78);
        let w = serial_shortfall(2000.0, 1).expect("156 kB/s on a 46 kB/s line");
        assert!(w.contains("156.0 kB/s"), "{w}");
        assert!(w.contains("drop about 70 %"), "{w}");
        assert!(w.contains("--decimation 4 or more"), "{w}");
        assert_eq!(serial_shortfall(2000.0, 4), None);
        assert_eq!(serial_shortfall(2000.0, 10), None);
        let w = serial_shortfall(1000.0, 1).expect("78 kB/s");
        assert!(w.contains("--decimation 2 or more"), "{w}");
        assert!(is_serial("/dev/ttyACM0"));
        assert!(!is_serial("tcp:127.0.0.1:5555") && !is_serial("rtt:127.0.0.1:3333"));
    }
}
