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
//!   (defmt-semihosting);
//! * the IWDG is not modelled either: a software watchdog in TIM5's
//!   interrupt (priority above the control task) resets the MCU through
//!   `SYSRESETREQ` when no tick has completed for [`WATCHDOG_TICKS`] ticks,
//!   and leaves a flag in RAM the start-up code does not clear, as the RCC's
//!   reset flag would be on the chip;
//! * the run injects a watchdog reset: once the trace is played and the
//!   telemetry flushed, the control task hangs on purpose; the watchdog
//!   resets the MCU, and the next boot (a *recovery boot*) must latch fault
//!   32 and keep the drive off for [`RECOVERY_TICKS`] ticks of the trace;
//!   then the run ends through semihosting with success. A panic or a
//!   HardFault ends it with failure.
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
    /// Every sample has been played (a recovery boot plays only the first
    /// [`RECOVERY_TICKS`]).
    pub fn finished(&self) -> bool {
        self.replay.finished()
            || (RECOVERY.load(Ordering::SeqCst) && self.replay.position() >= RECOVERY_TICKS)
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

/// Ticks without a completed control tick before the software watchdog
/// resets the MCU (the hardware IWDG's timeout is six periods).
pub const WATCHDOG_TICKS: u32 = 6;

/// Ticks a recovery boot runs on the trace before the run ends.
pub const RECOVERY_TICKS: usize = 50;

/// Pattern of the watchdog's reset flag ("WDOG").
const WATCHDOG_MAGIC: u32 = 0x5744_4F47;

/// The tick count at the last feed.
static FED_AT: AtomicU32 = AtomicU32::new(0);
/// The control task hangs on purpose from its next tick (watchdog test).
static HANG: AtomicBool = AtomicBool::new(false);
/// This boot follows a watchdog reset.
static RECOVERY: AtomicBool = AtomicBool::new(false);
/// The end of the trace has been handled.
static TRACE_ENDED: AtomicBool = AtomicBool::new(false);

/// The reset flag, in RAM the start-up code leaves alone (cortex-m-rt's
/// `.uninit`), as RCC_CSR's IWDGRSTF survives the reset on the chip.
#[link_section = ".uninit.WATCHDOG_FLAG"]
static mut WATCHDOG_FLAG: core::mem::MaybeUninit<u32> = core::mem::MaybeUninit::uninit();

/// The software watchdog, fed by every control tick that completes in time.
pub struct Watchdog;

impl Watchdog {
    /// Note that a tick completed.
    #[inline(always)]
    pub fn feed(&mut self) {
        FED_AT.store(TICKS.load(Ordering::SeqCst), Ordering::SeqCst);
    }
}

/// Did the software watchdog cause the last reset? Clears the flag. A
/// `true` makes this boot a recovery boot (see the module's docs).
pub fn take_watchdog_reset_flag() -> bool {
    let flag = core::ptr::addr_of_mut!(WATCHDOG_FLAG).cast::<u32>();
    // SAFETY: init runs once, before any task or handler; the word may hold
    // power-up noise, which the pattern rejects.
    let by_watchdog = unsafe { core::ptr::read_volatile(flag) } == WATCHDOG_MAGIC;
    // SAFETY: as above.
    unsafe { core::ptr::write_volatile(flag, 0) };
    RECOVERY.store(by_watchdog, Ordering::SeqCst);
    by_watchdog
}

/// No tick completed in time: drive off, flag for the next boot, reset.
fn watchdog_reset() -> ! {
    kill_drive();
    let flag = core::ptr::addr_of_mut!(WATCHDOG_FLAG).cast::<u32>();
    // SAFETY: a volatile store of one word no other code touches while the
    // MCU resets.
    unsafe { core::ptr::write_volatile(flag, WATCHDOG_MAGIC) };
    cortex_m::peripheral::SCB::sys_reset()
}

/// The control task's tick once the trace is played: feed the watchdog
/// while the telemetry flushes, then hang once the test is armed.
pub fn after_trace(watchdog: &mut Watchdog) {
    if HANG.load(Ordering::SeqCst) {
        loop {
            cortex_m::asm::nop();
        }
    }
    watchdog.feed();
}

/// The trace is played and the telemetry flushed. A first boot arms the
/// watchdog test (the control task hangs from its next tick); a recovery
/// boot ends the run with success.
pub fn trace_played() {
    if TRACE_ENDED.swap(true, Ordering::SeqCst) {
        return;
    }
    if RECOVERY.load(Ordering::SeqCst) {
        defmt::info!("recovery boot done: drive kept off");
        finish();
    }
    defmt::info!(
        "watchdog test: the control task hangs from the next tick ({=u32} ticks to the reset)",
        WATCHDOG_TICKS
    );
    HANG.store(true, Ordering::SeqCst);
}

fn trace() -> Option<Trace<'static>> {
    Trace::parse(TRACE_BYTES).ok()
}

/// The configuration the board boots with: the one the trace was recorded
/// with (the built-in one, with probing on if the trace's header says so),
/// or the built-in one if the trace is unreadable (`init` then stops).
pub fn config() -> cable_joint::Config {
    trace().map_or_else(cable_joint::board::firmware_config, |t| t.config())
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
}

/// TIM5 update: one control tick, and the software watchdog's check.
#[inline(always)]
pub fn on_tick_source() {
    // SAFETY: clear TIM5's update flag (rc_w0); TIM5 is only this tick source.
    unsafe { (*pac::TIM5::ptr()).sr().write(|w| w.bits(0)) };
    let now = TICKS.fetch_add(1, Ordering::SeqCst).wrapping_add(1);
    if now.wrapping_sub(FED_AT.load(Ordering::SeqCst)) > WATCHDOG_TICKS {
        watchdog_reset();
    }
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
    /// Software watchdog.
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
