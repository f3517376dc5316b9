//! STM32F407VG board: the only code that touches the prototype's registers.
//!
//! Clocks: 8 MHz HSE → PLL → 168 MHz SYSCLK, APB1 42 MHz (timers 84 MHz),
//! APB2 84 MHz (timers 168 MHz).
//!
//! | function | peripheral | pins (LQFP100) | notes |
//! |---|---|---|---|
//! | grating 1 (x1) | TIM2 encoder, 32 bit | PA15 (CH1), PB3 (CH2), AF1 | quadrature ×4 |
//! | grating 2 (x2) | TIM5 encoder, 32 bit | PA0 (CH1), PA1 (CH2), AF2 | quadrature ×4 |
//! | magnetic joint encoder | TIM3 encoder, 16 bit | PC6 (CH1), PC7 (CH2), AF2 | extended in software |
//! | motor encoder | TIM4 encoder, 16 bit | PB6 (CH1), PB7 (CH2), AF2 | extended in software |
//! | motor current monitor | ADC1 IN10, 12 bit | PC0 (analog) | triggered by TIM8 (below) |
//! | current reference | DAC channel 1, 12 bit | PA4 (analog) | ±10 V after the external amplifier |
//! | drive enable | GPIO out, push-pull | PD0 | high = enabled; cut by BSRR from any priority |
//! | drive fault | GPIO in + EXTI1 | PD1, pull-up | active low (open collector) |
//! | origin switch | GPIO in + EXTI2 | PD2, pull-down | photoelectric, active high |
//! | control tick | TIM6 update interrupt | – | 2 kHz default, up to 20 kHz |
//! | ADC trigger | TIM8 CC1 → TRGO | – | same period as TIM6, fires 3 µs before its update |
//! | cycle counter | DWT CYCCNT | – | per-stage cycles in telemetry |
//! | debug / RTT | SWD | PA13, PA14 | probe-rs |
//! | host link | USART2, 460 800 baud 8N1 | PA2 (TX), PA3 (RX), AF7 | `cable_joint::link` frames; RX interrupt |
//! | watchdog | IWDG (LSI, 17–47 kHz) | – | fed by every tick that completes in time; frozen while a debugger halts the core |
//!
//! TIM6's TRGO cannot trigger the ADC on the F407 (RM0090 Table 69 lists no
//! TIM6 event), so TIM8 runs at TIM6's period from the same 84 MHz count
//! rate, started in the same instruction sequence, and its compare-1 pulse
//! (TRGO) starts the conversion 3 µs before the tick: the result (1.3 µs
//! conversion) is ready when the control task reads it. The DAC is written
//! without a trigger, so the new reference reaches the drive a few
//! microseconds after the sample, not a period later.

use cable_joint::board::{DriveEnable, DriveKill, InputLine, SensorFrontEnd};
use cable_joint::controller::RawSample;
use cable_joint::units::{AdcCode, DacCode, GratingCount, MagneticCount, MotorCount};
use stm32f4xx_hal::{
    gpio::{Edge, ExtiPin, Input, Output, Pin, PushPull},
    pac,
    prelude::*,
    qei::Qei,
    rcc::{Config as RccConfig, Enable, Reset},
    watchdog::IndependentWatchdog,
};

/// One telemetry record every this many ticks (200 Hz at 2 kHz).
pub const TELEMETRY_DECIMATION: u32 = 10;

/// APB1 clock (USART2), Hz.
const PCLK1_HZ: u32 = 42_000_000;

/// The host link's baud rate (USART2), the one the host's `stty` sets.
pub const LINK_BAUD: u32 = cable_joint::link::SERIAL_BAUD;

/// Timer clock of TIM6 (APB1 ×2) and the rate TIM8 counts at, Hz.
const TIMER_COUNT_HZ: u32 = 84_000_000;

/// ADC conversion starts this many timer counts before the tick (3 µs).
const ADC_LEAD_COUNTS: u32 = 252;

/// Drive enable output.
pub type DrivePin = Pin<'D', 0, Output<PushPull>>;
/// Drive fault input (active low).
pub type FaultPin = Pin<'D', 1, Input>;
/// Origin switch input (active high).
pub type OriginPin = Pin<'D', 2, Input>;

/// The encoder timers, the ADC and the DAC.
pub struct FrontEnd {
    grating1: Qei<pac::TIM2>,
    grating2: Qei<pac::TIM5>,
    magnetic: Qei<pac::TIM3>,
    motor: Qei<pac::TIM4>,
    adc: pac::ADC1,
    dac: pac::DAC,
}

impl FrontEnd {
    /// Hardware never runs out of samples.
    pub fn finished(&self) -> bool {
        false
    }

    /// After the tick: nothing on the board (the PIL build answers the
    /// host's plant here).
    #[inline(always)]
    pub fn after_tick(&mut self, _outcome: &cable_joint::board::TickOutcome) {}
}

impl SensorFrontEnd for FrontEnd {
    #[inline]
    fn sample(&mut self) -> RawSample {
        // Two's complement reinterpretation: the 32-bit encoder timers count
        // through zero in both directions.
        RawSample {
            grating1: GratingCount(self.grating1.count() as i32),
            grating2: GratingCount(self.grating2.count() as i32),
            motor: MotorCount(self.motor.count()),
            magnetic: MagneticCount(self.magnetic.count()),
            // Converted 3 µs ago by TIM8's trigger; reading DR clears EOC.
            current: AdcCode(self.adc.dr().read().data().bits()),
        }
    }

    #[inline]
    fn write_current(&mut self, dac: DacCode) {
        self.dac
            .dhr12r1()
            .write(|w| w.daccdhr().set(dac.0 & 0x0fff));
    }

    #[inline]
    fn drive_fault_asserted(&mut self) -> bool {
        // SAFETY: a read of GPIOD's input data register (no side effect);
        // the EXTI task owns the pin, this reads only its level. PD1 is
        // active low.
        let idr = unsafe { (*pac::GPIOD::ptr()).idr().read().bits() };
        idr & (1 << 1) == 0
    }
}

/// The independent watchdog, fed by the control task.
pub struct Watchdog(IndependentWatchdog);

impl Watchdog {
    /// Reload the watchdog's counter.
    #[inline(always)]
    pub fn feed(&mut self) {
        self.0.feed();
    }
}

/// Watchdog timeout for a control rate, ms: six periods at the LSI's
/// nominal 32 kHz and at least 5 ms. The LSI may run at 17–47 kHz
/// (datasheet), so the real timeout is 0.68–1.9 times this: at least four
/// periods, never a false reset from one late tick.
fn watchdog_timeout_ms(rate_hz: f32) -> u32 {
    ((6000.0 / rate_hz) as u32).max(5)
}

/// Did the independent watchdog cause the last reset? Clears the reset
/// flags (call once, first thing in init).
pub fn take_watchdog_reset_flag() -> bool {
    // SAFETY: RCC_CSR's reset flags are read, then cleared by RMVF; nothing
    // else uses them and init runs before any task.
    let rcc = unsafe { &*pac::RCC::ptr() };
    let by_watchdog = rcc.csr().read().wdgrstf().bit_is_set(); // bit 29, IWDGRSTF
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    by_watchdog
}

/// DWT cycle counter.
pub struct Counter;

impl cable_joint::board::CycleCounter for Counter {
    #[inline(always)]
    fn now(&mut self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
}

/// The control timer (TIM6).
pub struct TickTimer {
    tim: pac::TIM6,
}

impl TickTimer {
    /// Acknowledge the update interrupt (first thing in the control task).
    #[inline(always)]
    pub fn ack(&mut self) {
        self.tim.sr().write(|w| w.uif().clear_bit());
    }

    /// Did the next update arrive before the task finished?
    #[inline(always)]
    pub fn overran(&self) -> bool {
        self.tim.sr().read().uif().bit_is_set()
    }

    /// Stop ticking (not used on hardware).
    pub fn stop(&mut self) {
        self.tim.cr1().modify(|_, w| w.cen().clear_bit());
    }
}

/// Cuts the drive enable line through GPIOD's bit set/reset register: one
/// atomic store, safe from any priority, no ownership of the pin needed.
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
    // SAFETY: a write-only, atomic reset of PD0 in BSRR; it races with
    // nothing (every other write to GPIOD is also a BSRR or a one-time
    // configuration in init).
    unsafe { (*pac::GPIOD::ptr()).bsrr().write(|w| w.br0().set_bit()) };
}

/// Clear the pending bit of EXTI line `line` (0..=15).
#[inline(always)]
pub fn clear_exti(line: u8) {
    // SAFETY: PR is write-1-to-clear; writing only this line's bit leaves the
    // other lines untouched.
    unsafe { (*pac::EXTI::ptr()).pr().write(|w| w.bits(1 << line)) };
}

/// Prescaler and auto-reload of an 84 MHz timer for `rate_hz` (100 Hz to
/// 20 kHz, as `Config::validate` allows).
fn timer_period(rate_hz: f32) -> (u16, u16) {
    let total = (TIMER_COUNT_HZ as f32 / rate_hz) as u32;
    let psc = total / 65_536;
    let arr = total / (psc + 1) - 1;
    (psc as u16, arr as u16)
}

/// What init hands to the tasks.
pub struct Board {
    /// Sensors and DAC.
    pub front_end: FrontEnd,
    /// Cycle counter.
    pub counter: Counter,
    /// Drive enable, disabled.
    pub drive: DriveEnable<DrivePin>,
    /// Drive fault line.
    pub drive_fault: InputLine<FaultPin>,
    /// Origin switch.
    pub origin: InputLine<OriginPin>,
    /// Control timer.
    pub tick: TickTimer,
    /// Independent watchdog, running.
    pub watchdog: Watchdog,
    /// Host link, transmit half.
    pub link_tx: crate::usart::Tx,
    /// Host link, receive half (its interrupt is enabled).
    pub link_rx: crate::usart::Rx,
}

/// The configuration the board boots with: the built-in one.
pub fn config() -> cable_joint::Config {
    cable_joint::board::firmware_config()
}

/// Bring the board up: drive disabled first, then clocks, sensors, inputs,
/// and the control timer at `rate_hz` (the last thing started).
pub fn init(dp: pac::Peripherals, mut cp: cortex_m::Peripherals, rate_hz: f32) -> Board {
    let mut rcc = dp.RCC.constrain();
    // Drive disabled before anything else (the pin floats until then; the
    // drive's enable input has a pull-down on the prototype).
    let gpiod = dp.GPIOD.split(&mut rcc);
    let drive = DriveEnable::new(gpiod.pd0.into_push_pull_output());

    let mut rcc = rcc.freeze(
        RccConfig::hse(8.MHz())
            .sysclk(168.MHz())
            .pclk1(42.MHz())
            .pclk2(84.MHz()),
    );
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();

    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    let front_end = FrontEnd {
        // PA15/PB3 come out of reset as JTAG (AF0); SWD only needs PA13/PA14.
        grating1: Qei::new(
            dp.TIM2,
            (
                gpioa.pa15.into_floating_input(),
                gpiob.pb3.into_floating_input(),
            ),
            &mut rcc,
        ),
        grating2: Qei::new(dp.TIM5, (gpioa.pa0, gpioa.pa1), &mut rcc),
        magnetic: Qei::new(dp.TIM3, (gpioc.pc6, gpioc.pc7), &mut rcc),
        motor: Qei::new(dp.TIM4, (gpiob.pb6, gpiob.pb7), &mut rcc),
        adc: dp.ADC1,
        dac: dp.DAC,
    };
    let _current_pin = gpioc.pc0.into_analog();
    let _dac_pin = gpioa.pa4.into_analog();

    // Period in counts of the 84 MHz timer clock, prescaled below 1.3 kHz
    // so that it fits the 16-bit auto-reload registers.
    let (psc, arr) = timer_period(rate_hz);

    // ADC1: 12 bit, one conversion of IN10, 15-cycle sampling at 21 MHz,
    // started by TIM8 TRGO (rising edge).
    pac::ADC1::enable(&mut rcc);
    pac::ADC1::reset(&mut rcc);
    let adc = &front_end.adc;
    dp.ADC_COMMON.ccr().modify(|_, w| w.adcpre().div4()); // 84 / 4 = 21 MHz
    adc.cr1().write(|w| w.res().twelve_bit());
    // SAFETY: L = 0 (one conversion) and SQ1 = 10 (IN10) are in range.
    adc.sqr1().write(|w| unsafe { w.l().bits(0) });
    adc.sqr3().write(|w| unsafe { w.sq1().bits(10) });
    adc.smpr1().write(|w| w.smp10().cycles15());
    adc.cr2()
        .write(|w| w.exten().rising_edge().extsel().tim8trgo().adon().set_bit());

    // DAC channel 1, output buffer on, no trigger (written by the control task).
    pac::DAC::enable(&mut rcc);
    pac::DAC::reset(&mut rcc);
    let mut front_end = front_end;
    front_end.write_current(DacCode(2048));
    front_end.dac.cr().write(|w| w.en1().set_bit());

    // Inputs and their EXTI lines (both edges; the tasks read the level).
    let mut syscfg = dp.SYSCFG.constrain(&mut rcc);
    let mut exti = dp.EXTI;
    let mut fault_pin = gpiod.pd1.into_pull_up_input();
    fault_pin.make_interrupt_source(&mut syscfg);
    fault_pin.trigger_on_edge(&mut exti, Edge::RisingFalling);
    fault_pin.enable_interrupt(&mut exti);
    let mut origin_pin = gpiod.pd2.into_pull_down_input();
    origin_pin.make_interrupt_source(&mut syscfg);
    origin_pin.trigger_on_edge(&mut exti, Edge::RisingFalling);
    origin_pin.enable_interrupt(&mut exti);

    // TIM8 (168 MHz, /2 → 84 MHz): compare 1 just before the period ends,
    // TRGO = compare pulse → ADC. TIM6 (84 MHz): update interrupt = tick.
    pac::TIM8::enable(&mut rcc);
    pac::TIM8::reset(&mut rcc);
    pac::TIM6::enable(&mut rcc);
    pac::TIM6::reset(&mut rcc);
    let tim8 = dp.TIM8;
    let tim6 = dp.TIM6;
    let lead = (ADC_LEAD_COUNTS / (psc as u32 + 1)).max(1);
    tim8.psc().write(|w| w.psc().set(2 * psc + 1));
    tim8.arr().write(|w| w.arr().set(arr));
    tim8.ccr1()
        .write(|w| w.ccr().set(arr.saturating_sub(lead as u16)));
    tim8.cr2().write(|w| w.mms().compare_pulse());
    tim8.egr().write(|w| w.ug().set_bit());
    tim6.psc().write(|w| w.psc().set(psc));
    tim6.arr().write(|w| w.arr().set(arr));
    tim6.egr().write(|w| w.ug().set_bit());
    tim6.sr().write(|w| w.uif().clear_bit());
    tim6.dier().write(|w| w.uie().set_bit());
    // Start both back to back: a fixed offset of a few counts.
    tim8.cr1().write(|w| w.cen().set_bit());
    tim6.cr1().write(|w| w.cen().set_bit());

    // Host link: USART2 on PA2/PA3 (AF7), receive interrupt on.
    let _link_tx_pin = gpioa.pa2.into_alternate::<7>();
    let _link_rx_pin = gpioa.pa3.into_alternate::<7>();
    pac::USART2::enable(&mut rcc);
    pac::USART2::reset(&mut rcc);
    let brr = ((PCLK1_HZ + LINK_BAUD / 2) / LINK_BAUD) as u16;
    let (link_tx, link_rx) = crate::usart::start(pac::USART2::ptr(), brr);

    // The watchdog last: from now on only completed ticks keep the MCU
    // running. Frozen while a debugger halts the core (breakpoints).
    let mut iwdg = IndependentWatchdog::new(dp.IWDG);
    iwdg.stop_on_debug(&dp.DBGMCU, true);
    iwdg.start(watchdog_timeout_ms(rate_hz).millis());

    Board {
        front_end,
        counter: Counter,
        drive,
        drive_fault: InputLine::new(fault_pin, true),
        origin: InputLine::new(origin_pin, false),
        tick: TickTimer { tim: tim6 },
        watchdog: Watchdog(iwdg),
        link_tx,
        link_rx,
    }
}

/// After a panic or HardFault (drive already off, boot note written): with a
/// debugger attached, `udf` (probe-rs stops and shows the backtrace);
/// otherwise reset, and the next boot reports the fault and keeps the drive
/// off until an operator clears it.
pub fn halt_failure() -> ! {
    if cortex_m::peripheral::DCB::is_debugger_attached() {
        cortex_m::asm::udf()
    } else {
        cortex_m::peripheral::SCB::sys_reset()
    }
}
