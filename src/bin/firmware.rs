//! RTIC 2 firmware of the cable-driven joint (STM32F407VG, 168 MHz).
//!
//! What it does: at every TIM6 update (2 kHz by default, `Config::
//! control_rate_hz`, up to 20 kHz) it samples the two gratings, the motor and
//! magnetic encoders and the current monitor, runs the core's
//! `Controller::step` (JAE, DOB, PD/PI cascade), writes the current reference
//! to the DAC and the drive enable line, and queues a raw telemetry record.
//! Start-up: drive disabled, clocks, sensor check, homing on the origin
//! switch, then the program (`board::Program::default()`: joint to 30° in one
//! second and hold, the seed's loading protocol).
//!
//! Tasks and priorities (higher preempts lower):
//!
//! | task | binds / kind | priority | deadline and miss |
//! |---|---|---|---|
//! | `drive_fault`, `origin_switch` | EXTI1, EXTI2 | 4 | cut the drive at once (BSRR), leave the fault for the control task |
//! | `control` | TIM6 update | 3 | one control period; a miss is `Fault::Overrun` (latched, drive cut) |
//! | `link_rx` | USART2 (host link) | 2 | the next byte (22 µs at 460 800 baud): bytes into frames, a complete frame to `link_frame` |
//! | `telemetry`, `link_frame` | async | 1 | none: telemetry records queue (64) and are dropped and counted when full (an origin record waits for room instead, the tick records behind it dropped); a host frame is checked down to a request (`cable_joint::link::receive`: CRC, version, body, `validate()`, filter design), queued (4) for the control task, which applies one per tick, and acknowledged. The RTT logger (`rtt.rs`) never blocks and takes no critical section (a full channel cuts the frame; a frame logged while another is open is dropped), so logging can never mask the tasks above |
//! | `idle` | – | 0 | after every wake-up (each tick), the host link's RTT down channel: bytes into frames, a complete frame to `link_frame`; then `wfi` |
//!
//! Settings: `board::firmware_config()` (the core's datasheet defaults at
//! `board::CONTROL_RATE_HZ`, 2 kHz, up to 20 kHz; compiled in; under QEMU
//! with probing on when the replayed trace was recorded so; new parameters
//! at the same rate arrive over the host link as `Down::SetConfig`, checked
//! by the `link_frame` task), the program, and the telemetry decimation (`TELEMETRY_DECIMATION`:
//! every 10th tick on hardware, i.e. 200 Hz; every tick under QEMU).
//!
//! Host link (`cable_joint::link`), one protocol on two ports: USART2 at
//! 460 800 baud (QEMU's second serial port) and RTT channel 1 through the
//! debug probe (`rtt.rs`); COBS frames with CRC-16; down: programs,
//! commands, configurations, fault clears, telemetry rate, heartbeats, each
//! acknowledged on the port it came from; up: the acknowledgements and,
//! on each port where a host has sent a valid frame, every telemetry
//! record as well.
//!
//! Telemetry: defmt over RTT channel 0 (`rtt.rs`; defmt-semihosting under
//! QEMU). Each record is
//! one `tlm [bytes]` line (`cable_joint::telemetry`: raw counts, ADC code,
//! DAC code and current reference, theta_ref, theta_hat, F_ext_hat, mode,
//! fault code, start-up phase, input lines, cycles of the whole tick and of
//! each step stage); `host-sim ingest` turns the decoded text into the
//! project's CSV log. Phase and fault changes are also logged as text.
//!
//! Variants: the default build drives the board (`hw` module); `--features
//! qemu` replays `firmware/trace.bin` on QEMU's netduinoplus2 (`qemu`
//! module). Nothing else differs. On the host this file compiles to a stub.

#![cfg_attr(target_os = "none", no_std, no_main)]
// RTIC's generated `spawn` returns the argument back on failure; a
// `Request` (a whole `Config` at most) is large, and there is no allocator
// to box it.
#![cfg_attr(target_os = "none", allow(clippy::result_large_err))]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "the firmware runs on the STM32F407: build it with `cargo fw` \
         (or `cargo fw-qemu` for the QEMU replay variant)"
    );
}

#[cfg(all(target_os = "none", not(feature = "qemu")))]
#[path = "firmware/hw.rs"]
mod board;

#[cfg(target_os = "none")]
#[path = "firmware/usart.rs"]
mod usart;

#[cfg(target_os = "none")]
#[path = "firmware/rtt.rs"]
mod rtt;

#[cfg(all(target_os = "none", feature = "qemu"))]
#[path = "firmware/qemu.rs"]
mod board;

#[cfg(all(target_os = "none", feature = "qemu"))]
use defmt_semihosting as _;

/// What the fault tasks leave for the control task (lock-free).
#[cfg(target_os = "none")]
static EVENTS: cable_joint::board::Events = cable_joint::board::Events::new();

/// The QEMU trace is played: the control task stops stepping, and the
/// telemetry task, once it has flushed, arms the watchdog test (first boot)
/// or ends the run (recovery boot).
#[cfg(all(target_os = "none", feature = "qemu"))]
static DONE: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Two words of RAM that the start-up code leaves alone (cortex-m-rt's
/// `.uninit`): a panic or HardFault handler writes its fault here before the
/// reset, and the next boot reads it (`cable_joint::board::boot`).
#[cfg(target_os = "none")]
#[link_section = ".uninit.BOOT_NOTE"]
static mut BOOT_NOTE: core::mem::MaybeUninit<[u32; 2]> = core::mem::MaybeUninit::uninit();

/// Leave `fault` for the next boot.
#[cfg(target_os = "none")]
fn write_boot_note(fault: cable_joint::Fault) {
    let words = cable_joint::board::boot::record(fault);
    // SAFETY: a volatile store of two plain words to a static no other code
    // touches while a handler runs (the handlers never return).
    unsafe { core::ptr::write_volatile(core::ptr::addr_of_mut!(BOOT_NOTE).cast(), words) };
}

/// Read and erase the note left before the last reset.
#[cfg(target_os = "none")]
fn take_boot_note() -> Option<cable_joint::Fault> {
    let note = core::ptr::addr_of_mut!(BOOT_NOTE).cast::<[u32; 2]>();
    // SAFETY: init runs once, before any task or handler; the words may hold
    // power-up noise, which `recorded` rejects by its check word.
    let words = unsafe { core::ptr::read_volatile(note) };
    unsafe { core::ptr::write_volatile(note, [0, 0]) };
    cable_joint::board::boot::recorded(words)
}

/// The ports on which a host has sent a valid frame (a bit per [`Via`]):
/// telemetry goes up those too.
#[cfg(target_os = "none")]
static LINK_UP: core::sync::atomic::AtomicU8 = core::sync::atomic::AtomicU8::new(0);

/// The two ports of the host link, one protocol on both.
#[cfg(target_os = "none")]
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Via {
    /// USART2 (QEMU's second serial port).
    Serial = 1,
    /// RTT channel 1, through the debug probe.
    Rtt = 2,
}

/// A frame as it arrived, and the port to answer on.
#[cfg(target_os = "none")]
pub struct Incoming {
    via: Via,
    frame: heapless::Vec<u8, { cable_joint::link::MAX_WIRE_LEN }>,
}

/// The transmitting side of both ports.
#[cfg(target_os = "none")]
pub struct Links {
    serial: usart::FrameTx,
    rtt: rtt::FrameTx,
}

#[cfg(target_os = "none")]
impl Links {
    /// Send `msg` on `via`.
    fn send(&mut self, via: Via, msg: &cable_joint::link::Up) {
        match via {
            Via::Serial => self.serial.send(msg),
            Via::Rtt => self.rtt.send(msg),
        }
    }
}

/// Log one telemetry record as a `tlm [bytes]` line, and send it up each
/// port of the host link on which a host has spoken.
#[cfg(target_os = "none")]
fn log_record(record: &cable_joint::telemetry::Record, links: Option<&mut Links>) {
    let mut buf = [0u8; cable_joint::telemetry::MAX_RECORD_LEN];
    let bytes = record.encode(&mut buf);
    defmt::info!("tlm {=[u8]}", bytes);
    let Some(links) = links else { return };
    let up = LINK_UP.load(core::sync::atomic::Ordering::Relaxed);
    for via in [Via::Serial, Via::Rtt] {
        if up & via as u8 != 0 {
            links.send(via, &cable_joint::link::Up::Telemetry(bytes));
        }
    }
}

/// Feed one received byte of `via` to its frame reader; a complete frame
/// goes to `spawn` (the `link_frame` task), which gives it back when that
/// task is still busy with the last one.
#[cfg(target_os = "none")]
fn assemble(
    reader: &mut cable_joint::link::FrameReader<{ cable_joint::link::MAX_WIRE_LEN }>,
    byte: u8,
    via: Via,
    spawn: impl FnOnce(Incoming) -> Result<(), Incoming>,
) {
    use cable_joint::link::{Pushed, MAX_WIRE_LEN};
    match reader.push(byte) {
        Pushed::Pending => {}
        Pushed::Dropped => defmt::warn!(
            "link: frame longer than {=usize} bytes dropped",
            MAX_WIRE_LEN
        ),
        Pushed::Frame(n) => {
            let Ok(frame) = heapless::Vec::from_slice(&reader.frame()[..n]) else {
                return;
            };
            if spawn(Incoming { via, frame }).is_err() {
                // The host waits for each answer: it sent too soon.
                defmt::warn!("link: frame dropped, the last one is still being checked");
            }
        }
    }
}

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [SPI1, SPI2])]
mod app {
    use cable_joint::board::boot::boot_fault;
    use cable_joint::board::{
        on_drive_fault_edge, on_origin_edge, ControlLoop, DriveEnable, InputLine, Program, Request,
    };
    use cable_joint::link::{receive, FrameReader, Refusal, Refused, Repeats, Up, MAX_WIRE_LEN};
    use cable_joint::telemetry::Record;
    use core::sync::atomic::Ordering;
    use heapless::spsc::{Consumer, Producer, Queue};

    use super::{
        assemble, board, log_record, rtt, take_boot_note, usart, Incoming, Links, Via, EVENTS,
        LINK_UP,
    };

    #[shared]
    struct Shared {
        /// The host link's transmit sides (the link and telemetry tasks,
        /// both priority 1: the lock costs nothing).
        links: Links,
    }

    #[local]
    struct Local {
        control: ControlLoop,
        front_end: board::FrontEnd,
        counter: board::Counter,
        drive: DriveEnable<board::DrivePin>,
        tick: board::TickTimer,
        watchdog: board::Watchdog,
        requests_rx: Consumer<'static, Request>,
        requests_tx: Producer<'static, Request>,
        telemetry_tx: Producer<'static, Record>,
        telemetry_rx: Consumer<'static, Record>,
        drive_fault: InputLine<board::FaultPin>,
        origin: InputLine<board::OriginPin>,
        link_rx: usart::Rx,
        rtt_rx: rtt::Rx,
    }

    #[init(local = [
        requests: Queue<Request, 4> = Queue::new(),
        telemetry: Queue<Record, 64> = Queue::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let config = board::config();
        // Why the last reset happened, before anything can overwrite it.
        let note = take_boot_note();
        let watchdog_reset = board::take_watchdog_reset_flag();
        // Drive disabled first, then clocks, sensors and the control timer.
        let mut b = board::init(cx.device, cx.core, config.control_rate_hz);
        let mut control = match ControlLoop::new(config, board::TELEMETRY_DECIMATION) {
            Ok(c) => c,
            Err(e) => panic!("invalid built-in configuration: {}", e.field),
        };
        if let Some(fault) = boot_fault(note, watchdog_reset) {
            // The drive stays off until an operator clears it.
            control.report_boot_fault(fault);
            defmt::error!(
                "last reset: fault {=u8} ({}); drive off until cleared",
                fault.code(),
                defmt::Display2Format(&fault)
            );
        }
        // An already asserted fault line has no edge to report it.
        let origin = b.origin.asserted();
        let fault = b.drive_fault.asserted();
        EVENTS.init_levels(origin, fault);
        log_record(&Record::Start(control.start_record()), None);
        defmt::info!(
            "cable-joint firmware up: {=f32} Hz control, telemetry every {=u32} ticks",
            config.control_rate_hz,
            board::TELEMETRY_DECIMATION
        );
        let (mut requests_tx, requests_rx) = cx.local.requests.split();
        let (telemetry_tx, telemetry_rx) = cx.local.telemetry.split();
        // The built-in program: check, homing, then its command. The queue
        // is empty, so this cannot fail; the host link can send another.
        if requests_tx
            .enqueue(Request::Program(Program::default()))
            .is_err()
        {
            defmt::error!("could not start the program");
        }
        (
            Shared {
                links: Links {
                    serial: usart::FrameTx::new(b.link_tx),
                    rtt: rtt::FrameTx::take(),
                },
            },
            Local {
                control,
                front_end: b.front_end,
                counter: b.counter,
                drive: b.drive,
                tick: b.tick,
                watchdog: b.watchdog,
                requests_rx,
                requests_tx,
                telemetry_tx,
                telemetry_rx,
                drive_fault: b.drive_fault,
                origin: b.origin,
                link_rx: b.link_rx,
                rtt_rx: rtt::Rx::take(),
            },
        )
    }

    /// Idle: read the host link's RTT down channel (a probe cannot raise
    /// an interrupt, so it is polled after every wake-up: each control
    /// tick on the board), then sleep until the next interrupt.
    #[idle(local = [rtt_rx, reader: FrameReader<MAX_WIRE_LEN> = FrameReader::new()])]
    fn idle(cx: idle::Context) -> ! {
        let idle::LocalResources { rtt_rx, reader, .. } = cx.local;
        loop {
            let mut bytes = [0u8; 64];
            loop {
                let n = rtt_rx.read(&mut bytes);
                if n == 0 {
                    break;
                }
                for &byte in &bytes[..n] {
                    assemble(reader, byte, Via::Rtt, link_frame::spawn);
                }
            }
            cortex_m::asm::wfi();
        }
    }

    /// Control tick: sample, step, DAC, drive line, telemetry record.
    ///
    /// Deadline: the next TIM6 update, one control period (500 µs at the
    /// default 2 kHz, 50 µs at 20 kHz); the measured tick is about 3000
    /// instructions (docs/firmware.md). Preempted only by the fault inputs.
    /// On overrun (the next update flagged before this task ends) the
    /// controller latches `Fault::Overrun` through `report_fault` and the
    /// drive is disabled immediately; from the next tick on the output is
    /// zero until an operator `Request::ClearFault`.
    #[task(binds = TIM6_DAC, priority = 3, local = [
        control, front_end, counter, drive, tick, watchdog, requests_rx, telemetry_tx,
        dropped: u32 = 0,
        origin_pending: Option<Record> = None,
    ])]
    fn control(cx: control::Context) {
        let control::LocalResources {
            control,
            front_end,
            counter,
            drive,
            tick,
            watchdog,
            requests_rx,
            telemetry_tx,
            dropped,
            origin_pending,
            ..
        } = cx.local;
        #[cfg(feature = "qemu")]
        if super::DONE.load(core::sync::atomic::Ordering::SeqCst) {
            board::after_trace(watchdog);
            return;
        }
        tick.ack();
        let request = requests_rx.dequeue();
        let outcome = control.tick(front_end, drive, &EVENTS, request, counter);
        let mut queued = false;
        // The origin record is never dropped: the host converts every
        // later record's counts with it. While the queue has no room for
        // it, it waits here and the tick records after it are dropped
        // (counted), so the stream keeps its order.
        // A new origin supersedes one still waiting.
        let waiting = match outcome.origin {
            Some(origin) => Some(Record::Origin(origin)),
            None => origin_pending.take(),
        };
        if let Some(record) = waiting {
            *origin_pending = telemetry_tx.enqueue(record).err();
            queued |= origin_pending.is_none();
        }
        if outcome.telemetry_due {
            if origin_pending.is_none() {
                if push(telemetry_tx, Record::Tick(outcome.record), dropped) {
                    // The next record's applied current starts here; a
                    // dropped record leaves its ticks to the next one.
                    control.record_queued();
                    queued = true;
                }
            } else {
                *dropped = dropped.wrapping_add(1);
            }
        }
        if tick.overran() {
            control.overrun(drive);
        } else {
            // Only a tick that completed in time feeds the watchdog: a hung
            // or starved control task resets the MCU (drive off through the
            // enable line's pull-down), reported at the next boot.
            watchdog.feed();
        }
        // PIL: the answer to the host's plant (nothing on the board).
        front_end.after_tick(&outcome);
        #[cfg(feature = "qemu")]
        if front_end.finished() {
            // The tick source keeps running: the software watchdog lives in it.
            super::DONE.store(true, core::sync::atomic::Ordering::SeqCst);
            queued = true;
        }
        if queued || !telemetry_tx.is_empty() {
            // Fails only while the task is running or already spawned. Each
            // run takes only what was queued when it started (`drain`), so
            // records queued meanwhile spawn it again on a later tick, even
            // when the queue is full and this tick's record was dropped.
            telemetry::spawn().ok();
        }
    }

    fn push(tx: &mut Producer<'static, Record>, record: Record, dropped: &mut u32) -> bool {
        if tx.enqueue(record).is_err() {
            *dropped = dropped.wrapping_add(1);
            false
        } else {
            true
        }
    }

    /// Drive fault line (EXTI1, both edges): cut the drive, leave the fault.
    /// Deadline: none beyond "at once"; it preempts the control task.
    #[task(binds = EXTI1, priority = 4, local = [drive_fault, kill: board::Kill = board::Kill])]
    fn drive_fault(cx: drive_fault::Context) {
        board::clear_exti(1);
        on_drive_fault_edge(cx.local.drive_fault, cx.local.kill, &EVENTS);
    }

    /// Origin switch (EXTI2, both edges): homing input, or a fault when the
    /// joint estimate is away from zero (`board::on_origin_edge`).
    #[task(binds = EXTI2, priority = 4, local = [origin, kill: board::Kill = board::Kill])]
    fn origin_switch(cx: origin_switch::Context) {
        board::clear_exti(2);
        on_origin_edge(cx.local.origin, cx.local.kill, &EVENTS);
    }

    /// QEMU only: TIM5 stands in for TIM6, which QEMU does not model, and
    /// runs the software watchdog that stands in for the IWDG.
    #[cfg(all(feature = "qemu", not(feature = "pil")))]
    #[task(binds = TIM5, priority = 5)]
    fn qemu_tick(_: qemu_tick::Context) {
        board::on_tick_source();
    }

    /// PIL only: TIM4 wakes the idle loop, which polls the RTT down
    /// channel (lowest priority: it never delays a tick).
    #[cfg(feature = "pil")]
    #[task(binds = TIM4, priority = 1)]
    fn rtt_wake(_: rtt_wake::Context) {
        board::on_wake();
    }

    /// PIL only: the host plant's sensor frame is the tick (see the QEMU
    /// board's docs).
    #[cfg(feature = "pil")]
    #[task(binds = USART3, priority = 5)]
    fn sensor_bus(_: sensor_bus::Context) {
        board::on_sensor_bus();
    }

    /// Host link, receive interrupt (USART2): bytes into frames; each
    /// complete frame goes to the `link_frame` task. Deadline: the next byte
    /// (22 µs at 460 800 baud); it only copies.
    #[task(binds = USART2, priority = 2, local = [
        link_rx,
        reader: FrameReader<MAX_WIRE_LEN> = FrameReader::new(),
    ])]
    fn link_rx(cx: link_rx::Context) {
        let link_rx::LocalResources {
            link_rx, reader, ..
        } = cx.local;
        while let Some(byte) = link_rx.read() {
            assemble(reader, byte, Via::Serial, link_frame::spawn);
        }
    }

    /// Host link frames: checked down to a request (frame, version, body,
    /// content; a configuration is validated and its filters designed
    /// here), queued for the control task, which applies one per tick, and
    /// answered with an acknowledgement that names a refusal. No deadline.
    #[task(priority = 1, shared = [links], local = [requests_tx, repeats: Repeats = Repeats::new()])]
    async fn link_frame(mut cx: link_frame::Context, incoming: Incoming) {
        let Incoming { via, mut frame } = incoming;
        let n = frame.len();
        let received = receive(&mut frame, n);
        let (seq, crc) = (received.seq, received.crc);
        let refused = match received.outcome {
            Ok(_) if cx.local.repeats.is_repeat(&received) => {
                // Its acknowledgement was lost: acknowledge, apply once.
                defmt::info!(
                    "link: resend of frame {=u8} acknowledged, not applied again",
                    seq
                );
                None
            }
            Ok(request) => {
                LINK_UP.fetch_or(via as u8, Ordering::Relaxed);
                match cx.local.requests_tx.enqueue(request) {
                    Ok(()) => {
                        cx.local.repeats.queued(seq, crc);
                        None
                    }
                    Err(_) => {
                        defmt::warn!("request queue full: request refused");
                        Some(Refusal::Busy)
                    }
                }
            }
            Err(Refused::Invalid(e)) => {
                defmt::warn!(
                    "request rejected: {=str} must be {=str}",
                    e.field,
                    e.expected
                );
                Some(Refusal::Invalid)
            }
            Err(Refused::Frame(e)) => {
                defmt::warn!("link: {}", defmt::Display2Format(&e));
                Some(Refusal::Frame(e.code()))
            }
        };
        let ack = Up::Ack { seq, refused };
        cx.shared.links.lock(|links| links.send(via, &ack));
    }

    /// Telemetry: encode the queued raw records and log them; report phase
    /// and fault changes as text. No deadline: when it falls behind, the
    /// control task drops records (counted) instead of waiting. Each run
    /// takes the records queued when it starts ([`drain`]).
    #[task(priority = 1, shared = [links], local = [telemetry_rx, last: (u8, u8) = (u8::MAX, 0)])]
    async fn telemetry(mut cx: telemetry::Context) {
        let telemetry::LocalResources {
            telemetry_rx, last, ..
        } = cx.local;
        cx.shared
            .links
            .lock(|links| drain(telemetry_rx, last, links, DRAIN_MAX));
        #[cfg(feature = "qemu")]
        if super::DONE.load(core::sync::atomic::Ordering::SeqCst) {
            // The control task stopped before setting DONE: this drain
            // flushes everything it queued.
            cx.shared
                .links
                .lock(|links| drain(telemetry_rx, last, links, usize::MAX));
            defmt::info!("trace played");
            board::trace_played();
        }
    }

    /// Most records one run of the telemetry task sends: a host frame that
    /// arrives meanwhile waits for at most these before `link_frame`
    /// checks it (13 ms of the link at 460 800 baud). A run that took the
    /// whole queue (64 records, about 0.1 s of the link, as long under
    /// QEMU) held acknowledgements back so long that the host sent most
    /// requests twice and applied commands late.
    const DRAIN_MAX: usize = 8;

    /// Log and send the records queued when it starts, at most `max`:
    /// records the control task queues meanwhile wait for the next run
    /// (its spawn on the next tick), so the task returns and a host frame
    /// waiting at the same priority (`link_frame`) is checked in between.
    /// Draining until the queue was empty starved it whenever the control
    /// task queued records as fast as the link sent them (PIL under QEMU,
    /// telemetry every tick: every host frame after the first dropped).
    fn drain(
        rx: &mut Consumer<'static, Record>,
        last: &mut (u8, u8),
        links: &mut Links,
        max: usize,
    ) {
        for _ in 0..rx.len().min(max) {
            let Some(record) = rx.dequeue() else { break };
            log_record(&record, Some(&mut *links));
            if let Record::Tick(t) = record {
                if (t.phase, t.fault) != *last {
                    defmt::info!(
                        "tick {=u32}: phase {=u8}, fault {=u8}, mode {=u8}",
                        t.tick,
                        t.phase,
                        t.fault,
                        t.mode
                    );
                    *last = (t.phase, t.fault);
                }
            }
        }
    }
}

/// Set by the first panic: a panic inside the panic handler's logging goes
/// straight to the halt.
#[cfg(target_os = "none")]
static PANICKING: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Panic: the drive is disabled before anything else, the fault is left for
/// the next boot, the message is logged (dropped if the logger is busy: the
/// RTT logger never blocks and never masks interrupts), then
/// `board::halt_failure` (hardware: stop for an attached debugger, else
/// reset; QEMU: a semihosting failure exit).
#[cfg(target_os = "none")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    board::kill_drive();
    write_boot_note(cable_joint::Fault::Panic);
    if !PANICKING.swap(true, core::sync::atomic::Ordering::SeqCst) {
        defmt::error!("panic: {}", defmt::Display2Format(info));
    }
    board::halt_failure()
}

/// HardFault: drive disabled, the fault left for the next boot, then as a
/// panic.
#[cfg(target_os = "none")]
#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    board::kill_drive();
    write_boot_note(cable_joint::Fault::HardFault);
    board::halt_failure()
}
