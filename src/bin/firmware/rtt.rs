//! The RTT control block (`_SEGGER_RTT`, layout and ring arithmetic in
//! `cable_joint::rtt`): the defmt log on up channel 0 (the board's global
//! logger; QEMU builds log over semihosting and leave it empty), the host
//! link on channel 1 both ways.
//!
//! A debug probe reads and writes this block while the MCU runs. The
//! firmware never trusts what it finds there beyond the two offsets the
//! probe owns: each handle below keeps its buffer's address and length from
//! this file, and `cable_joint::rtt::Ring` reads offsets out of range as an
//! empty ring. Nothing here blocks: a full up channel drops what does not
//! fit (a link frame whole), as a slow or absent host must never stall the
//! MCU.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering};

use cable_joint::link::{encode, Up};
use cable_joint::rtt::{Ring, Transfer, DOWN_CHANNELS, ID, UP_CHANNELS};
use cable_joint::telemetry::MAX_RECORD_LEN;

/// defmt up channel, bytes: 30 ms of the hardware's telemetry lines.
const DEFMT_LEN: usize = 1024;
/// Link up channel, bytes: a few dozen telemetry frames.
const LINK_UP_LEN: usize = 2048;
/// Link down channel, bytes: a whole configuration frame and more.
const LINK_DOWN_LEN: usize = 1024;
/// Down channel 0 exists only so that the link is channel 1 both ways.
const UNUSED_DOWN_LEN: usize = 16;

/// A ring buffer in RAM, written through raw pointers by its one writer
/// and read by the probe.
#[repr(transparent)]
struct Buffer<const N: usize>(UnsafeCell<[u8; N]>);

// SAFETY: each buffer has one writer (its handle) and one reader; the ring
// offsets (atomics) order their accesses.
unsafe impl<const N: usize> Sync for Buffer<N> {}

impl<const N: usize> Buffer<N> {
    const fn new() -> Self {
        Self(UnsafeCell::new([0; N]))
    }
    const fn ptr(&'static self) -> *mut u8 {
        self.0.get().cast()
    }
}

/// A channel descriptor, SEGGER's layout on a 32-bit target.
#[repr(C)]
struct Channel {
    name: *const u8,
    buffer: *mut u8,
    size: u32,
    write: AtomicU32,
    read: AtomicU32,
    flags: AtomicU32,
}

impl Channel {
    const fn new(name: &'static [u8], buffer: *mut u8, size: usize) -> Self {
        Self {
            name: name.as_ptr(),
            buffer,
            size: size as u32,
            write: AtomicU32::new(0),
            read: AtomicU32::new(0),
            flags: AtomicU32::new(0),
        }
    }
}

/// The control block.
#[repr(C)]
struct ControlBlock {
    id: [u8; 16],
    max_up: i32,
    max_down: i32,
    up: [Channel; UP_CHANNELS as usize],
    down: [Channel; DOWN_CHANNELS as usize],
}

// SAFETY: the descriptors' pointers are fixed addresses of the buffers
// below; everything the firmware changes at run time is an atomic.
unsafe impl Sync for ControlBlock {}

static DEFMT_BUF: Buffer<DEFMT_LEN> = Buffer::new();
static LINK_UP_BUF: Buffer<LINK_UP_LEN> = Buffer::new();
static LINK_DOWN_BUF: Buffer<LINK_DOWN_LEN> = Buffer::new();
static UNUSED_DOWN_BUF: Buffer<UNUSED_DOWN_LEN> = Buffer::new();

/// Found by the probe through this symbol (probe-rs) or by its id in RAM
/// (OpenOCD's `rtt setup`, `host-sim`'s GDB bridge). Initialised data, so
/// the id is in place before `main` and no half-built block is ever seen.
#[no_mangle]
static _SEGGER_RTT: ControlBlock = ControlBlock {
    id: ID,
    max_up: UP_CHANNELS as i32,
    max_down: DOWN_CHANNELS as i32,
    up: [
        Channel::new(b"defmt\0", DEFMT_BUF.ptr(), DEFMT_LEN),
        Channel::new(b"link\0", LINK_UP_BUF.ptr(), LINK_UP_LEN),
    ],
    down: [
        Channel::new(b"unused\0", UNUSED_DOWN_BUF.ptr(), UNUSED_DOWN_LEN),
        Channel::new(b"link\0", LINK_DOWN_BUF.ptr(), LINK_DOWN_LEN),
    ],
};

/// One end of one channel: its descriptor's offsets, and the buffer's
/// address and length as this file knows them.
struct End {
    channel: &'static Channel,
    buffer: *mut u8,
    len: u32,
}

// SAFETY: an `End` is the only owner of its side of the channel (see the
// constructors); moving it to another task moves that ownership.
unsafe impl Send for End {}

impl End {
    /// The ring as it stands: both offsets acquired, so the bytes the
    /// other side handed over are visible before they are used.
    fn ring(&self) -> Ring {
        Ring {
            size: self.len,
            write: self.channel.write.load(Ordering::Acquire),
            read: self.channel.read.load(Ordering::Acquire),
        }
    }

    /// Copy `bytes` into the runs of `t`, then publish the write offset.
    fn put(&mut self, t: &Transfer, bytes: &[u8]) {
        let (a, b) = bytes.split_at(t.first.len as usize);
        // SAFETY: `Ring` keeps both runs inside `len` bytes of `buffer`, a
        // static of that length this end alone writes (the reader only
        // reads bytes before the write offset, published below).
        unsafe {
            core::ptr::copy_nonoverlapping(
                a.as_ptr(),
                self.buffer.add(t.first.start as usize),
                a.len(),
            );
            core::ptr::copy_nonoverlapping(b.as_ptr(), self.buffer, b.len());
        }
        self.channel.write.store(t.next, Ordering::Release);
    }

    /// Write as much of `bytes` as fits; returns how much did.
    // The defmt logger's: the QEMU builds log over semihosting.
    #[cfg_attr(feature = "qemu", allow(dead_code))]
    fn write_some(&mut self, bytes: &[u8]) -> usize {
        let t = self.ring().write_some(bytes.len() as u32);
        self.put(&t, &bytes[..t.len() as usize]);
        t.len() as usize
    }

    /// Write all of `bytes`, or nothing if they do not fit.
    fn write_all(&mut self, bytes: &[u8]) -> bool {
        match self.ring().write_all(bytes.len() as u32) {
            Some(t) => {
                self.put(&t, bytes);
                true
            }
            None => false,
        }
    }

    /// Take up to `out.len()` waiting bytes; returns how many.
    fn read(&mut self, out: &mut [u8]) -> usize {
        let t = self.ring().read(out.len() as u32);
        let (a, b) = out.split_at_mut(t.first.len as usize);
        // SAFETY: `Ring` keeps both runs inside `len` bytes of `buffer`; the
        // writer (the probe) does not touch bytes before its write offset
        // until this end moves the read offset past them, below.
        unsafe {
            core::ptr::copy_nonoverlapping(
                self.buffer.add(t.first.start as usize),
                a.as_mut_ptr(),
                a.len(),
            );
            core::ptr::copy_nonoverlapping(self.buffer, b.as_mut_ptr(), t.second.len as usize);
        }
        self.channel.read.store(t.next, Ordering::Release);
        t.len() as usize
    }
}

/// The link's up channel: its frames, numbered in order.
pub struct FrameTx {
    end: End,
    seq: u8,
}

impl FrameTx {
    /// The link's up channel. Call once: the handle is its only writer.
    pub fn take() -> Self {
        Self {
            end: End {
                channel: &_SEGGER_RTT.up[cable_joint::rtt::LINK_CHANNEL as usize],
                buffer: LINK_UP_BUF.ptr(),
                len: LINK_UP_LEN as u32,
            },
            seq: 0,
        }
    }

    /// Send `msg` as the next frame, whole, or drop it when the host has
    /// not made room (an absent host costs the encoding only).
    pub fn send(&mut self, msg: &Up) {
        let mut wire = [0u8; 2 * MAX_RECORD_LEN];
        if let Ok(frame) = encode(msg, self.seq, &mut wire) {
            self.end.write_all(frame);
        }
        self.seq = self.seq.wrapping_add(1);
    }
}

/// The link's down channel, read by the idle loop.
pub struct Rx {
    end: End,
}

impl Rx {
    /// The link's down channel. Call once: the handle is its only reader.
    pub fn take() -> Self {
        Self {
            end: End {
                channel: &_SEGGER_RTT.down[cable_joint::rtt::LINK_CHANNEL as usize],
                buffer: LINK_DOWN_BUF.ptr(),
                len: LINK_DOWN_LEN as u32,
            },
        }
    }

    /// Take up to `out.len()` bytes the host has written; returns how many.
    pub fn read(&mut self, out: &mut [u8]) -> usize {
        self.end.read(out)
    }
}

/// The defmt global logger on up channel 0 (the board only).
///
/// Never blocks, never masks an interrupt: a frame that does not fit is cut
/// (the decoder resyncs at the next frame), and a frame logged by a task
/// that preempted another task's frame is dropped (nesting depth above 1),
/// as defmt-rtt's `drop-on-contention` does.
#[cfg(not(feature = "qemu"))]
mod logger {
    use core::sync::atomic::{AtomicU8, Ordering};

    use super::{End, _SEGGER_RTT, DEFMT_BUF, DEFMT_LEN};

    /// Frames open, counting preempting ones: only depth 1 writes.
    static DEPTH: AtomicU8 = AtomicU8::new(0);

    /// Owned by whoever holds depth 1.
    struct Shared {
        encoder: defmt::Encoder,
        end: End,
    }

    struct Cell(core::cell::UnsafeCell<Shared>);
    // SAFETY: only the holder of depth 1 touches it, and on a single core a
    // preempting task ends (and leaves depth 1) before the holder resumes.
    unsafe impl Sync for Cell {}

    static SHARED: Cell = Cell(core::cell::UnsafeCell::new(Shared {
        encoder: defmt::Encoder::new(),
        end: End {
            channel: &_SEGGER_RTT.up[cable_joint::rtt::DEFMT_CHANNEL as usize],
            buffer: DEFMT_BUF.ptr(),
            len: DEFMT_LEN as u32,
        },
    }));

    /// The logger's state, for the holder of depth 1.
    ///
    /// # Safety
    /// The caller holds depth 1 (see [`Cell`]).
    #[allow(clippy::mut_from_ref)]
    unsafe fn shared() -> &'static mut Shared {
        // SAFETY: exclusive by the caller's contract.
        unsafe { &mut *SHARED.0.get() }
    }

    #[defmt::global_logger]
    struct Logger;

    // SAFETY: `acquire`/`release` bracket every frame; only depth 1 encodes.
    unsafe impl defmt::Logger for Logger {
        fn acquire() {
            if DEPTH.fetch_add(1, Ordering::Acquire) == 0 {
                // SAFETY: depth 1 is ours.
                let s = unsafe { shared() };
                s.encoder.start_frame(|b| {
                    s.end.write_some(b);
                });
            }
        }

        unsafe fn flush() {}

        unsafe fn release() {
            if DEPTH.load(Ordering::Relaxed) == 1 {
                // SAFETY: depth 1 is ours.
                let s = unsafe { shared() };
                s.encoder.end_frame(|b| {
                    s.end.write_some(b);
                });
            }
            DEPTH.fetch_sub(1, Ordering::Release);
        }

        unsafe fn write(bytes: &[u8]) {
            if DEPTH.load(Ordering::Relaxed) == 1 {
                // SAFETY: depth 1 is ours.
                let s = unsafe { shared() };
                s.encoder.write(bytes, |b| {
                    s.end.write_some(b);
                });
            }
        }
    }
}
