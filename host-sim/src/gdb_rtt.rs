//! The firmware link over RTT channel 1, reached through a GDB server: the
//! port `rtt:HOST:PORT` of [`crate::operator::open`].
//!
//! A debug probe reads and writes the firmware's RTT block while the MCU
//! runs (`cable_joint::rtt`). Under QEMU the "probe" is QEMU's GDB stub
//! (`-gdb tcp::PORT`; `host-sim pil --rtt`): this port finds the block by
//! its id in RAM, and on each poll stops the machine, takes what the
//! firmware wrote to up channel 1, writes what the host has queued for down
//! channel 1, and lets it run again. Under `-icount` a stopped machine's
//! clock stands still, so the polls do not change what the firmware sees.
//!
//! **Not for a board**: a GDB server stops the CPU for each poll, and a
//! stopped controller leaves the motor on its last current. On the
//! prototype the link's RTT channel goes through OpenOCD, which reads RAM
//! while the MCU runs (`rtt server start 9091 1`, then `tcp:localhost:9091`;
//! docs/firmware.md).
//!
//! The GDB remote protocol used: `?`, `m`, `M`, `c` and the interrupt byte
//! 0x03, with acknowledgements.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use cable_joint::rtt::{
    down_offset, field, up_offset, Ring, Transfer, DOWN_CHANNELS, ID, LINK_CHANNEL,
    MAX_DOWN_OFFSET, MAX_UP_OFFSET, UP_CHANNELS,
};

use crate::operator::Port;

/// Where the firmware's RAM is searched for the block: the STM32F4's
/// 128 KiB of SRAM (QEMU's netduinoplus2 has the same).
const RAM: std::ops::Range<u32> = 0x2000_0000..0x2002_0000;

/// Bytes per memory read while searching (QEMU's stub answers up to 4 KiB
/// of hex in one packet).
const SEARCH_CHUNK: u32 = 1024;

/// Time between two polls while a read waits for data.
const POLL_PERIOD: Duration = Duration::from_millis(2);

/// A GDB remote-protocol connection.
struct Gdb {
    stream: TcpStream,
    /// Bytes read past the last packet.
    buffered: VecDeque<u8>,
}

impl Gdb {
    fn connect(addr: &str) -> anyhow::Result<Self> {
        let stream = TcpStream::connect(addr)
            .with_context(|| format!("connecting to the GDB server at {addr}"))?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(Duration::from_secs(10)))?;
        Ok(Self {
            stream,
            buffered: VecDeque::new(),
        })
    }

    fn byte(&mut self) -> anyhow::Result<u8> {
        if let Some(b) = self.buffered.pop_front() {
            return Ok(b);
        }
        let mut buf = [0u8; 4096];
        let n = match self.stream.read(&mut buf) {
            Ok(0) => bail!("the GDB server closed the connection"),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                bail!("the GDB server did not answer within 10 s")
            }
            Err(e) => return Err(e).context("reading from the GDB server"),
        };
        self.buffered.extend(&buf[..n]);
        Ok(self.buffered.pop_front().unwrap_or_default())
    }

    /// Send one packet (and wait for its acknowledgement). A packet the
    /// server sent meanwhile (QEMU's stop reply on attaching) is
    /// acknowledged and dropped.
    fn send(&mut self, data: &str) -> anyhow::Result<()> {
        let sum = data.bytes().fold(0u8, |s, b| s.wrapping_add(b));
        let packet = format!("${data}#{sum:02x}");
        for _ in 0..3 {
            self.stream
                .write_all(packet.as_bytes())
                .context("writing to the GDB server")?;
            loop {
                match self.byte()? {
                    b'+' => return Ok(()),
                    b'-' => break,
                    b'$' => {
                        self.payload()?;
                    }
                    _ => {}
                }
            }
        }
        bail!("the GDB server refused the packet `{data}` three times")
    }

    /// The next packet's payload (acknowledged).
    fn receive(&mut self) -> anyhow::Result<String> {
        while self.byte()? != b'$' {}
        self.payload()
    }

    /// The rest of a packet whose `$` was read: its payload, acknowledged.
    fn payload(&mut self) -> anyhow::Result<String> {
        let mut data = Vec::new();
        loop {
            match self.byte()? {
                b'#' => break,
                b => data.push(b),
            }
        }
        let sum = [self.byte()?, self.byte()?];
        let want = data.iter().fold(0u8, |s, b| s.wrapping_add(*b));
        let got = std::str::from_utf8(&sum)
            .ok()
            .and_then(|s| u8::from_str_radix(s, 16).ok());
        if got != Some(want) {
            self.stream.write_all(b"-")?;
            bail!("a packet from the GDB server failed its checksum");
        }
        self.stream.write_all(b"+")?;
        String::from_utf8(data).context("a packet from the GDB server is not text")
    }

    fn command(&mut self, data: &str) -> anyhow::Result<String> {
        self.send(data)?;
        self.receive()
    }

    /// Stop the machine (it runs after [`Gdb::resume`]).
    fn interrupt(&mut self) -> anyhow::Result<()> {
        self.stream.write_all(&[0x03])?;
        self.wait_stopped()
    }

    /// Wait for a stop reply (`S..` or `T..`).
    fn wait_stopped(&mut self) -> anyhow::Result<()> {
        loop {
            let reply = self.receive()?;
            match reply.as_bytes().first() {
                Some(b'S' | b'T') => return Ok(()),
                Some(b'W' | b'X') => bail!("the target exited ({reply})"),
                _ => {}
            }
        }
    }

    fn resume(&mut self) -> anyhow::Result<()> {
        // No answer until the next stop.
        self.send("c")
    }

    fn read(&mut self, addr: u32, len: u32) -> anyhow::Result<Vec<u8>> {
        let reply = self.command(&format!("m{addr:x},{len:x}"))?;
        if reply.starts_with('E') || reply.len() != 2 * len as usize {
            bail!("the GDB server could not read {len} bytes at {addr:#010x} ({reply:.8})");
        }
        (0..reply.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&reply[i..i + 2], 16))
            .collect::<Result<_, _>>()
            .context("the GDB server's memory read is not hex")
    }

    fn write(&mut self, addr: u32, bytes: &[u8]) -> anyhow::Result<()> {
        if bytes.is_empty() {
            return Ok(());
        }
        let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
        let reply = self.command(&format!("M{addr:x},{:x}:{hex}", bytes.len()))?;
        if reply != "OK" {
            bail!(
                "the GDB server could not write {} bytes at {addr:#010x} ({reply:.8})",
                bytes.len()
            );
        }
        Ok(())
    }

    fn word(&mut self, addr: u32) -> anyhow::Result<u32> {
        let b = self.read(addr, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// One channel's descriptor address and buffer, as found in the block.
#[derive(Clone, Copy, Debug)]
struct Channel {
    descriptor: u32,
    buffer: u32,
    size: u32,
}

impl Channel {
    fn find(gdb: &mut Gdb, descriptor: u32) -> anyhow::Result<Self> {
        let buffer = gdb.word(descriptor + field::BUFFER)?;
        let size = gdb.word(descriptor + field::SIZE)?;
        if size < 2 || !RAM.contains(&buffer) || !RAM.contains(&(buffer + size - 1)) {
            bail!(
                "RTT channel descriptor at {descriptor:#010x} is not set up \
                 (buffer {buffer:#010x}, {size} bytes)"
            );
        }
        Ok(Self {
            descriptor,
            buffer,
            size,
        })
    }

    fn ring(&self, gdb: &mut Gdb) -> anyhow::Result<Ring> {
        let b = gdb.read(self.descriptor + field::WRITE, 8)?;
        Ok(Ring {
            size: self.size,
            write: u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            read: u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
        })
    }

    fn runs(&self, t: &Transfer) -> [(u32, u32); 2] {
        [
            (self.buffer + t.first.start, t.first.len),
            (self.buffer + t.second.start, t.second.len),
        ]
    }
}

/// The link over RTT channel 1 through a GDB server (see the module docs).
pub struct GdbRtt {
    gdb: Gdb,
    up: Channel,
    down: Channel,
    /// Bytes from the firmware not yet read.
    received: VecDeque<u8>,
    /// Bytes for the firmware not yet written.
    queued: VecDeque<u8>,
    timeout: Duration,
}

impl GdbRtt {
    /// Connect to the GDB server at `addr` (`HOST:PORT`), find the
    /// firmware's RTT block in RAM, and let the machine run.
    pub fn connect(addr: &str) -> anyhow::Result<Self> {
        let mut gdb = Gdb::connect(addr)?;
        // QEMU stops the machine when a debugger attaches; `?` says so.
        gdb.send("?")?;
        gdb.wait_stopped()?;
        let block = find_block(&mut gdb)?;
        let max_up = gdb.word(block + MAX_UP_OFFSET)?;
        let max_down = gdb.word(block + MAX_DOWN_OFFSET)?;
        if max_up < UP_CHANNELS || max_down < DOWN_CHANNELS || max_up > 16 || max_down > 16 {
            bail!(
                "the RTT block at {block:#010x} has {max_up} up and {max_down} down channels; \
                 the firmware's has {UP_CHANNELS} and {DOWN_CHANNELS}"
            );
        }
        let up = Channel::find(&mut gdb, block + up_offset(LINK_CHANNEL))?;
        let down = Channel::find(&mut gdb, block + down_offset(max_up, LINK_CHANNEL))?;
        gdb.resume()?;
        Ok(Self {
            gdb,
            up,
            down,
            received: VecDeque::new(),
            queued: VecDeque::new(),
            timeout: Duration::from_millis(50),
        })
    }

    /// Stop the machine, move the bytes both ways, let it run again.
    fn poll(&mut self) -> anyhow::Result<()> {
        self.gdb.interrupt()?;
        let ring = self.up.ring(&mut self.gdb)?;
        let t = ring.read(u32::MAX);
        for (addr, len) in self.up.runs(&t) {
            if len > 0 {
                let bytes = self.gdb.read(addr, len)?;
                self.received.extend(bytes);
            }
        }
        if !t.is_empty() {
            self.gdb
                .write(self.up.descriptor + field::READ, &t.next.to_le_bytes())?;
        }
        if !self.queued.is_empty() {
            let ring = self.down.ring(&mut self.gdb)?;
            let t = ring.write_some(self.queued.len() as u32);
            for (addr, len) in self.down.runs(&t) {
                let bytes: Vec<u8> = self.queued.drain(..len as usize).collect();
                self.gdb.write(addr, &bytes)?;
            }
            if !t.is_empty() {
                self.gdb
                    .write(self.down.descriptor + field::WRITE, &t.next.to_le_bytes())?;
            }
        }
        self.gdb.resume()
    }
}

/// The RTT block's address: its id, searched for in RAM.
fn find_block(gdb: &mut Gdb) -> anyhow::Result<u32> {
    let overlap = ID.len() as u32;
    let mut addr = RAM.start;
    while addr < RAM.end {
        let len = SEARCH_CHUNK.min(RAM.end - addr);
        let bytes = gdb.read(addr, len)?;
        if let Some(i) = bytes.windows(ID.len()).position(|w| w == ID) {
            return Ok(addr + i as u32);
        }
        addr += len.saturating_sub(overlap).max(1);
        if len < SEARCH_CHUNK {
            break;
        }
    }
    bail!(
        "no RTT block (id \"SEGGER RTT\") in RAM {:#010x}..{:#010x}: is the firmware running?",
        RAM.start,
        RAM.end
    )
}

fn io_error(e: anyhow::Error) -> std::io::Error {
    std::io::Error::other(format!("{e:#}"))
}

impl Read for GdbRtt {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let deadline = Instant::now() + self.timeout;
        while self.received.is_empty() {
            self.poll().map_err(io_error)?;
            if !self.received.is_empty() {
                break;
            }
            if Instant::now() >= deadline {
                return Err(ErrorKind::WouldBlock.into());
            }
            std::thread::sleep(POLL_PERIOD);
        }
        let n = buf.len().min(self.received.len());
        for (slot, b) in buf.iter_mut().zip(self.received.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

impl Write for GdbRtt {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.queued.extend(buf);
        Ok(buf.len())
    }

    /// Poll until the firmware has taken every queued byte (or the read
    /// timeout has passed: it reads its channel every control tick).
    fn flush(&mut self) -> std::io::Result<()> {
        let deadline = Instant::now() + self.timeout.max(Duration::from_millis(500));
        while !self.queued.is_empty() {
            self.poll().map_err(io_error)?;
            if self.queued.is_empty() {
                break;
            }
            if Instant::now() >= deadline {
                return Err(ErrorKind::TimedOut.into());
            }
            std::thread::sleep(POLL_PERIOD);
        }
        Ok(())
    }
}

impl Port for GdbRtt {
    fn set_timeout(&mut self, timeout: Duration) -> std::io::Result<()> {
        self.timeout = timeout;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    /// A GDB server over a fake target's RAM whose "firmware", each time
    /// the machine runs, echoes what the host wrote to down channel 1 into
    /// up channel 1 (through the core's `Ring`, as the firmware does).
    struct FakeTarget {
        ram: Vec<u8>,
        block: Option<u32>,
    }

    const BLOCK: u32 = 0x2001_0004;
    const UP_BUF: u32 = 0x2000_1000;
    const DOWN_BUF: u32 = 0x2000_2000;
    const UP_LEN: u32 = 300;
    const DOWN_LEN: u32 = 200;

    impl FakeTarget {
        fn new(with_block: bool) -> Self {
            let mut t = Self {
                ram: vec![0; (RAM.end - RAM.start) as usize],
                block: with_block.then_some(BLOCK),
            };
            if with_block {
                t.put(BLOCK, &ID);
                t.word(BLOCK + MAX_UP_OFFSET, UP_CHANNELS);
                t.word(BLOCK + MAX_DOWN_OFFSET, DOWN_CHANNELS);
                let up = BLOCK + up_offset(LINK_CHANNEL);
                t.word(up + field::BUFFER, UP_BUF);
                t.word(up + field::SIZE, UP_LEN);
                let down = BLOCK + down_offset(UP_CHANNELS, LINK_CHANNEL);
                t.word(down + field::BUFFER, DOWN_BUF);
                t.word(down + field::SIZE, DOWN_LEN);
            }
            t
        }
        fn at(addr: u32) -> usize {
            (addr - RAM.start) as usize
        }
        fn put(&mut self, addr: u32, bytes: &[u8]) {
            let a = Self::at(addr);
            self.ram[a..a + bytes.len()].copy_from_slice(bytes);
        }
        fn word(&mut self, addr: u32, v: u32) {
            self.put(addr, &v.to_le_bytes());
        }
        fn get(&self, addr: u32) -> u32 {
            let a = Self::at(addr);
            u32::from_le_bytes(self.ram[a..a + 4].try_into().unwrap())
        }
        fn ring(&self, descriptor: u32, size: u32) -> Ring {
            Ring {
                size,
                write: self.get(descriptor + field::WRITE),
                read: self.get(descriptor + field::READ),
            }
        }
        /// The firmware's turn: move what fits from down 1 to up 1.
        fn run(&mut self) {
            let Some(block) = self.block else { return };
            let up = block + up_offset(LINK_CHANNEL);
            let down = block + down_offset(UP_CHANNELS, LINK_CHANNEL);
            let free = self.ring(up, UP_LEN).writable();
            let t = self.ring(down, DOWN_LEN).read(free.min(37));
            let mut bytes = Vec::new();
            for s in [t.first, t.second] {
                let a = Self::at(DOWN_BUF + s.start);
                bytes.extend_from_slice(&self.ram[a..a + s.len as usize]);
            }
            self.word(down + field::READ, t.next);
            let w = self.ring(up, UP_LEN).write_all(bytes.len() as u32).unwrap();
            let (x, y) = bytes.split_at(w.first.len as usize);
            self.put(UP_BUF + w.first.start, x);
            self.put(UP_BUF, y);
            self.word(up + field::WRITE, w.next);
        }
    }

    fn packet(data: &str) -> Vec<u8> {
        let sum = data.bytes().fold(0u8, |s, b| s.wrapping_add(b));
        format!("${data}#{sum:02x}").into_bytes()
    }

    /// Serve one connection: a stop reply on attach (as QEMU sends), then
    /// `?`, `m`, `M`, `c` and the interrupt byte.
    fn serve(mut target: FakeTarget) -> (String, std::thread::JoinHandle<()>) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let handle = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            s.set_nodelay(true).unwrap();
            s.write_all(&packet("T02thread:01;")).unwrap();
            let mut pending = Vec::new();
            let mut buf = [0u8; 8192];
            loop {
                let n = match s.read(&mut buf) {
                    Ok(0) | Err(_) => return,
                    Ok(n) => n,
                };
                pending.extend_from_slice(&buf[..n]);
                loop {
                    match pending.first() {
                        None => break,
                        Some(b'+') => {
                            pending.remove(0);
                        }
                        Some(0x03) => {
                            pending.remove(0);
                            s.write_all(&packet("T02thread:01;")).unwrap();
                        }
                        Some(b'$') => {
                            let Some(end) = pending.iter().position(|&b| b == b'#') else {
                                break;
                            };
                            if pending.len() < end + 3 {
                                break;
                            }
                            let data = String::from_utf8(pending[1..end].to_vec()).unwrap();
                            pending.drain(..end + 3);
                            s.write_all(b"+").unwrap();
                            let reply = match data.as_bytes()[0] {
                                b'?' => Some("S05".to_owned()),
                                b'c' => {
                                    target.run();
                                    None
                                }
                                b'm' => {
                                    let (a, l) = data[1..].split_once(',').unwrap();
                                    let a = u32::from_str_radix(a, 16).unwrap();
                                    let l = u32::from_str_radix(l, 16).unwrap();
                                    let i = FakeTarget::at(a);
                                    Some(
                                        target.ram[i..i + l as usize]
                                            .iter()
                                            .map(|b| format!("{b:02x}"))
                                            .collect(),
                                    )
                                }
                                b'M' => {
                                    let (head, hex) = data[1..].split_once(':').unwrap();
                                    let a =
                                        u32::from_str_radix(head.split(',').next().unwrap(), 16)
                                            .unwrap();
                                    let bytes: Vec<u8> = (0..hex.len())
                                        .step_by(2)
                                        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
                                        .collect();
                                    target.put(a, &bytes);
                                    Some("OK".to_owned())
                                }
                                _ => Some(String::new()),
                            };
                            if let Some(r) = reply {
                                s.write_all(&packet(&r)).unwrap();
                            }
                        }
                        Some(_) => {
                            pending.remove(0);
                        }
                    }
                }
            }
        });
        (addr, handle)
    }

    #[test]
    fn bytes_go_down_and_come_back_up_in_order_across_wraps() {
        let (addr, server) = serve(FakeTarget::new(true));
        let mut port = GdbRtt::connect(&addr).unwrap();
        port.set_timeout(Duration::from_millis(200)).unwrap();
        // Five times the down buffer: many polls, every ring wrapping.
        let sent: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        port.write_all(&sent).unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        let deadline = Instant::now() + Duration::from_secs(20);
        while got.len() < sent.len() && Instant::now() < deadline {
            match port.read(&mut buf) {
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                Err(e) => panic!("{e}"),
            }
        }
        assert_eq!(got, sent);
        drop(port);
        server.join().unwrap();
    }

    #[test]
    fn a_target_without_the_block_is_named_as_such() {
        let (addr, _server) = serve(FakeTarget::new(false));
        let err = GdbRtt::connect(&addr).err().expect("no block to find");
        let text = format!("{err:#}");
        assert!(text.contains("no RTT block"), "{text}");
    }
}
