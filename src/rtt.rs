//! SEGGER RTT as the firmware lays it out in RAM, and the ring arithmetic
//! both ends of a channel share.
//!
//! RTT is a block of RAM that a debug probe reads and writes while the MCU
//! runs: a header (the id `"SEGGER RTT"`, the number of up and down
//! channels), then one descriptor per channel (name, buffer, size, write
//! offset, read offset, flags), each channel a ring buffer. The writer of a
//! ring owns its write offset and the reader its read offset, so neither
//! side needs a lock. The firmware's block (`src/bin/firmware/rtt.rs`):
//!
//! | channel | up (MCU → host) | down (host → MCU) |
//! |---|---|---|
//! | 0 | `defmt`: the log and telemetry lines (defmt-print, probe-rs) | unused |
//! | 1 | `link`: the link's frames ([`crate::link`]) | `link`: the link's frames |
//!
//! so the link is one channel number both ways, as OpenOCD's `rtt server
//! start PORT 1` serves it on a TCP port, and `host-sim` reaches it through
//! a GDB server under QEMU (`host_sim::rtt`).
//!
//! This module holds what both ends must agree on: the layout of the block
//! on the 32-bit target ([`HEADER_LEN`], [`CHANNEL_LEN`], [`field`]) and
//! where the bytes of a read or a write go ([`Ring`]). The offsets in a ring
//! come from the other side of the probe and are checked here: a ring whose
//! offsets are out of range reads as empty and takes nothing.

/// The block's id, the first 16 bytes of the header.
pub const ID: [u8; 16] = *b"SEGGER RTT\0\0\0\0\0\0";

/// Bytes of the header: the id, then the numbers of up and down channels
/// (`i32` each).
pub const HEADER_LEN: u32 = 24;

/// Bytes of one channel descriptor on a 32-bit target.
pub const CHANNEL_LEN: u32 = 24;

/// Offset of the number of up channels in the header.
pub const MAX_UP_OFFSET: u32 = 16;

/// Offset of the number of down channels in the header.
pub const MAX_DOWN_OFFSET: u32 = 20;

/// Offsets of a channel descriptor's fields (`u32` each on the target).
pub mod field {
    /// Address of the channel's name (a C string).
    pub const NAME: u32 = 0;
    /// Address of the ring buffer.
    pub const BUFFER: u32 = 4;
    /// Size of the ring buffer, bytes.
    pub const SIZE: u32 = 8;
    /// Write offset (owned by the writer).
    pub const WRITE: u32 = 12;
    /// Read offset (owned by the reader).
    pub const READ: u32 = 16;
    /// Mode flags (the firmware never blocks, whatever they say).
    pub const FLAGS: u32 = 20;
}

/// Up channels of the firmware's block.
pub const UP_CHANNELS: u32 = 2;

/// Down channels of the firmware's block.
pub const DOWN_CHANNELS: u32 = 2;

/// The up channel of the defmt stream.
pub const DEFMT_CHANNEL: u32 = 0;

/// The channel of the host link, up and down.
pub const LINK_CHANNEL: u32 = 1;

/// Offset of up channel `i`'s descriptor from the block's start.
pub const fn up_offset(i: u32) -> u32 {
    HEADER_LEN + i * CHANNEL_LEN
}

/// Offset of down channel `i`'s descriptor from the block's start, in a
/// block of `max_up` up channels.
pub const fn down_offset(max_up: u32, i: u32) -> u32 {
    HEADER_LEN + (max_up + i) * CHANNEL_LEN
}

/// A contiguous run of a ring buffer: `len` bytes from offset `start`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    /// First byte, offset in the buffer.
    pub start: u32,
    /// Bytes.
    pub len: u32,
}

/// Where the bytes of one read or write go: at most two runs (the second
/// after the wrap), and the offset the owner stores afterwards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transfer {
    /// The run up to the end of the buffer.
    pub first: Span,
    /// The run from the start of the buffer (empty without a wrap).
    pub second: Span,
    /// The owner's new offset.
    pub next: u32,
}

impl Transfer {
    /// Bytes moved.
    pub const fn len(&self) -> u32 {
        self.first.len + self.second.len
    }

    /// Nothing moves.
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One ring's state as read from its descriptor.
///
/// One byte always stays free, so `write == read` means empty: a ring of
/// `size` bytes holds at most `size - 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ring {
    /// Buffer size, bytes.
    pub size: u32,
    /// Next byte the writer fills.
    pub write: u32,
    /// Next byte the reader takes.
    pub read: u32,
}

impl Ring {
    /// Offsets inside the buffer and a buffer that can hold a byte. A ring
    /// that is not valid (the other side wrote nonsense, or the block is not
    /// set up yet) reads as empty and takes nothing.
    pub const fn is_valid(&self) -> bool {
        self.size >= 2 && self.write < self.size && self.read < self.size
    }

    /// Bytes waiting to be read.
    pub const fn readable(&self) -> u32 {
        if !self.is_valid() {
            0
        } else if self.write >= self.read {
            self.write - self.read
        } else {
            self.size - self.read + self.write
        }
    }

    /// Bytes that can be written without overtaking the reader.
    pub const fn writable(&self) -> u32 {
        if !self.is_valid() {
            0
        } else {
            self.size - 1 - self.readable()
        }
    }

    /// `n` bytes from offset `from`, wrapped at the end of the buffer
    /// (`n < size`).
    const fn runs(&self, from: u32, n: u32) -> Transfer {
        if n == 0 {
            // Also the path of an invalid ring, whose `from` may be anywhere.
            let none = Span {
                start: from,
                len: 0,
            };
            return Transfer {
                first: none,
                second: Span { start: 0, len: 0 },
                next: from,
            };
        }
        let to_end = self.size - from;
        let first = if n < to_end { n } else { to_end };
        let second = n - first;
        let next = if second > 0 { second } else { from + first };
        let next = if next == self.size { 0 } else { next };
        Transfer {
            first: Span {
                start: from,
                len: first,
            },
            second: Span {
                start: 0,
                len: second,
            },
            next,
        }
    }

    /// Where `n` bytes go if the writer writes them all, or `None` if they
    /// do not all fit (a frame is written whole or not at all).
    pub const fn write_all(&self, n: u32) -> Option<Transfer> {
        if n > self.writable() {
            None
        } else {
            Some(self.runs(self.write, n))
        }
    }

    /// Where the writer puts as many of `n` bytes as fit.
    pub const fn write_some(&self, n: u32) -> Transfer {
        let free = self.writable();
        self.runs(self.write, if n < free { n } else { free })
    }

    /// Where the reader takes at most `max` of the waiting bytes from.
    pub const fn read(&self, max: u32) -> Transfer {
        let waiting = self.readable();
        self.runs(self.read, if max < waiting { max } else { waiting })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// A ring and its buffer, both ends driven through [`Ring`] as the
    /// firmware and the host do.
    struct Model {
        buf: Vec<u8>,
        write: u32,
        read: u32,
    }

    impl Model {
        fn new(size: usize) -> Self {
            Self {
                buf: std::vec![0; size],
                write: 0,
                read: 0,
            }
        }
        fn ring(&self) -> Ring {
            Ring {
                size: self.buf.len() as u32,
                write: self.write,
                read: self.read,
            }
        }
        fn put(&mut self, t: &Transfer, bytes: &[u8]) {
            let (a, b) = bytes.split_at(t.first.len as usize);
            let s = t.first.start as usize;
            self.buf[s..s + a.len()].copy_from_slice(a);
            self.buf[..b.len()].copy_from_slice(b);
            self.write = t.next;
        }
        fn write_some(&mut self, bytes: &[u8]) -> usize {
            let t = self.ring().write_some(bytes.len() as u32);
            self.put(&t, &bytes[..t.len() as usize]);
            t.len() as usize
        }
        fn read(&mut self, max: usize) -> Vec<u8> {
            let t = self.ring().read(max as u32);
            let mut out = Vec::new();
            for s in [t.first, t.second] {
                out.extend_from_slice(&self.buf[s.start as usize..(s.start + s.len) as usize]);
            }
            self.read = t.next;
            out
        }
    }

    #[test]
    fn layout_is_segger_rtt_on_a_32_bit_target() {
        assert_eq!(&ID[..10], b"SEGGER RTT");
        assert_eq!(up_offset(0), 24);
        assert_eq!(up_offset(1), 48);
        assert_eq!(down_offset(UP_CHANNELS, 0), 72);
        assert_eq!(down_offset(UP_CHANNELS, LINK_CHANNEL), 96);
        assert_eq!(field::FLAGS + 4, CHANNEL_LEN);
    }

    #[test]
    fn a_ring_holds_one_byte_less_than_its_size() {
        let mut m = Model::new(8);
        assert_eq!(m.ring().writable(), 7);
        assert_eq!(m.write_some(&[1; 10]), 7);
        assert_eq!(m.ring().readable(), 7);
        assert_eq!(m.ring().writable(), 0);
        assert_eq!(m.ring().write_all(1), None);
        assert_eq!(m.read(100), std::vec![1; 7]);
        assert_eq!(m.ring().readable(), 0);
    }

    #[test]
    fn bytes_come_out_in_order_across_every_wrap() {
        // Every write and read size against a small ring: the stream read is
        // the stream written, and the ring never claims more than it holds.
        for size in 2..12usize {
            for chunk in 1..size + 2 {
                for take in 1..size + 2 {
                    let mut m = Model::new(size);
                    let mut sent = Vec::new();
                    let mut got = Vec::new();
                    let mut next = 0u8;
                    for _ in 0..40 {
                        let bytes: Vec<u8> =
                            (0..chunk).map(|i| next.wrapping_add(i as u8)).collect();
                        let n = m.write_some(&bytes);
                        sent.extend_from_slice(&bytes[..n]);
                        next = next.wrapping_add(n as u8);
                        assert!(m.ring().readable() < size as u32);
                        got.extend(m.read(take));
                    }
                    got.extend(m.read(size));
                    assert_eq!(got, sent, "size {size}, chunk {chunk}, take {take}");
                }
            }
        }
    }

    #[test]
    fn a_frame_goes_whole_or_not_at_all() {
        let mut m = Model::new(16);
        m.write = 12;
        m.read = 12;
        let t = m.ring().write_all(10).unwrap();
        assert_eq!(t.first, Span { start: 12, len: 4 });
        assert_eq!(t.second, Span { start: 0, len: 6 });
        assert_eq!(t.next, 6);
        m.put(&t, &[7; 10]);
        assert_eq!(m.ring().write_all(6), None);
        assert!(m.ring().write_all(5).is_some());
    }

    #[test]
    fn offsets_out_of_range_read_as_empty_and_take_nothing() {
        for (size, write, read) in [
            (16, 16, 0),
            (16, 0, 99),
            (1, 0, 0),
            (0, 0, 0),
            (16, u32::MAX, 3),
        ] {
            let r = Ring { size, write, read };
            assert!(!r.is_valid());
            assert_eq!(r.readable(), 0);
            assert_eq!(r.writable(), 0);
            assert!(r.read(10).is_empty());
            assert!(r.write_some(10).is_empty());
            assert_eq!(r.write_all(1), None);
        }
    }
}
