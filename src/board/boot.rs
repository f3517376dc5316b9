//! Why the MCU last reset, told at the next boot.
//!
//! A panic or HardFault handler cuts the drive, then [`record`]s its fault in
//! two words of RAM that the start-up code does not initialise (cortex-m-rt's
//! `.uninit` section) and resets the MCU. At the next boot the firmware reads
//! the words back with [`recorded`] and the reset-cause flags, and
//! [`boot_fault`] names the fault to latch: the controller starts with it, so
//! the drive stays off until an operator clears it, and telemetry carries the
//! code from the first record on.
//!
//! The second word is the first one's check (`code ^ MAGIC`): RAM after a
//! power-up holds noise, which passes the check with odds of one in 2³².

use crate::fault::Fault;

/// Check pattern of the boot note.
pub const MAGIC: u32 = 0x4A4F_494E;

/// The two words a handler leaves for the next boot.
pub fn record(fault: Fault) -> [u32; 2] {
    let code = u32::from(fault.code());
    [code, code ^ MAGIC]
}

/// The fault a handler left, if the words hold a valid note.
pub fn recorded(words: [u32; 2]) -> Option<Fault> {
    let [code, check] = words;
    if code ^ MAGIC != check || code > u32::from(u8::MAX) {
        return None;
    }
    Fault::from_code(code as u8)
}

/// The fault to latch at boot: a note left by a handler first (it says
/// more), else the independent watchdog's reset flag.
pub fn boot_fault(note: Option<Fault>, watchdog_reset: bool) -> Option<Fault> {
    note.or(watchdog_reset.then_some(Fault::Watchdog))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recorded_fault_is_read_back_and_noise_is_not() {
        for f in [Fault::Panic, Fault::HardFault] {
            assert_eq!(recorded(record(f)), Some(f));
        }
        assert_eq!(recorded([0, 0]), None, "zeroed RAM");
        assert_eq!(recorded([30, 0xdead_beef]), None, "check fails");
        let big = 0x1_0000u32;
        assert_eq!(recorded([big, big ^ MAGIC]), None, "not a code");
        assert_eq!(recorded([5, 5 ^ MAGIC]), None, "retired code");
    }

    #[test]
    fn boot_fault_prefers_the_note_and_names_the_watchdog() {
        assert_eq!(boot_fault(None, false), None);
        assert_eq!(boot_fault(None, true), Some(Fault::Watchdog));
        assert_eq!(boot_fault(Some(Fault::Panic), true), Some(Fault::Panic));
    }
}
