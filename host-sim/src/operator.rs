//! The host's end of the firmware link (`cable_joint::link`): connect to a
//! port, send a request and wait for its acknowledgement, collect the
//! telemetry the firmware streams meanwhile.
//!
//! A port is `tcp:HOST:PORT` (QEMU's serial port as a socket, `host-sim
//! pil --link-port`) or a serial device (`/dev/ttyACM0`: the prototype's
//! USART2 through a USB–serial adapter; set to 460 800 baud raw with
//! `stty` before it is opened).
//!
//! Requests are stop-and-wait: one frame, then its acknowledgement (the
//! firmware checks each one down to `validate()` before it answers), then
//! the next. A refusal comes back with its reason; no answer within the
//! timeout is an error naming the request.

use std::collections::VecDeque;
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

/// Open `spec`: `tcp:HOST:PORT` or a serial device path.
pub fn open(spec: &str) -> anyhow::Result<Box<dyn Port>> {
    if let Some(addr) = spec.strip_prefix("tcp:") {
        let stream = TcpStream::connect(addr)
            .with_context(|| format!("connecting to the firmware link at {addr}"))?;
        stream.set_nodelay(true)?;
        return Ok(Box::new(stream));
    }
    let status = std::process::Command::new("stty")
        .args([
            "-F", spec, "460800", "raw", "-echo", "min", "0", "time", "1",
        ])
        .status()
        .with_context(|| format!("running stty on {spec}"))?;
    if !status.success() {
        bail!("stty could not set {spec} to 460800 baud raw (is it a serial device?)");
    }
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(spec)
        .with_context(|| format!("opening the serial device {spec}"))?;
    Ok(Box::new(Tty(file)))
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
        Refusal::Busy => "the firmware's request queue was full: send it again".to_owned(),
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
    /// How long [`Client::request`] waits for its acknowledgement.
    pub ack_timeout: Duration,
}

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
        })
    }

    /// Send `msg` (`what` names it in errors) as the next frame, without
    /// waiting for an answer; its sequence number.
    pub fn send<M: Serialize>(&mut self, msg: &M, what: &str) -> anyhow::Result<u8> {
        self.seq = self.seq.wrapping_add(1);
        let mut wire = [0u8; MAX_WIRE_LEN];
        let frame = link::encode(msg, self.seq, &mut wire)
            .map_err(|e| anyhow::anyhow!("encoding {what}: {e}"))?;
        self.port
            .write_all(frame)
            .with_context(|| format!("sending {what}"))?;
        self.port.flush()?;
        Ok(self.seq)
    }

    /// Send `msg` and wait for its acknowledgement; telemetry that arrives
    /// meanwhile is kept for [`Client::take_telemetry`].
    pub fn request(&mut self, msg: &Down) -> anyhow::Result<()> {
        let seq = self.send(msg, name(msg))?;
        let deadline = Instant::now() + self.ack_timeout;
        while Instant::now() < deadline {
            match self.next_frame()? {
                Some(Frame::Ack { seq: s, refused }) if s == seq => {
                    return match refused {
                        None => Ok(()),
                        Some(r) => {
                            bail!("the firmware refused {}: {}", name(msg), refusal_text(r))
                        }
                    };
                }
                Some(Frame::Ack { .. }) | None => {}
                Some(Frame::Telemetry(r)) => self.pending.push(r),
            }
        }
        bail!(
            "no answer from the firmware to {} within {:.1} s (is it running, and the port right?)",
            name(msg),
            self.ack_timeout.as_secs_f64()
        )
    }

    /// Read what has arrived (waiting up to the port's timeout once) and
    /// return the telemetry received so far.
    pub fn poll(&mut self) -> anyhow::Result<Vec<Record>> {
        self.fill()?;
        for f in self.incoming.drain(..) {
            if let Frame::Telemetry(r) = f {
                self.pending.push(r);
            }
        }
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

    /// The telemetry records received so far.
    pub fn take_telemetry(&mut self) -> Vec<Record> {
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
        let mut buf = [0u8; 512];
        let n = match self.port.read(&mut buf) {
            Ok(0) => bail!("the firmware link closed"),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => 0,
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
    use cable_joint::link::{encode, receive};
    use cable_joint::telemetry::{StartRecord, FORMAT_VERSION, MAX_RECORD_LEN};
    use std::net::TcpListener;

    /// A stand-in for the firmware's link tasks on a socket: every frame
    /// goes through the core's `receive` (as the `link_frame` task does),
    /// a telemetry record goes up before each acknowledgement, and a
    /// decimation of 7 is answered "busy".
    fn fake_firmware(listener: TcpListener) -> Vec<Request> {
        let (mut s, _) = listener.accept().unwrap();
        let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
        let mut queued = Vec::new();
        let mut buf = [0u8; 256];
        let mut up_seq = 0u8;
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
                let r = receive(reader.frame(), len);
                let mut bytes = [0u8; MAX_RECORD_LEN];
                let record = Record::Start(StartRecord {
                    version: FORMAT_VERSION,
                    control_rate_hz: 2000.0,
                    decimation: 1,
                });
                send(&mut s, &Up::Telemetry(record.encode(&mut bytes)));
                let refused = match r.outcome {
                    Ok(Request::SetDecimation(7)) => Some(Refusal::Busy),
                    Ok(req) => {
                        queued.push(req);
                        None
                    }
                    Err(e) => Some(e.refusal()),
                };
                send(
                    &mut s,
                    &Up::Ack {
                        seq: r.seq,
                        refused,
                    },
                );
            }
        }
    }

    #[test]
    fn client_gets_acknowledgements_refusals_and_the_telemetry_between() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let firmware = std::thread::spawn(move || fake_firmware(listener));
        let mut c = Client::new(open(&format!("tcp:127.0.0.1:{port}")).unwrap()).unwrap();
        c.request(&Down::Heartbeat).unwrap();
        c.request(&Down::SetDecimation(10)).unwrap();
        // Refused on the way in, with the reason in words.
        let e = c.request(&Down::SetDecimation(0)).unwrap_err().to_string();
        assert!(
            e.contains("the telemetry rate") && e.contains("validation"),
            "{e}"
        );
        let e = c.request(&Down::SetDecimation(7)).unwrap_err().to_string();
        assert!(e.contains("queue was full"), "{e}");
        c.request(&Down::ClearFault).unwrap();
        // One record came up before each of the five answers.
        assert_eq!(c.take_telemetry().len(), 5);
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
        let e = c.request(&Down::Heartbeat).unwrap_err().to_string();
        assert!(
            e.contains("no answer from the firmware to the heartbeat"),
            "{e}"
        );
    }
}
