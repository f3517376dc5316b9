//! Processor in the loop: the firmware binary (`cargo fw-pil`: the QEMU
//! build with the sensor bus instead of the embedded trace) runs on QEMU's
//! netduinoplus2 and closes the loop on the simulated prototype, in
//! lockstep over QEMU's emulated serial ports:
//!
//! | QEMU `-serial` | firmware | host |
//! |---|---|---|
//! | 1 (USART1) | unused | `null` |
//! | 2 (USART2) | the host link, as on the board | [`crate::operator::Client`] (requests), or a TCP port for `host-sim link` (`--link-port`) |
//! | 3 (USART3) | the sensor bus | this module: one [`SensorFrame`] per tick, answered by the tick's record |
//!
//! With [`PilOptions::rtt`] the run's requests take the link's other port
//! instead: RTT channel 1, through QEMU's GDB stub ([`crate::gdb_rtt`]),
//! as a probe reaches it on the board; [`PilOptions::gdb_port`] opens the
//! stub for `host-sim link --port rtt:127.0.0.1:PORT`.
//!
//! Each tick the host sends the sample the board would have read, waits for
//! the tick's telemetry record (DAC code, drive enable), applies the current
//! to the plant over one period, and sends the next sample: the loop of
//! [`crate::trace::record_on`], the same as the host-only run of the same
//! firmware logic ([`cable_joint::board::Harness`]), so the two can be
//! compared tick by tick. `-icount shift=0` makes TIM2 count guest
//! instructions, which the records carry per tick and per stage.

use std::fs::File;
use std::io::ErrorKind;
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use cable_joint::board::{Phase, Program, Request, TraceSample};
use cable_joint::link::SensorFrame;
use cable_joint::telemetry::{Record, TickRecord};

use crate::ingest::{cycle_stats, CycleStats};
use crate::operator::{down_for, Client, Frame, LosesAcks};
use crate::plant::PlantParams;
use crate::trace::{
    record_on, record_with, Firmware, Inject, NoInjection, Progress, Recorded, Ticked, TraceOptions,
};

/// How the PIL run starts QEMU.
#[derive(Debug, Clone)]
pub struct PilOptions {
    /// The PIL firmware (`cargo fw-pil`; its ELF).
    pub elf: PathBuf,
    /// Where QEMU's defmt stream (`qemu.defmt`) and stderr go.
    pub out_dir: PathBuf,
    /// Expose the firmware link on this local TCP port (for `host-sim
    /// link`) instead of keeping it for the run's own requests.
    pub link_port: Option<u16>,
    /// Longest wait for one tick's answer (QEMU's start included for the
    /// first).
    pub tick_timeout: Duration,
    /// Acknowledgements on the run's own link that the line loses (the
    /// `n`-th from 0; [`crate::operator::LosesAcks`]): the request is sent
    /// again and must act once, at the same tick.
    pub lost_acks: Vec<usize>,
    /// The run's own requests go over RTT channel 1 through QEMU's GDB
    /// stub instead of USART2.
    pub rtt: bool,
    /// Open QEMU's GDB stub on this local TCP port (for `host-sim link
    /// --port rtt:127.0.0.1:PORT`, or the run's own RTT link); with
    /// [`PilOptions::rtt`] and no port, a free one is picked.
    pub gdb_port: Option<u16>,
}

impl PilOptions {
    /// The options of a run of `elf` writing to `out_dir`: the link's USART
    /// kept for the run's own requests, no lost acknowledgements, no GDB
    /// stub, 20 s for an answer.
    pub fn new(elf: PathBuf, out_dir: PathBuf) -> Self {
        Self {
            elf,
            out_dir,
            link_port: None,
            tick_timeout: Duration::from_secs(20),
            lost_acks: Vec::new(),
            rtt: false,
            gdb_port: None,
        }
    }
}

/// A local TCP port nobody listens on (for QEMU's GDB stub).
fn free_port() -> anyhow::Result<u16> {
    let l = TcpListener::bind("127.0.0.1:0").context("finding a free local port")?;
    Ok(l.local_addr()?.port())
}

/// The firmware binary on QEMU, driven tick by tick.
pub struct Pil {
    child: Child,
    /// The sensor bus: samples down, the ticks' records up.
    bus: Client,
    link: Option<Client>,
    /// A request went over the link: the firmware now streams its
    /// telemetry there too, which this run reads and drops.
    link_up: bool,
    timeout: Duration,
    out_dir: PathBuf,
}

/// Wait for QEMU to connect to `listener`, or fail if it exits first.
fn accept(
    listener: &TcpListener,
    child: &mut Child,
    what: &str,
    out_dir: &Path,
) -> anyhow::Result<TcpStream> {
    listener.set_nonblocking(true)?;
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        match listener.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false)?;
                s.set_nodelay(true)?;
                return Ok(s);
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {}
            Err(e) => return Err(e).context(format!("accepting QEMU's {what}")),
        }
        if let Some(status) = child.try_wait()? {
            bail!(
                "QEMU exited ({status}) before connecting its {what}; see {}",
                out_dir.join("qemu.stderr").display()
            );
        }
        if Instant::now() > deadline {
            bail!("QEMU did not connect its {what} within 20 s");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

impl Pil {
    /// Start QEMU on the PIL firmware and connect its serial ports.
    pub fn start(opts: &PilOptions) -> anyhow::Result<Self> {
        anyhow::ensure!(
            opts.elf.is_file(),
            "the PIL firmware {} does not exist: build it with `cargo fw-pil`",
            opts.elf.display()
        );
        crate::output::ensure_dir(&opts.out_dir)?;
        let bus =
            TcpListener::bind("127.0.0.1:0").context("opening a local port for the sensor bus")?;
        let bus_port = bus.local_addr()?.port();
        let (link_serial, link_listener) = match opts.link_port {
            Some(p) => (
                format!("tcp:127.0.0.1:{p},server=on,wait=off,nodelay=on"),
                None,
            ),
            None if opts.rtt => ("null".to_owned(), None),
            None => {
                let l = TcpListener::bind("127.0.0.1:0")
                    .context("opening a local port for the link")?;
                (
                    format!("tcp:127.0.0.1:{},nodelay=on", l.local_addr()?.port()),
                    Some(l),
                )
            }
        };
        let gdb_port = match opts.gdb_port {
            Some(p) => Some(p),
            None if opts.rtt => Some(free_port()?),
            None => None,
        };
        let defmt = File::create(opts.out_dir.join("qemu.defmt"))?;
        let stderr = File::create(opts.out_dir.join("qemu.stderr"))?;
        let mut qemu = Command::new("qemu-system-arm");
        if let Some(p) = gdb_port {
            qemu.args(["-gdb", &format!("tcp:127.0.0.1:{p}")]);
        }
        let mut child = qemu
            .args([
                "-machine",
                "netduinoplus2",
                "-nographic",
                "-monitor",
                "none",
            ])
            .args(["-serial", "null", "-serial", &link_serial])
            .args(["-serial", &format!("tcp:127.0.0.1:{bus_port},nodelay=on")])
            .args(["-semihosting-config", "enable=on,target=native"])
            // Instructions, not host time, drive the virtual clock inside a
            // tick (TIM2 counts them); sleep=on lets it follow the host's
            // time while the firmware waits for the next sample.
            .args(["-icount", "shift=0,sleep=on", "-kernel"])
            .arg(&opts.elf)
            .stdin(Stdio::null())
            .stdout(defmt)
            .stderr(stderr)
            .spawn()
            .context("starting qemu-system-arm (install it: apt-get install qemu-system-arm)")?;
        let lossy = |port: Box<dyn crate::operator::Port>| -> Box<dyn crate::operator::Port> {
            if opts.lost_acks.is_empty() {
                port
            } else {
                Box::new(LosesAcks::new(port, opts.lost_acks.clone()))
            }
        };
        // QEMU connects its client ports in order: the link, then the bus.
        let link = match &link_listener {
            Some(l) => {
                let s = accept(l, &mut child, "link port (USART2)", &opts.out_dir)?;
                Some(Client::new(lossy(Box::new(s)))?)
            }
            None => None,
        };
        let bus = accept(&bus, &mut child, "sensor bus (USART3)", &opts.out_dir)?;
        let mut pil = Self {
            child,
            bus: Client::new(Box::new(bus))?,
            link,
            link_up: false,
            timeout: opts.tick_timeout,
            out_dir: opts.out_dir.clone(),
        };
        // Bytes sent before the firmware opens the bus are lost.
        if let Frame::Telemetry(_) = pil.next_up("the firmware's ready frame")? {
            bail!("the firmware sent telemetry before its ready frame");
        }
        if let (true, Some(p)) = (opts.rtt, gdb_port) {
            // After the ready frame: the RTT block is in RAM by then.
            let rtt = crate::gdb_rtt::GdbRtt::connect(&format!("127.0.0.1:{p}"))
                .context("reaching the firmware's RTT channel through QEMU's GDB stub")?;
            pil.link = Some(Client::new(lossy(Box::new(rtt)))?);
        }
        Ok(pil)
    }

    /// Stop QEMU (the run has no end of its own).
    pub fn stop(mut self) -> anyhow::Result<()> {
        self.child.kill().ok();
        self.child.wait()?;
        Ok(())
    }

    /// The next frame up the sensor bus (`what` names it in errors).
    fn next_up(&mut self, what: &str) -> anyhow::Result<Frame> {
        let deadline = Instant::now() + self.timeout;
        loop {
            if let Some(frame) = self.bus.next_frame()? {
                return Ok(frame);
            }
            if self.bus.damaged > 0 {
                bail!("{what}: a frame on the sensor bus arrived damaged");
            }
            if let Some(status) = self.child.try_wait()? {
                bail!(
                    "QEMU exited ({status}) while waiting for {what}; the firmware's log: {}",
                    self.out_dir.join("qemu.defmt").display()
                );
            }
            if Instant::now() > deadline {
                bail!("no {what} within {:.1} s", self.timeout.as_secs_f64());
            }
        }
    }

    fn answer(&mut self, k: usize) -> anyhow::Result<Ticked> {
        let mut origin = None;
        loop {
            match self.next_up(&format!("answer to tick {k}"))? {
                Frame::Ack { .. } => {
                    bail!("tick {k}: the firmware restarted (a second ready frame)")
                }
                Frame::Telemetry(Record::Origin(o)) => origin = Some(o),
                Frame::Telemetry(Record::Tick(record)) => {
                    return Ok(Ticked {
                        record,
                        origin,
                        drive_enabled: record.drive_enable,
                    })
                }
                Frame::Telemetry(Record::Start(_)) => {}
            }
        }
    }
}

impl Drop for Pil {
    fn drop(&mut self) {
        self.child.kill().ok();
        self.child.wait().ok();
    }
}

impl Firmware for Pil {
    fn tick(
        &mut self,
        k: usize,
        sample: &TraceSample,
        request: Option<Request>,
    ) -> anyhow::Result<Ticked> {
        // The firmware queues its built-in program itself at boot.
        let builtin = k == 0 && request == Some(Request::Program(Program::default()));
        if let (Some(req), false) = (request, builtin) {
            let Some(client) = self.link.as_mut() else {
                bail!("tick {k}: the link is given to `host-sim link` (--link-port); this run cannot send requests");
            };
            // Acknowledged before the sample goes out: queued for this tick,
            // as the host harness takes it.
            client.request(&down_for(&req)?)?;
            self.link_up = true;
        }
        let frame = SensorFrame {
            tick: k as u32,
            sample: *sample,
        };
        self.bus.send(&frame, &format!("tick {k}'s sample"))?;
        let answer = self.answer(k)?;
        if let (true, Some(link)) = (self.link_up, self.link.as_mut()) {
            // QEMU blocks on a full socket, and the whole machine with it.
            link.discard_waiting()?;
        }
        Ok(answer)
    }
}

/// The PIL run against the host-only run of the same firmware logic on
/// the same plant, noise and load.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// The firmware binary's run.
    pub pil: Recorded,
    /// The host harness's run.
    pub host: Recorded,
    /// Ticks whose records agree bit for bit (instruction counts and the
    /// applied mean current aside).
    pub identical_ticks: usize,
    /// The first tick where they do not.
    pub first_difference: Option<usize>,
    /// Largest |θ̂ PIL − θ̂ host|, rad.
    pub max_theta_hat_diff_rad: f64,
    /// Largest |F̂ PIL − F̂ host| (the DOB's), N.
    pub max_f_ext_hat_diff_n: f64,
    /// Tracking and force errors of each run.
    pub errors: [RunErrors; 2],
    /// Instructions per tick and per stage in the PIL run (TIM2 under
    /// `-icount shift=0`), over the ticks the controller stepped.
    pub instructions: Option<CycleStats>,
}

/// What a closed-loop run achieved, judged on the plant's truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunErrors {
    /// RMS of θ_ref − θ over the ticks with the program running and the
    /// drive on, rad.
    pub tracking_rms_rad: f64,
    /// Largest |θ_ref − θ| there, rad.
    pub tracking_max_rad: f64,
    /// Mean |F̂ − F| of the DOB over the ticks with the full load hung and
    /// the drive on, N (NaN without such ticks).
    pub force_mean_abs_n: f64,
    /// Ticks those means cover: tracking, force.
    pub ticks: (usize, usize),
}

impl RunErrors {
    /// The errors of `rec` (the load as `opts` hangs it).
    pub fn of(rec: &Recorded, opts: &TraceOptions) -> Self {
        let period = 1.0 / f64::from(rec.control_rate_hz);
        let running = Phase::Running.code();
        let (mut sq, mut max, mut n) = (0.0, 0.0f64, 0usize);
        let (mut f_sum, mut f_n) = (0.0, 0usize);
        for (k, o) in rec.outcomes.iter().enumerate() {
            let r = &o.record;
            if r.phase != running || !r.drive_enable {
                continue;
            }
            let e = f64::from(r.theta_ref_rad) - rec.theta_true_rad[k];
            sq += e * e;
            max = max.max(e.abs());
            n += 1;
            let t = k as f64 * period;
            if opts.load_n != 0.0 && t >= opts.load_at_s + 0.05 {
                f_sum += (f64::from(r.f_ext_hat_n) - rec.f_ext_true_n[k]).abs();
                f_n += 1;
            }
        }
        Self {
            tracking_rms_rad: if n > 0 {
                (sq / n as f64).sqrt()
            } else {
                f64::NAN
            },
            tracking_max_rad: max,
            force_mean_abs_n: if f_n > 0 {
                f_sum / f_n as f64
            } else {
                f64::NAN
            },
            ticks: (n, f_n),
        }
    }
}

/// A record without its instruction counts (which only the MCU has) and
/// without its applied mean current: the firmware restarts that mean when
/// its telemetry queue took the last record due, which under QEMU depends
/// on how fast the link's host reads (a record dropped from a full queue
/// leaves its ticks to the next one), while the host harness sends every
/// record. Its arithmetic is compared bit for bit by the QEMU proof's
/// replay (`tests/qemu_replay.rs`, no link, nothing dropped) and tested on
/// the host (`trace::tests`).
fn arithmetic(r: &TickRecord) -> TickRecord {
    TickRecord {
        cycles: 0,
        stage_cycles: [0; 4],
        current_applied_a: 0.0,
        ..*r
    }
}

/// Run `opts` on the PIL firmware and on the host harness, and compare.
/// `progress` is called after each PIL tick.
pub fn compare(
    plant: PlantParams,
    opts: &TraceOptions,
    pil: &PilOptions,
    progress: &mut Progress,
) -> anyhow::Result<Comparison> {
    compare_with(plant, opts, pil, &|| Box::new(NoInjection), progress)
}

/// [`compare`] with the operator's requests of `inject()` (a fresh one for
/// each run): the PIL run sends them over the firmware link, acknowledged
/// before the tick's sample goes out, the host harness takes them at the
/// same tick.
pub fn compare_with(
    plant: PlantParams,
    opts: &TraceOptions,
    pil: &PilOptions,
    inject: &dyn Fn() -> Box<dyn Inject>,
    progress: &mut Progress,
) -> anyhow::Result<Comparison> {
    anyhow::ensure!(
        !opts.probing,
        "the PIL firmware boots with the built-in configuration (probing off); \
         send another over the link instead of --probe"
    );
    let config = opts.config();
    let host = record_with(plant, opts, config, inject().as_mut())?;
    let mut firmware = Pil::start(pil)?;
    let pil_run = record_on(
        plant,
        opts,
        config,
        inject().as_mut(),
        &mut firmware,
        progress,
    );
    firmware.stop()?;
    let pil_run = pil_run?;
    let mut identical = 0;
    let mut first = None;
    let (mut d_theta, mut d_force) = (0.0f64, 0.0f64);
    for (k, (a, b)) in pil_run.outcomes.iter().zip(&host.outcomes).enumerate() {
        if arithmetic(&a.record) == arithmetic(&b.record) && a.origin == b.origin {
            identical += 1;
        } else if first.is_none() {
            first = Some(k);
        }
        d_theta = d_theta.max(f64::from(a.record.theta_hat_rad - b.record.theta_hat_rad).abs());
        d_force = d_force.max(f64::from(a.record.f_ext_hat_n - b.record.f_ext_hat_n).abs());
    }
    let stepped: Vec<TickRecord> = pil_run
        .outcomes
        .iter()
        .map(|o| o.record)
        .filter(|r| r.step_cycles() > 0)
        .collect();
    Ok(Comparison {
        errors: [RunErrors::of(&pil_run, opts), RunErrors::of(&host, opts)],
        instructions: cycle_stats(&stepped),
        identical_ticks: identical,
        first_difference: first,
        max_theta_hat_diff_rad: d_theta,
        max_f_ext_hat_diff_n: d_force,
        pil: pil_run,
        host,
    })
}

impl std::fmt::Display for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.pil.outcomes.len();
        writeln!(
            f,
            "ticks identical to the host run (instruction counts and applied mean aside): {} of \
             {n}{}",
            self.identical_ticks,
            match self.first_difference {
                Some(k) => format!(", first difference at tick {k}"),
                None => String::new(),
            }
        )?;
        writeln!(
            f,
            "largest difference: theta_hat {:.3e} rad, F_ext_hat {:.3e} N",
            self.max_theta_hat_diff_rad, self.max_f_ext_hat_diff_n
        )?;
        writeln!(
            f,
            "{:<6} {:>18} {:>18} {:>22}",
            "run", "tracking RMS (deg)", "tracking max (deg)", "DOB mean |error| (N)"
        )?;
        for (name, e) in ["PIL", "host"].iter().zip(&self.errors) {
            writeln!(
                f,
                "{name:<6} {:>18.4} {:>18.4} {:>22.4}",
                e.tracking_rms_rad.to_degrees(),
                e.tracking_max_rad.to_degrees(),
                e.force_mean_abs_n
            )?;
        }
        match &self.instructions {
            Some(s) => write!(f, "instructions per tick (PIL, -icount shift=0):\n{s}"),
            None => write!(f, "no tick stepped the controller: no instruction counts"),
        }
    }
}
