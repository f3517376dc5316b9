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
//! * the host link is USART2, as on the board (QEMU's second `-serial`).
//!
//! With `--features pil` (processor in the loop) the trace is replaced by
//! the host's simulated plant: QEMU's third `-serial` (USART3) is the
//! sensor bus. Each [`SensorFrame`] the host sends is one tick: its
//! receive interrupt (priority 5, where TIM5's tick source is otherwise)
//! stores the sample, raises the input lines' EXTI interrupts on a change,
//! counts the tick for the software watchdog and pends the control task,
//! which answers with the tick's telemetry record (DAC code, drive enable,
//! estimates, instruction counts) on the same bus ([`FrontEnd::after_tick`]).
//! The host waits for that answer before it integrates the plant over the
//! period and sends the next sample: lockstep, whatever QEMU's speed. TIM5
//! is not started, and the watchdog counts sensor frames; the run ends when
//! the host stops QEMU.
//!
//! No RCC register is touched (QEMU has no clock model; HAL clock set-up
//! would wait forever for the PLL).

use core::convert::Infallible;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cable_joint::board::{DriveEnable, DriveKill, InputLine};
#[cfg(not(feature = "pil"))]
use cable_joint::board::{ReplayFrontEnd, SensorFrontEnd, TickOutcome, Trace};
#[cfg(not(feature = "pil"))]
use cable_joint::controller::RawSample;
use cable_joint::telemetry::Inputs;
#[cfg(not(feature = "pil"))]
use cable_joint::units::DacCode;
use cortex_m_semihosting::debug;
use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
use stm32f4xx_hal::pac::{self, Interrupt};

/// Every tick is logged: the replay test compares them all.
pub const TELEMETRY_DECIMATION: u32 = 1;

/// The trace recorded by `host-sim trace` (copied to OUT_DIR by build.rs).
#[cfg(not(feature = "pil"))]
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
#[cfg(not(feature = "pil"))]
pub struct FrontEnd {
    replay: ReplayFrontEnd<'static, fn(Inputs, Inputs)>,
}

#[cfg(not(feature = "pil"))]
impl FrontEnd {
    /// Every sample has been played (a recovery boot plays only the first
    /// [`RECOVERY_TICKS`]).
    pub fn finished(&self) -> bool {
        self.replay.finished()
            || (RECOVERY.load(Ordering::SeqCst) && self.replay.position() >= RECOVERY_TICKS)
    }

    /// After the tick: nothing (the replay test reads the defmt stream).
    #[inline(always)]
    pub fn after_tick(&mut self, _outcome: &TickOutcome) {}
}

#[cfg(not(feature = "pil"))]
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

#[cfg(feature = "pil")]
pub use pil::{on_sensor_bus, FrontEnd};

#[cfg(feature = "pil")]
mod pil {
    use core::cell::{Cell, RefCell};
    use core::sync::atomic::Ordering;

    use cable_joint::board::{SensorFrontEnd, TickOutcome, TraceSample};
    use cable_joint::controller::RawSample;
    use cable_joint::link::{self, FrameReader, Pushed, SensorFrame, Up};
    use cable_joint::telemetry::{Inputs, Record, MAX_RECORD_LEN};
    use cable_joint::units::DacCode;
    use cortex_m::interrupt::{self, Mutex};

    use super::{count_tick, on_inputs, FAULT_LEVEL};
    use crate::usart;

    /// The sample of the tick being run (written by the bus interrupt,
    /// read by the control task it then pends).
    static SAMPLE: Mutex<Cell<TraceSample>> = Mutex::new(Cell::new(TraceSample {
        raw: RawSample {
            grating1: cable_joint::units::GratingCount(0),
            grating2: cable_joint::units::GratingCount(0),
            motor: cable_joint::units::MotorCount(0),
            magnetic: cable_joint::units::MagneticCount(0),
            current: cable_joint::units::AdcCode(0),
        },
        inputs: Inputs(0),
    }));

    /// Largest sensor frame on the wire, bytes (about 30 in practice).
    const BUS_FRAME_LEN: usize = 64;

    /// The sensor bus's receiving side, the interrupt task's alone (a
    /// static because RTIC builds a task's locals even where the task is
    /// configured out; the critical section costs nothing at priority 5,
    /// the highest).
    static BUS: Mutex<RefCell<SensorBus>> = Mutex::new(RefCell::new(SensorBus::new()));

    /// USART3 receive interrupt (see [`SensorBus::on_rx`]).
    pub fn on_sensor_bus() {
        interrupt::free(|cs| BUS.borrow(cs).borrow_mut().on_rx());
    }

    struct SensorBus {
        rx: usart::Rx,
        reader: FrameReader<BUS_FRAME_LEN>,
        prev: Inputs,
    }

    impl SensorBus {
        /// USART3's receiving side (`init` opens the port; this task alone
        /// reads it).
        const fn new() -> Self {
            Self {
                rx: usart::Rx::steal(stm32f4xx_hal::pac::USART3::ptr()),
                reader: FrameReader::new(),
                prev: Inputs(0),
            }
        }

        /// USART3 receive interrupt: collect bytes; a complete sensor
        /// frame is one tick.
        fn on_rx(&mut self) {
            while let Some(byte) = self.rx.read() {
                let Pushed::Frame(n) = self.reader.push(byte) else {
                    continue;
                };
                match link::decode::<SensorFrame>(self.reader.frame(), n) {
                    Ok((_, frame)) => {
                        interrupt::free(|cs| SAMPLE.borrow(cs).set(frame.sample));
                        on_inputs(self.prev, frame.sample.inputs);
                        self.prev = frame.sample.inputs;
                        count_tick();
                    }
                    // The host waits for an answer that never comes and
                    // names the tick.
                    Err(e) => defmt::error!("sensor bus: {}", defmt::Display2Format(&e)),
                }
            }
        }
    }

    /// The host's plant behind the sensor bus.
    pub struct FrontEnd {
        pub(super) frames: usart::FrameTx,
    }

    impl FrontEnd {
        /// The host ends the run.
        pub fn finished(&self) -> bool {
            false
        }

        /// Answer the host: the origin record (on the homing tick), then
        /// the tick's record, whose DAC code and drive enable the plant
        /// applies over the next period.
        pub fn after_tick(&mut self, outcome: &TickOutcome) {
            if let Some(origin) = outcome.origin {
                self.send(&Record::Origin(origin));
            }
            self.send(&Record::Tick(outcome.record));
        }

        /// Tell the host the bus is open (an acknowledgement of nothing).
        pub(super) fn ready(&mut self) {
            self.frames.send(&Up::Ack {
                seq: 0,
                refused: None,
            });
        }

        fn send(&mut self, record: &Record) {
            let mut bytes = [0u8; MAX_RECORD_LEN];
            self.frames.send(&Up::Telemetry(record.encode(&mut bytes)));
        }
    }

    impl SensorFrontEnd for FrontEnd {
        #[inline]
        fn sample(&mut self) -> RawSample {
            interrupt::free(|cs| SAMPLE.borrow(cs).get()).raw
        }

        /// The DAC code goes back in the tick's record.
        #[inline]
        fn write_current(&mut self, _dac: DacCode) {}

        #[inline]
        fn drive_fault_asserted(&mut self) -> bool {
            FAULT_LEVEL.load(Ordering::SeqCst)
        }
    }
}

/// Ticks without a completed control tick before the software watchdog
/// resets the MCU (the hardware IWDG's timeout is six periods).
pub const WATCHDOG_TICKS: u32 = 6;

/// Ticks a recovery boot runs on the trace before the run ends.
#[cfg(not(feature = "pil"))]
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

#[cfg(not(feature = "pil"))]
fn trace() -> Option<Trace<'static>> {
    Trace::parse(TRACE_BYTES).ok()
}

/// The configuration the board boots with: the one the trace was recorded
/// with (the built-in one, with probing on if the trace's header says so),
/// or the built-in one if the trace is unreadable (`init` then stops).
#[cfg(not(feature = "pil"))]
pub fn config() -> cable_joint::Config {
    trace().map_or_else(cable_joint::board::firmware_config, |t| t.config())
}

/// The configuration the board boots with: the built-in one, as on the
/// board (the host may send another over the link).
#[cfg(feature = "pil")]
pub fn config() -> cable_joint::Config {
    cable_joint::board::firmware_config()
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

/// TIM4 update (PIL): the idle loop's wake-up, nothing else.
#[cfg(feature = "pil")]
pub fn on_wake() {
    // SAFETY: clear TIM4's update flag (rc_w0); TIM4 is only this wake-up.
    unsafe { (*pac::TIM4::ptr()).sr().write(|w| w.bits(0)) };
}

/// TIM5 update: one control tick, and the software watchdog's check.
#[cfg(not(feature = "pil"))]
#[inline(always)]
pub fn on_tick_source() {
    // SAFETY: clear TIM5's update flag (rc_w0); TIM5 is only this tick source.
    unsafe { (*pac::TIM5::ptr()).sr().write(|w| w.bits(0)) };
    count_tick();
}

/// One tick of the tick source (TIM5, or a PIL sensor frame): the software
/// watchdog's check, then the control task.
#[inline(always)]
fn count_tick() {
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
    /// Host link (USART2), transmit half.
    pub link_tx: crate::usart::Tx,
    /// Host link, receive half (its interrupt is enabled).
    pub link_rx: crate::usart::Rx,
}

/// Bring the virtual board up: drive disabled, trace checked against the
/// control rate (PIL: the sensor bus opened instead), TIM2 free-running,
/// TIM5 ticking at `rate_hz` (replay only), the host link open.
pub fn init(dp: pac::Peripherals, _cp: cortex_m::Peripherals, rate_hz: f32) -> Board {
    let drive = DriveEnable::new(DriveLine);
    // SAFETY (`bits` writes): full-range counter settings of TIM2/TIM5.
    let tim2 = dp.TIM2;
    tim2.psc().write(|w| w.psc().set(0));
    tim2.arr().write(|w| unsafe { w.bits(u32::MAX) });
    tim2.cr1().write(|w| w.cen().set_bit());
    // QEMU ignores the baud rate.
    let (link_tx, link_rx) = crate::usart::start(pac::USART2::ptr(), 1);
    #[cfg(not(feature = "pil"))]
    let front_end = {
        let Some(trace) = trace() else {
            panic!("the embedded sensor trace is missing or malformed (run `host-sim trace`)");
        };
        if trace.control_rate_hz() != rate_hz || trace.is_empty() {
            panic!("the sensor trace was recorded at another control rate");
        }
        // QEMU's timers count at 1 GHz: /10 → 100 MHz, then the period.
        let tim5 = dp.TIM5;
        tim5.psc().write(|w| w.psc().set(9));
        tim5.arr()
            .write(|w| unsafe { w.bits((100e6 / rate_hz) as u32 - 1) });
        tim5.dier().write(|w| w.uie().set_bit());
        tim5.cr1().write(|w| w.cen().set_bit());
        FrontEnd {
            replay: ReplayFrontEnd::new(trace, on_inputs as fn(Inputs, Inputs)),
        }
    };
    #[cfg(feature = "pil")]
    let front_end = {
        let _ = rate_hz; // the host's plant sets the pace
                         // Nothing else wakes the idle loop between two sensor frames, and a
                         // host that writes the RTT down channel waits for its answer before
                         // it sends the next one: TIM5 wakes it every millisecond (TIM4; of
                         // virtual time, which follows the host's time while idle under
                         // `-icount sleep=on`), as the control tick does on the board.
                         // CNT first: QEMU's timer counts from its last CNT write and sets
                         // the update's alarm when ARR is written, which a counter already
                         // past ARR would put out of reach.
        let tim4 = dp.TIM4;
        tim4.psc().write(|w| w.psc().set(9_999));
        tim4.cnt().write(|w| unsafe { w.bits(0) });
        tim4.arr().write(|w| unsafe { w.bits(100 - 1) });
        tim4.dier().write(|w| w.uie().set_bit());
        tim4.cr1().write(|w| w.cen().set_bit());
        // The receiving half is the sensor bus task's (`SensorBus::new`).
        let (tx, _rx) = crate::usart::start(pac::USART3::ptr(), 1);
        let mut front_end = FrontEnd {
            frames: crate::usart::FrameTx::new(tx),
        };
        // Bytes that reach a disabled USART are lost: the host sends the
        // first sample only after this.
        front_end.ready();
        front_end
    };
    Board {
        front_end,
        counter: Counter,
        drive,
        drive_fault: InputLine::new(ReplayPin(&FAULT_LEVEL), false),
        origin: InputLine::new(ReplayPin(&ORIGIN_LEVEL), false),
        tick: TickTimer { seen: 0 },
        watchdog: Watchdog,
        link_tx,
        link_rx,
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
