//! Register-level USART for the host link (both boards) and the PIL build's
//! sensor bus: receive by interrupt, transmit by polling.
//!
//! Registers, not the HAL's serial driver, because the same code must run on
//! QEMU, which has no clock model (the HAL's set-up would wait for a PLL
//! that never locks). The board enables the peripheral's clock and its pins
//! before [`start`]; QEMU needs neither.
//!
//! Transmission polls TXE from the caller's priority: the link's senders are
//! the priority-1 tasks (never the tick), and on QEMU the byte leaves at
//! once. At 460 800 baud a 70-byte telemetry frame takes 1.5 ms, which only
//! the idle loop and the other priority-1 tasks wait for.

use cable_joint::link::{encode, Up};
use cable_joint::telemetry::MAX_RECORD_LEN;
use stm32f4xx_hal::pac::usart1::RegisterBlock;

const SR_ORE: u16 = 1 << 3;
const SR_RXNE: u16 = 1 << 5;
const SR_TXE: u16 = 1 << 7;
const CR1_RE: u16 = 1 << 2;
const CR1_TE: u16 = 1 << 3;
const CR1_RXNEIE: u16 = 1 << 5;
const CR1_UE: u16 = 1 << 13;

/// One USART's register block (USART1/2/3/6 share the layout).
#[derive(Clone, Copy)]
struct Regs(*const RegisterBlock);

// SAFETY: the pointer is a fixed peripheral address; each half below touches
// only its own direction's bits (RX reads SR/DR, TX polls SR and writes DR),
// which the hardware keeps apart.
unsafe impl Send for Regs {}

impl Regs {
    fn get(&self) -> &RegisterBlock {
        // SAFETY: a valid, always-mapped peripheral address.
        unsafe { &*self.0 }
    }
}

/// The receiving half, owned by the USART's interrupt task.
pub struct Rx(Regs);

/// The transmitting half.
pub struct Tx(Regs);

/// Enable `regs` at `brr` (the bus clock over the baud rate; QEMU ignores
/// it): 8N1, receiver, transmitter and the receive interrupt on.
pub fn start(regs: *const RegisterBlock, brr: u16) -> (Tx, Rx) {
    let r = Regs(regs);
    // SAFETY: plain register values: BRR's 16 bits and CR1's enable bits.
    r.get().brr().write(|w| unsafe { w.bits(brr) });
    r.get()
        .cr1()
        .write(|w| unsafe { w.bits(CR1_UE | CR1_TE | CR1_RE | CR1_RXNEIE) });
    (Tx(r), Rx(r))
}

impl Rx {
    /// The receiving half of `regs`, for a task-local resource (which
    /// RTIC builds in a `const` context). The caller owns that USART's
    /// receive side: nothing else may read its data register.
    pub const fn steal(regs: *const RegisterBlock) -> Self {
        Rx(Regs(regs))
    }

    /// The next received byte, if any. An overrun (a byte lost because the
    /// interrupt came too late) is cleared by the same SR-then-DR read; the
    /// frame it broke fails its CRC and is refused.
    #[inline]
    pub fn read(&mut self) -> Option<u8> {
        let regs = self.0.get();
        let sr = regs.sr().read().bits();
        if sr & (SR_RXNE | SR_ORE) == 0 {
            return None;
        }
        let byte = regs.dr().read().bits() as u8;
        (sr & SR_RXNE != 0).then_some(byte)
    }
}

impl Tx {
    /// Send `bytes`, waiting for the data register before each.
    pub fn write_all(&mut self, bytes: &[u8]) {
        let regs = self.0.get();
        for &b in bytes {
            while regs.sr().read().bits() & SR_TXE == 0 {}
            // SAFETY: DR takes any 8-bit value.
            regs.dr().write(|w| unsafe { w.bits(u16::from(b)) });
        }
    }
}

/// The link's frames out of a USART, numbered in order.
pub struct FrameTx {
    tx: Tx,
    seq: u8,
}

impl FrameTx {
    /// Frames out of `tx`, numbered from 0.
    pub fn new(tx: Tx) -> Self {
        Self { tx, seq: 0 }
    }

    /// Send `msg` as the next frame: an acknowledgement or a telemetry
    /// record (a message that does not fit two records' bytes is not sent).
    pub fn send(&mut self, msg: &Up) {
        let mut wire = [0u8; 2 * MAX_RECORD_LEN];
        if let Ok(frame) = encode(msg, self.seq, &mut wire) {
            self.tx.write_all(frame);
        }
        self.seq = self.seq.wrapping_add(1);
    }
}
