//! `host-sim link` against a stand-in for the firmware's link on a local
//! socket: what a run received is kept when the link fails part way.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::ops::Range;
use std::process::Command;

use cable_joint::link::{encode, receive, FrameReader, Pushed, Up, MAX_WIRE_LEN};
use cable_joint::telemetry::{
    OriginRecord, Record, StartRecord, TickRecord, FORMAT_VERSION, MAX_RECORD_LEN,
};

/// Telemetry records the stand-in sends before it closes the link.
const SENT_TICKS: u32 = 500;

fn send(s: &mut TcpStream, seq: &mut u8, msg: &Up) {
    try_send(s, seq, msg).unwrap();
}

fn try_send(s: &mut TcpStream, seq: &mut u8, msg: &Up) -> std::io::Result<()> {
    let mut wire = [0u8; MAX_WIRE_LEN];
    let sent = s.write_all(encode(msg, *seq, &mut wire).unwrap());
    *seq = seq.wrapping_add(1);
    sent
}

fn send_record(s: &mut TcpStream, seq: &mut u8, record: Record) {
    let mut bytes = [0u8; MAX_RECORD_LEN];
    send(s, seq, &Up::Telemetry(record.encode(&mut bytes)));
}

/// [`send_record`] for a stand-in that outlives the host: whether the host
/// still takes records (it closes the link when it stops on an error, and
/// a write after that fails at a time the kernel picks).
fn send_record_while_open(s: &mut TcpStream, seq: &mut u8, record: Record) -> bool {
    let mut bytes = [0u8; MAX_RECORD_LEN];
    try_send(s, seq, &Up::Telemetry(record.encode(&mut bytes))).is_ok()
}

/// What the stand-in sends.
#[derive(Clone)]
struct Stream {
    /// An origin record where homing ends (tick `SENT_TICKS / 2`).
    origin: bool,
    /// Ticks not sent (records a link dropped).
    lost: Range<u32>,
    /// The host sets this decimation (`--decimation`): the stand-in sends
    /// [`EARLY_TICKS`] records every tick first, then acknowledges the
    /// request and sends every N-th tick.
    decimation: Option<u32>,
}

/// Records sent every tick before a decimation request is taken.
const EARLY_TICKS: u32 = 10;

/// The next request frame's sequence number.
fn next_request(s: &mut TcpStream, reader: &mut FrameReader<MAX_WIRE_LEN>) -> u8 {
    let mut buf = [0u8; 256];
    loop {
        let n = s.read(&mut buf).unwrap();
        assert!(n > 0, "the host closed before its request");
        for &b in &buf[..n] {
            if let Pushed::Frame(len) = reader.push(b) {
                return receive(reader.frame(), len).seq;
            }
        }
    }
}

/// Acknowledges the host's first request (its heartbeat), sends a start
/// record and tick records up to [`SENT_TICKS`], homing for the first half
/// and running after it, as `stream` says, then closes the connection, as a
/// board that loses power would.
fn firmware_that_stops(listener: TcpListener, stream: Stream) {
    let (mut s, _) = listener.accept().unwrap();
    let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
    let mut up_seq = 0u8;
    let seq = next_request(&mut s, &mut reader);
    send(&mut s, &mut up_seq, &Up::Ack { seq, refused: None });
    let start = StartRecord {
        version: FORMAT_VERSION,
        control_rate_hz: 2000.0,
        decimation: 1,
    };
    send_record(&mut s, &mut up_seq, Record::Start(start));
    let mut step = 1;
    let mut tick = 0;
    while tick < SENT_TICKS {
        if let (Some(n), EARLY_TICKS) = (stream.decimation, tick) {
            let seq = next_request(&mut s, &mut reader);
            send(&mut s, &mut up_seq, &Up::Ack { seq, refused: None });
            step = n;
            tick = tick.next_multiple_of(n);
        }
        if tick == SENT_TICKS / 2 && stream.origin {
            let o = OriginRecord {
                tick,
                ..OriginRecord::default()
            };
            send_record(&mut s, &mut up_seq, Record::Origin(o));
        }
        if !stream.lost.contains(&tick) {
            let t = TickRecord {
                tick,
                phase: if tick < SENT_TICKS / 2 { 3 } else { 4 },
                mode: 1,
                drive_enable: true,
                dac: cable_joint::units::DacCode(2048),
                ..TickRecord::default()
            };
            send_record(&mut s, &mut up_seq, Record::Tick(t));
        }
        tick += step;
    }
    s.flush().unwrap();
}

/// `host-sim link --duration-s 10 --record` against [`firmware_that_stops`]:
/// whether it succeeded, its stderr and the log's text (if written).
fn record_from_stand_in(name: &str, stream: Stream) -> (bool, String, Option<String>) {
    let dir = std::env::temp_dir().join(format!("link-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("run.csv");
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let decimation = stream.decimation;
    let firmware = std::thread::spawn(move || firmware_that_stops(listener, stream));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_host-sim"));
    cmd.args(["link", "--port", &format!("tcp:127.0.0.1:{port}")])
        .args(["--duration-s", "10", "--record"])
        .arg(&log);
    if let Some(n) = decimation {
        cmd.args(["--decimation", &n.to_string()]);
    }
    let before_s = unix_now_s();
    let out = cmd.output().unwrap();
    let after_s = unix_now_s();
    firmware.join().unwrap();
    let text = std::fs::read_to_string(&log).ok();
    if let Some(text) = &text {
        host_clock_is_the_runs(text, before_s, after_s);
    }
    std::fs::remove_dir_all(&dir).ok();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        text,
    )
}

/// The host's wall clock, Unix time in seconds.
fn unix_now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// The log's host clock (`t_unix_s`, `host-sim link` stamps it from when
/// records arrived): on every row, advancing with the tick counter at the
/// control rate, and no row stamped after the last record could have
/// arrived. The stand-in sends faster than real time, so the stamps can
/// lie before the run began by at most the ticks' span.
fn host_clock_is_the_runs(text: &str, before_s: f64, after_s: f64) {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (clock, tick) = (at("t_unix_s"), at("tick"));
    let rows: Vec<(f64, f64)> = lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            (cells[clock].parse().unwrap(), cells[tick].parse().unwrap())
        })
        .collect();
    let span_s = f64::from(SENT_TICKS) / 2000.0;
    for &(unix_s, tick) in &rows {
        let (first_unix_s, first_tick) = rows[0];
        let expected = first_unix_s + (tick - first_tick) / 2000.0;
        assert!((unix_s - expected).abs() < 1e-6, "{unix_s} at tick {tick}");
        assert!(
            (before_s - span_s - 1.0..=after_s).contains(&unix_s),
            "{unix_s} outside the run [{before_s}, {after_s}]"
        );
    }
}

/// Every tick sent, an origin record where homing ends.
fn whole() -> Stream {
    Stream {
        origin: true,
        lost: 0..0,
        decimation: None,
    }
}

#[test]
fn a_link_that_closes_part_way_keeps_the_records_received() {
    let (ok, stderr, text) = record_from_stand_in("closes", whole());
    assert!(!ok, "the link reported success: {stderr}");
    assert!(stderr.contains("the firmware link closed"), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "after {SENT_TICKS} tick records at a record every tick, none lost"
        )),
        "{stderr}"
    );
    let text = text.expect("the received records are written");
    let rows = text.lines().count() - 1;
    assert_eq!(rows, SENT_TICKS as usize, "{stderr}");
    assert!(!stderr.contains("origin record"), "{stderr}");
}

#[test]
fn a_homing_whose_origin_record_was_lost_is_named_in_a_warning() {
    let (_, stderr, text) = record_from_stand_in(
        "no-origin",
        Stream {
            origin: false,
            ..whole()
        },
    );
    assert!(text.is_some(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "homing ended by tick {} but its origin record is not in the stream",
            SENT_TICKS / 2
        )),
        "{stderr}"
    );
}

/// Records the link dropped are counted from the gaps of the firmware's tick
/// counter, and the log keeps what arrived.
#[test]
fn records_the_link_lost_are_counted_from_the_tick_counter() {
    let lossy = Stream {
        lost: 100..110,
        ..whole()
    };
    let (_, stderr, text) = record_from_stand_in("lossy", lossy);
    assert!(
        stderr.contains(&format!(
            "after {} tick records at a record every tick; 10 lost in a gap of the tick counter \
             (the longest 0.0055 s, before line 102)",
            SENT_TICKS - 10
        )),
        "{stderr}"
    );
    let rows = text.expect("the log is written").lines().count() - 1;
    assert_eq!(rows, SENT_TICKS as usize - 10);
}

/// After `--decimation 4` the losses are counted at a record every 4th
/// tick, from the first record after the request was acknowledged (the
/// records before it came every tick).
#[test]
fn records_lost_after_a_decimation_request_are_counted_at_that_decimation() {
    let decimated = Stream {
        lost: 200..240,
        decimation: Some(4),
        ..whole()
    };
    let (_, stderr, text) = record_from_stand_in("decimated", decimated);
    // Ticks 0..9, then 12, 16, ..., 496 less the 10 of 200..240.
    let rows = EARLY_TICKS + (SENT_TICKS - 12).div_ceil(4) - 10;
    assert!(
        stderr.contains(&format!(
            "after {rows} tick records at a record every 4 ticks; 10 lost from line 12 in a gap \
             of the tick counter (the longest 0.0220 s, before line 59)"
        )),
        "{stderr}"
    );
    assert_eq!(text.map(|t| t.lines().count() - 1), Some(rows as usize));
}

/// Before it touches the board, `link` warns when it would load a
/// configuration whose force parameters are still the datasheet plant's
/// for a run that rests on the force estimate (a grip regulates it); not
/// for a calibration run, which is what identifies them. The port here is
/// closed, so the command fails after the warning.
#[test]
fn a_grip_with_datasheet_force_parameters_is_warned_before_the_board_is_touched() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    std::fs::write(&cfg, "control_rate_hz = 2000.0\n").unwrap();
    let port = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let run = |scenario: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args([
                "link",
                "--port",
                &format!("tcp:127.0.0.1:{port}"),
                "--config",
            ])
            .arg(&cfg)
            .args(["--scenario", scenario])
            .output()
            .unwrap();
        assert!(!o.status.success(), "nothing listens on port {port}");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let grip = run("grip");
    assert!(
        grip.contains("still the datasheet plant's: the JAE") && grip.contains("the tension model"),
        "{grip}"
    );
    let calibration = run("jae-ident");
    assert!(!calibration.contains("datasheet plant's"), "{calibration}");
}

/// The program `link --scenario NAME` sends first, as the firmware's link
/// receives and checks it (a stand-in that acknowledges the heartbeat and
/// the program, then closes).
fn program_sent_for(scenario: &str) -> cable_joint::board::Program {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let firmware = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
        let mut up_seq = 0u8;
        let mut requests = Vec::new();
        let mut buf = [0u8; 256];
        while requests.len() < 2 {
            let n = s.read(&mut buf).unwrap();
            assert!(n > 0, "the host closed before its program");
            for &b in &buf[..n] {
                if let Pushed::Frame(len) = reader.push(b) {
                    let r = receive(reader.frame(), len);
                    send(
                        &mut s,
                        &mut up_seq,
                        &Up::Ack {
                            seq: r.seq,
                            refused: None,
                        },
                    );
                    requests.push(r.outcome.expect("a valid request"));
                }
            }
        }
        requests
    });
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["link", "--port", &format!("tcp:127.0.0.1:{port}")])
        .args(["--scenario", scenario, "--idle-timeout-s", "0.5"])
        .output()
        .unwrap();
    let requests = firmware.join().unwrap();
    assert!(!o.status.success(), "the stand-in closed the link");
    match requests[1] {
        cable_joint::board::Request::Program(p) => p,
        other => panic!("second request {other:?}, not a program"),
    }
}

/// The no-load motor run needs the rope wheel unhooked, where homing cannot
/// find the origin: `link --scenario bm-noload` sends a motor-only program
/// (no homing; the firmware faults if slider 1 moves), any other scenario
/// one that homes.
#[test]
fn the_no_load_motor_run_is_sent_as_a_motor_only_program() {
    let bm = program_sent_for("bm-noload");
    assert!(bm.homing.motor_only);
    assert_eq!(bm.command.mode, cable_joint::Mode::MotorPosition);
    let jae = program_sent_for("jae-ident");
    assert!(!jae.homing.motor_only);
}

/// A stand-in that runs in real time: a start record, then a tick record
/// every 0.5 ms (sent 20 at a time every 10 ms), homing until `homed_tick`,
/// running after it, for `ticks`; every request acknowledged and kept
/// with the tick and the wall-clock time it arrived at.
fn firmware_in_real_time(
    listener: TcpListener,
    homed_tick: u32,
    ticks: u32,
) -> Vec<(u32, f64, cable_joint::board::Request)> {
    let (mut s, _) = listener.accept().unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_millis(1)))
        .unwrap();
    let mut reader = FrameReader::<MAX_WIRE_LEN>::new();
    let mut up_seq = 0u8;
    let mut requests = Vec::new();
    let start = StartRecord {
        version: FORMAT_VERSION,
        control_rate_hz: 2000.0,
        decimation: 1,
    };
    send_record(&mut s, &mut up_seq, Record::Start(start));
    let began = std::time::Instant::now();
    let mut buf = [0u8; 512];
    let mut tick = 0;
    'run: while tick < ticks {
        // Ticks due by now (2 kHz since `began`), at most 20 at once.
        let due = (began.elapsed().as_secs_f64() * 2000.0) as u32;
        while tick < due.min(ticks) {
            let t = TickRecord {
                tick,
                phase: if tick < homed_tick { 3 } else { 4 },
                mode: 1,
                drive_enable: true,
                dac: cable_joint::units::DacCode(2048),
                ..TickRecord::default()
            };
            if !send_record_while_open(&mut s, &mut up_seq, Record::Tick(t)) {
                break 'run;
            }
            tick += 1;
        }
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                for &b in &buf[..n] {
                    if let Pushed::Frame(len) = reader.push(b) {
                        let r = receive(reader.frame(), len);
                        let ack = Up::Ack {
                            seq: r.seq,
                            refused: None,
                        };
                        send(&mut s, &mut up_seq, &ack);
                        requests.push((tick, unix_now_s(), r.outcome.expect("a valid request")));
                    }
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => break,
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    requests
}

/// `link --scenario jae-ident --start-at T` against [`firmware_in_real_time`]
/// homing until 0.2 s: the program holds the joint where the scenario's
/// first command starts, and that first command goes out when the host's
/// clock reaches T, not when homing ends; the run's length counts the
/// wait. A time in the past is refused before the board is touched, and
/// homing still running at T is an error.
#[test]
fn a_scenario_started_at_a_wall_clock_time_starts_its_motion_then() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let firmware = std::thread::spawn(move || firmware_in_real_time(listener, 400, 3000));
    let start_at = unix_now_s() + 0.8;
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["link", "--port", &format!("tcp:127.0.0.1:{port}")])
        .args(["--scenario", "jae-ident", "--duration-scale", "0.1"])
        .args(["--duration-s", "1.2"])
        .args(["--start-at", &format!("{start_at:.3}")])
        .output()
        .unwrap();
    let requests = firmware.join().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("the scenario's motion starts now"),
        "{stderr}"
    );
    let Some((_, _, cable_joint::board::Request::Program(program))) = requests.get(1) else {
        panic!("second request not a program: {requests:?}");
    };
    assert!(
        matches!(
            program.command.trajectory,
            cable_joint::trajectory::Trajectory::Hold { .. }
        ),
        "{program:?}"
    );
    let commands: Vec<(u32, f64, cable_joint::Command)> = requests
        .iter()
        .filter_map(|(tick, at, r)| match r {
            cable_joint::board::Request::SetCommand(c) => Some((*tick, *at, *c)),
            _ => None,
        })
        .collect();
    assert!(commands.len() >= 2, "{requests:?}");
    let ((tick, at_s, first), (next_tick, _, next)) = (commands[0], commands[1]);
    assert_eq!(first, program_sent_for("jae-ident").command);
    assert!(
        (start_at..start_at + 1.0).contains(&at_s) && tick > 400,
        "first command at {:+.3} s from --start-at, tick {tick}",
        at_s - start_at
    );
    // jae-ident's sine follows its 1 s hold, scaled by 0.1: 200 ticks on
    // (sent on the host's next poll after, never before; the bounds are
    // loose for a loaded machine).
    assert!(
        matches!(
            next.trajectory,
            cable_joint::trajectory::Trajectory::Sine { .. }
        ) && (150..=1000).contains(&(next_tick - tick)),
        "{next:?} {} ticks after the first",
        next_tick - tick
    );
    // In the past: refused before connecting (nothing listens on port 9).
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args([
            "link",
            "--port",
            "tcp:127.0.0.1:9",
            "--scenario",
            "jae-ident",
        ])
        .args(["--start-at", "1000"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("in the past"),
        "{stderr}"
    );
    // Homing until 1 s, the motion asked for at 0.3 s.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let firmware = std::thread::spawn(move || firmware_in_real_time(listener, 2000, 2400));
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["link", "--port", &format!("tcp:127.0.0.1:{port}")])
        .args(["--scenario", "jae-ident", "--duration-s", "1.2"])
        .args(["--start-at", &format!("{:.3}", unix_now_s() + 0.3)])
        .output()
        .unwrap();
    firmware.join().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("homing had not ended"),
        "{stderr}"
    );
}

/// A recording that could not be written (its directory missing, or the
/// path a directory) is refused before the link opens: a rig's run is not
/// spent only to lose its records at the end.
#[test]
fn a_recording_that_cannot_be_written_is_refused_before_the_link_opens() {
    let dir = tempfile::tempdir().unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    for record in [
        dir.path().join("missing").join("run.csv"),
        dir.path().to_owned(),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["link", "--port", &format!("tcp:127.0.0.1:{port}")])
            .args(["--duration-s", "10", "--record"])
            .arg(&record)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{stderr}");
        assert!(
            stderr.contains(&format!("--record {}", record.display()))
                && stderr.contains("nothing was sent to the firmware"),
            "{stderr}"
        );
    }
    // No connection waits to be accepted: the link never opened.
    listener.set_nonblocking(true).unwrap();
    assert_eq!(
        listener.accept().map(|_| ()).unwrap_err().kind(),
        std::io::ErrorKind::WouldBlock
    );
}

/// Ctrl-C (SIGINT) during a recording stops the run as `q` does and the
/// records received are written; without the handler the process died
/// with them in memory and the file was never written.
#[test]
fn ctrl_c_during_a_recording_keeps_what_was_received() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.csv");
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    // 30 s of ticks in real time; the host asks for all of them.
    let firmware = std::thread::spawn(move || firmware_in_real_time(listener, 400, 60_000));
    let child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["link", "--port", &format!("tcp:127.0.0.1:{port}")])
        .args(["--duration-s", "30", "--record"])
        .arg(&log)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    firmware.join().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("stopped with q or Ctrl-C before the end; what was received is kept"),
        "{stderr}"
    );
    let text = std::fs::read_to_string(&log).unwrap();
    let rows = text.lines().count() - 1;
    assert!((100..60_000).contains(&rows), "{rows} rows");
    // Nothing staged is left beside it.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, ["run.csv"]);
}
