//! QEMU board (`--features qemu`, machine `netduinoplus2`): the same tasks
//! on a replayed sensor trace.
//!
//! QEMU models neither the RCC nor the encoder timers, the ADC samples
//! nothing, and TIM6 is not modelled at all, so this board changes exactly
//! these things and nothing else:
//!
//! * the front end plays back `firmware/trace.bin` (embedded by build.rs),
//!   one sample per tick, and the two input lines follow the trace: a change
//!   sets the replayed level and pends the EXTI interrupt the real line would
//!   raise;
//! * TIM5 (modelled, 1 GHz of virtual time) is the tick source: its update
//!   interrupt pends TIM6_DAC, the control task's own interrupt;
//! * TIM2 counts virtual nanoseconds; under `-icount shift=0,sleep=off` its
//!   delta is the number of guest instructions (the per-stage counts);
//! * the drive enable line is a flag; logging goes over semihosting
//!   (defmt-semihosting), and the run ends through semihosting: success when
//!   the trace is played and the telemetry flushed, failure on a panic or a
//!   HardFault.
//!
//! No RCC register is touched (QEMU has no clock model; HAL clock set-up
//! would wait forever for the PLL).

use core::convert::Infallible;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cable_joint::board::{
    DriveEnable, DriveKill, InputLine, ReplayFrontEnd, SensorFrontEnd, Trace,
};
use cable_joint::controller::RawSample;
use cable_joint::telemetry::Inputs;
use cable_joint::units::DacCode;
use cortex_m_semihosting::debug;
use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
use stm32f4xx_hal::pac::{self, Interrupt};

/// Every tick is logged: the replay test compares them all.
pub const TELEMETRY_DECIMATION: u32 = 1;

/// The trace recorded by `host-sim trace` (copied to OUT_DIR by build.rs).
static TRACE_BYTES: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/trace.bin"));

static ORIGIN_LEVEL: AtomicBool = AtomicBool::new(false);
static FAULT_LEVEL: AtomicBool = AtomicBool::new(false);
static DRIVE_LINE: AtomicBool = AtomicBool::new(false);
static TICKS: AtomicU32 = AtomicU32::new(0);

/// A replayed input line.
pub struct ReplayPin(&'static AtomicBool);

impl ErrorType for ReplayPin {
    type Error = Infallible;
}

impl InputPin for ReplayPin {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.0.load(Ordering::SeqCst))
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0.load(Ordering::SeqCst))
    }
}

/// The drive enable line (a flag: GPIO is not modelled).
pub struct DriveLine;

impl ErrorType for DriveLine {
    type Error = Infallible;
}

impl OutputPin for DriveLine {
    fn set_high(&mut self) -> Result<(), Infallible> {
        DRIVE_LINE.store(true, Ordering::SeqCst);
        Ok(())
    }
    fn set_low(&mut self) -> Result<(), Infallible> {
        DRIVE_LINE.store(false, Ordering::SeqCst);
        Ok(())
    }
}

/// Drive enable output.
pub type DrivePin = DriveLine;
/// Drive fault input (replayed, asserted = high).
pub type FaultPin = ReplayPin;
/// Origin switch input (replayed, asserted = high).
pub type OriginPin = ReplayPin;

/// A replayed input changed: set its level and raise its EXTI interrupt
/// (drive fault on EXTI1, origin on EXTI2, as on the board).
fn on_inputs(prev: Inputs, now: Inputs) {
    if prev.drive_fault() != now.drive_fault() {
        FAULT_LEVEL.store(now.drive_fault(), Ordering::SeqCst);
        rtic::pend(Interrupt::EXTI1);
    }
    if prev.origin() != now.origin() {
        ORIGIN_LEVEL.store(now.origin(), Ordering::SeqCst);
        rtic::pend(Interrupt::EXTI2);
    }
}

/// The trace player.
pub struct FrontEnd {
    replay: ReplayFrontEnd<'static, fn(Inputs, Inputs)>,
}

impl FrontEnd {
    /// Every sample has been played.
    pub fn finished(&self) -> bool {
        self.replay.finished()
    }
}

impl SensorFrontEnd for FrontEnd {
    #[inline]
    fn sample(&mut self) -> RawSample {
        self.replay.sample()
    }

    #[inline]
    fn write_current(&mut self, dac: DacCode) {
        self.replay.write_current(dac);
    }

    #[inline]
    fn drive_fault_asserted(&mut self) -> bool {
        self.replay.drive_fault_asserted()
    }
}

/// QEMU's netduinoplus2 does not model the IWDG: feeding is a no-op here
/// (the hardware build runs the real one; its logic, the boot report, is
/// tested on the host).
pub struct Watchdog;

impl Watchdog {
    /// Nothing to feed.
    #[inline(always)]
    pub fn feed(&mut self) {}
}

/// No watchdog, so never a watchdog reset.
pub fn take_watchdog_reset_flag() -> bool {
    false
}

fn trace() -> Option<Trace<'static>> {
    Trace::parse(TRACE_BYTES).ok()
}

/// TIM2: virtual nanoseconds = guest instructions under `-icount shift=0`.
pub struct Counter;

impl cable_joint::board::CycleCounter for Counter {
    #[inline(always)]
    fn now(&mut self) -> u32 {
        // SAFETY: a read of TIM2's counter, which nothing else writes after init.
        unsafe { (*pac::TIM2::ptr()).cnt().read().bits() }
    }
}

/// The tick source as the control task sees it.
pub struct TickTimer {
    seen: u32,
}

impl TickTimer {
    /// Remember which tick this run of the task serves.
    #[inline(always)]
    pub fn ack(&mut self) {
        self.seen = TICKS.load(Ordering::SeqCst);
    }

    /// Did another tick arrive before the task finished?
    #[inline(always)]
    pub fn overran(&self) -> bool {
        TICKS.load(Ordering::SeqCst) != self.seen
    }

    /// Stop the tick source (the trace is played).
    pub fn stop(&mut self) {
        // SAFETY: TIM5 is only used as this tick source.
        unsafe { (*pac::TIM5::ptr()).cr1().write(|w| w.bits(0)) };
    }
}

/// TIM5 update: one control tick.
#[inline(always)]
pub fn on_tick_source() {
    // SAFETY: clear TIM5's update flag (rc_w0); TIM5 is only this tick source.
    unsafe { (*pac::TIM5::ptr()).sr().write(|w| w.bits(0)) };
    TICKS.fetch_add(1, Ordering::SeqCst);
    rtic::pend(Interrupt::TIM6_DAC);
}

/// Drive enable low.
pub struct Kill;

impl DriveKill for Kill {
    #[inline(always)]
    fn kill(&mut self) {
        kill_drive();
    }
}

/// Drive enable low (panic, HardFault, fault tasks).
#[inline(always)]
pub fn kill_drive() {
    DRIVE_LINE.store(false, Ordering::SeqCst);
}

/// Clear the pending bit of EXTI line `line` (EXTI is modelled).
#[inline(always)]
pub fn clear_exti(line: u8) {
    // SAFETY: PR is write-1-to-clear; only this line's bit is written.
    unsafe { (*pac::EXTI::ptr()).pr().write(|w| w.bits(1 << line)) };
}

/// What init hands to the tasks.
pub struct Board {
    /// Trace player.
    pub front_end: FrontEnd,
    /// Instruction counter.
    pub counter: Counter,
    /// Drive enable, disabled.
    pub drive: DriveEnable<DrivePin>,
    /// Drive fault line (replayed).
    pub drive_fault: InputLine<FaultPin>,
    /// Origin switch (replayed).
    pub origin: InputLine<OriginPin>,
    /// Tick source.
    pub tick: TickTimer,
    /// No-op watchdog.
    pub watchdog: Watchdog,
}

/// Bring the virtual board up: drive disabled, trace checked against the
/// control rate, TIM2 free-running, TIM5 ticking at `rate_hz`.
pub fn init(dp: pac::Peripherals, _cp: cortex_m::Peripherals, rate_hz: f32) -> Board {
    let drive = DriveEnable::new(DriveLine);
    let Some(trace) = trace() else {
        panic!("the embedded sensor trace is missing or malformed (run `host-sim trace`)");
    };
    if trace.control_rate_hz() != rate_hz || trace.is_empty() {
        panic!("the sensor trace was recorded at another control rate");
    }
    // SAFETY (`bits` writes): full-range counter settings of TIM2/TIM5.
    let tim2 = dp.TIM2;
    tim2.psc().write(|w| w.psc().set(0));
    tim2.arr().write(|w| unsafe { w.bits(u32::MAX) });
    tim2.cr1().write(|w| w.cen().set_bit());
    // QEMU's timers count at 1 GHz: /10 → 100 MHz, then the period.
    let tim5 = dp.TIM5;
    tim5.psc().write(|w| w.psc().set(9));
    tim5.arr()
        .write(|w| unsafe { w.bits((100e6 / rate_hz) as u32 - 1) });
    tim5.dier().write(|w| w.uie().set_bit());
    tim5.cr1().write(|w| w.cen().set_bit());
    Board {
        front_end: FrontEnd {
            replay: ReplayFrontEnd::new(trace, on_inputs as fn(Inputs, Inputs)),
        },
        counter: Counter,
        drive,
        drive_fault: InputLine::new(ReplayPin(&FAULT_LEVEL), false),
        origin: InputLine::new(ReplayPin(&ORIGIN_LEVEL), false),
        tick: TickTimer { seen: 0 },
        watchdog: Watchdog,
    }
}

/// The trace is played and the telemetry flushed: leave QEMU with success.
pub fn finish() -> ! {
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

/// Leave QEMU with failure (panic, HardFault).
pub fn halt_failure() -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
