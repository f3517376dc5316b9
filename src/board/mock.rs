//! Mock pins for host tests: they count calls (moteus-style) and share their
//! state between clones so a test keeps a handle on a pin it moved away.

use std::cell::Cell;
use std::rc::Rc;

use core::convert::Infallible;

use embedded_hal::digital::{Error, ErrorKind, ErrorType, InputPin, OutputPin};

use super::io::{DriveKill, Events};
use crate::fault::Fault;

#[derive(Debug, Default)]
struct OutState {
    high: Cell<bool>,
    highs: Cell<u32>,
    lows: Cell<u32>,
}

/// An output pin that counts `set_high` / `set_low` calls.
#[derive(Clone, Debug, Default)]
pub struct MockOut {
    state: Rc<OutState>,
    fault_on_high: Option<&'static Events>,
}

impl MockOut {
    /// Raise a drive fault in `events` whenever the pin is driven high (a
    /// fault task preempting right after the write).
    pub fn with_fault_on_high(mut self, events: &'static Events) -> Self {
        self.fault_on_high = Some(events);
        self
    }
    pub fn is_high(&self) -> bool {
        self.state.high.get()
    }
    pub fn high_count(&self) -> u32 {
        self.state.highs.get()
    }
    pub fn low_count(&self) -> u32 {
        self.state.lows.get()
    }
}

impl ErrorType for MockOut {
    type Error = Infallible;
}

impl OutputPin for MockOut {
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.state.high.set(true);
        self.state.highs.set(self.state.highs.get() + 1);
        if let Some(ev) = self.fault_on_high {
            ev.raise(Fault::DriveFault);
        }
        Ok(())
    }
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.state.high.set(false);
        self.state.lows.set(self.state.lows.get() + 1);
        Ok(())
    }
}

/// A read error of a mock input.
#[derive(Debug)]
pub struct ReadError;

impl Error for ReadError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// An input pin whose level the test sets.
#[derive(Clone, Debug)]
pub struct MockIn {
    level: Rc<Cell<bool>>,
    fail: bool,
}

impl MockIn {
    pub fn new(high: bool) -> Self {
        Self {
            level: Rc::new(Cell::new(high)),
            fail: false,
        }
    }
    /// Every read fails.
    pub fn failing(mut self) -> Self {
        self.fail = true;
        self
    }
    pub fn set(&self, high: bool) {
        self.level.set(high);
    }
}

impl ErrorType for MockIn {
    type Error = ReadError;
}

impl InputPin for MockIn {
    fn is_high(&mut self) -> Result<bool, ReadError> {
        if self.fail {
            Err(ReadError)
        } else {
            Ok(self.level.get())
        }
    }
    fn is_low(&mut self) -> Result<bool, ReadError> {
        self.is_high().map(|h| !h)
    }
}

/// Counts drive kills.
#[derive(Debug, Default)]
pub struct CountingKill {
    pub count: u32,
}

impl DriveKill for CountingKill {
    fn kill(&mut self) {
        self.count += 1;
    }
}
