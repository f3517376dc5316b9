//! The live view of a run, in the terminal: joint angle (reference and
//! estimate), the fused force estimate with its bound, the motor current
//! (command and measured), the start-up phase, the drive and the fault,
//! redrawn as the telemetry arrives: `host-sim link --view` on the rig (or
//! on QEMU), `host-sim pil --view` and `host-sim trace --view`.
//!
//! [`Live`] holds what is shown and draws it on any ratatui backend (the
//! tests draw it into a buffer); [`Screen`] puts it on the terminal, reads
//! the operator's keys, and gives the terminal back as it found it, also
//! when the run fails.

use std::collections::VecDeque;
use std::io::{self, IsTerminal, Stdout};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use cable_joint::board::Phase;
use cable_joint::controller::Mode;
use cable_joint::fault::Fault;
use cable_joint::telemetry::TickRecord;
use cable_joint::units::Scales;
use cable_joint::Config;
use ratatui::backend::CrosstermBackend;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::crossterm::execute;
use ratatui::crossterm::terminal::{
    disable_raw_mode, enable_raw_mode, EnterAlternateScreen, LeaveAlternateScreen,
};
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{Axis, Block, Chart, Dataset, GraphType, Paragraph};
use ratatui::{Frame, Terminal};

use crate::operator::Losses;
use crate::trace::Ticked;

/// Firmware seconds the charts span.
pub const WINDOW_S: f64 = 5.0;

/// Shortest wall time between two redraws (20 frames per second).
const REDRAW: Duration = Duration::from_millis(50);

/// `--view`, shared by the commands that can show a run live.
#[derive(clap::Args, Debug, Clone, Copy, Default)]
pub struct ViewArg {
    /// Show the run live in the terminal: joint angle (reference and
    /// estimate), force estimate with its bound, motor current, phase,
    /// drive and fault; `q` quits. Needs a terminal.
    #[arg(long)]
    pub view: bool,
}

/// One tick as the charts show it, in display units.
#[derive(Clone, Copy, Debug)]
struct Point {
    t_s: f64,
    ref_deg: f64,
    est_deg: f64,
    force_n: f64,
    lo_n: f64,
    hi_n: f64,
    current_ref_a: f64,
    current_a: f64,
}

/// What the view shows: the last [`WINDOW_S`] of ticks and the state of
/// the newest.
#[derive(Clone, Debug)]
pub struct Live {
    source: String,
    rate_hz: f64,
    scales: Scales,
    points: VecDeque<Point>,
    last: Option<TickRecord>,
    records: u64,
    /// Records the stream lost since the first (or a restart).
    losses: Losses,
    first_fault: Option<(u32, u8)>,
    note: String,
    finished: bool,
}

impl Live {
    /// A view of `source` (shown in the title) running at `rate_hz`, its
    /// current monitor read with `scales`.
    pub fn new(source: impl Into<String>, rate_hz: f64, scales: Scales) -> Self {
        Live {
            source: source.into(),
            rate_hz,
            scales,
            points: VecDeque::new(),
            last: None,
            records: 0,
            losses: Losses::default(),
            first_fault: None,
            note: String::new(),
            finished: false,
        }
    }

    /// The host asked the firmware for a record every `n` ticks: losses
    /// are counted at that decimation, from the first record after which
    /// every tick is a multiple of it (the boot streams every tick).
    #[must_use]
    pub fn asked_every(mut self, n: Option<u32>) -> Self {
        self.losses = Losses::new(n);
        self
    }

    /// Take in one tick record.
    pub fn push(&mut self, r: &TickRecord) {
        let t_s = f64::from(r.tick) / self.rate_hz;
        // A tick counter that went back is a restarted firmware: start over.
        if self.points.back().is_some_and(|p| p.t_s > t_s) {
            self.points.clear();
        }
        self.losses.push(r.tick);
        self.points.push_back(Point {
            t_s,
            ref_deg: f64::from(r.theta_ref_rad).to_degrees(),
            est_deg: f64::from(r.theta_hat_rad).to_degrees(),
            force_n: f64::from(r.f_ext_fused_n),
            lo_n: f64::from(r.f_ext_lo_n),
            hi_n: f64::from(r.f_ext_hi_n),
            current_ref_a: f64::from(r.current_ref_a),
            current_a: f64::from(self.scales.adc_a(r.raw.current)),
        });
        while self.points.front().is_some_and(|p| p.t_s < t_s - WINDOW_S) {
            self.points.pop_front();
        }
        if r.fault != 0 && self.first_fault.is_none() {
            self.first_fault = Some((r.tick, r.fault));
        }
        self.records += 1;
        self.last = Some(*r);
    }

    /// The command's own status (what it records, what it sent), shown in
    /// the footer.
    pub fn set_note(&mut self, note: impl Into<String>) {
        self.note = note.into();
    }

    /// The run is over: the footer says so and asks for `q`.
    pub fn finish(&mut self) {
        self.finished = true;
    }

    /// Tick records taken in.
    pub fn records(&self) -> u64 {
        self.records
    }

    /// Tick records the stream lost since its first (or since the firmware
    /// restarted), at the decimation asked for ([`Live::asked_every`]) or
    /// else the smallest tick step seen ([`Losses`]).
    pub fn lost(&self) -> u64 {
        self.losses.lost()
    }

    /// Draw the view on `frame`.
    pub fn draw(&self, frame: &mut Frame) {
        let [head, angle, force, current, foot] = Layout::vertical([
            Constraint::Length(2),
            Constraint::Fill(1),
            Constraint::Fill(1),
            Constraint::Fill(1),
            Constraint::Length(1),
        ])
        .areas(frame.area());
        frame.render_widget(Paragraph::new(self.header()), head);
        let last = self.points.back().copied();
        let t1 = last.map_or(WINDOW_S, |l| l.t_s.max(WINDOW_S));
        let x = [t1 - WINDOW_S, t1];
        for (panel, area) in PANELS.iter().zip([angle, force, current]) {
            chart(frame, area, panel, &self.points, x);
        }
        frame.render_widget(Paragraph::new(self.footer()), foot);
    }

    /// Source, tick, phase and mode of the newest record; its drive and
    /// fault on a line of their own.
    fn header(&self) -> Vec<Line<'static>> {
        let bold = Style::new().add_modifier(Modifier::BOLD);
        let mut spans = vec![Span::styled(
            format!("cable joint · {} ", self.source),
            bold,
        )];
        let Some(r) = self.last else {
            spans.push(Span::raw("· waiting for telemetry"));
            return vec![Line::from(spans)];
        };
        let phase = Phase::from_code(r.phase).map_or_else(
            || format!("code {}", r.phase),
            |p| format!("{p:?}").to_lowercase(),
        );
        let mode = Mode::from_code(r.mode)
            .map_or_else(|| format!("code {}", r.mode), |m| format!("{m:?}"));
        spans.push(Span::raw(format!(
            "· tick {} ({:.2} s) · phase {phase} · mode {mode}",
            r.tick,
            f64::from(r.tick) / self.rate_hz
        )));
        let drive = if r.drive_enable {
            Span::styled("drive on", Style::new().fg(Color::Green))
        } else {
            Span::styled("drive off", Style::new().fg(Color::Yellow))
        };
        let fault = match r.fault {
            0 => Span::raw("fault none"),
            code => Span::styled(
                format!("FAULT {code}: {}", fault_text(code)),
                Style::new()
                    .fg(Color::White)
                    .bg(Color::Red)
                    .add_modifier(Modifier::BOLD),
            ),
        };
        vec![
            Line::from(spans),
            Line::from(vec![drive, Span::raw(" · "), fault]),
        ]
    }

    /// Records, the first fault, the command's note, the keys.
    fn footer(&self) -> Line<'static> {
        let mut text = format!("{} records", self.records);
        match self.lost() {
            0 => {}
            n => text.push_str(&format!(" ({n} lost)")),
        }
        if let Some((tick, code)) = self.first_fault {
            text.push_str(&format!(" · first fault {code} at tick {tick}"));
        }
        if !self.note.is_empty() {
            text.push_str(" · ");
            text.push_str(&self.note);
        }
        let keys = if self.finished {
            Span::styled(
                "run finished: q quits",
                Style::new().add_modifier(Modifier::REVERSED),
            )
        } else {
            Span::raw("q quits")
        };
        Line::from(vec![Span::raw(text), Span::raw(" · "), keys])
    }
}

/// A fault code in words.
fn fault_text(code: u8) -> String {
    Fault::from_code(code).map_or_else(|| "unknown code".to_string(), |f| f.to_string())
}

/// One line of a chart: its legend, colour, and value at a tick.
struct Trace {
    name: &'static str,
    color: Color,
    value: fn(&Point) -> f64,
}

/// One chart of the view: its title, the newest values written after it,
/// and its lines.
struct Panel {
    name: &'static str,
    readout: fn(&Point) -> String,
    lines: &'static [Trace],
}

/// The view's charts, top to bottom.
const PANELS: [Panel; 3] = [
    Panel {
        name: "joint angle, deg",
        readout: |l| format!("reference {:.2}  estimate {:.2} ", l.ref_deg, l.est_deg),
        lines: &[
            Trace {
                name: "reference",
                color: Color::Yellow,
                value: |q| q.ref_deg,
            },
            Trace {
                name: "estimate",
                color: Color::Cyan,
                value: |q| q.est_deg,
            },
        ],
    },
    Panel {
        name: "external force, N",
        readout: |l| {
            format!(
                "estimate {:.2}  bound [{:.2}, {:.2}] ",
                l.force_n, l.lo_n, l.hi_n
            )
        },
        lines: &[
            Trace {
                name: "lower",
                color: Color::DarkGray,
                value: |q| q.lo_n,
            },
            Trace {
                name: "upper",
                color: Color::DarkGray,
                value: |q| q.hi_n,
            },
            Trace {
                name: "estimate",
                color: Color::Green,
                value: |q| q.force_n,
            },
        ],
    },
    Panel {
        name: "motor current, A",
        readout: |l| {
            format!(
                "command {:.3}  measured {:.3} ",
                l.current_ref_a, l.current_a
            )
        },
        lines: &[
            Trace {
                name: "command",
                color: Color::Yellow,
                value: |q| q.current_ref_a,
            },
            Trace {
                name: "measured",
                color: Color::Magenta,
                value: |q| q.current_a,
            },
        ],
    },
];

/// At most two points per column of a chart `width` cells wide (braille
/// has two dots per cell), each column's newest sample.
fn series(points: &VecDeque<Point>, width: u16, f: impl Fn(&Point) -> f64) -> Vec<(f64, f64)> {
    let most = 2 * usize::from(width.max(1));
    let stride = points.len().div_ceil(most).max(1);
    points
        .iter()
        .rev()
        .step_by(stride)
        .map(|p| (p.t_s, f(p)))
        .filter(|&(_, y)| y.is_finite())
        .collect()
}

/// One panel's chart over `x`, the y range fitted to what is shown.
fn chart(frame: &mut Frame, area: Rect, panel: &Panel, points: &VecDeque<Point>, x: [f64; 2]) {
    let data: Vec<Vec<(f64, f64)>> = panel
        .lines
        .iter()
        .map(|line| series(points, area.width, line.value))
        .collect();
    let (lo, hi) =
        crate::stats::finite_range(data.iter().flatten().map(|&(_, y)| y)).unwrap_or((-1.0, 1.0));
    let pad = ((hi - lo) * 0.1).max(1e-3 * hi.abs().max(lo.abs()).max(1.0));
    let y = [lo - pad, hi + pad];
    let title = Line::from(vec![
        Span::styled(
            format!(" {} ", panel.name),
            Style::new().add_modifier(Modifier::BOLD),
        ),
        Span::raw(points.back().map_or(String::new(), panel.readout)),
    ]);
    let datasets = panel
        .lines
        .iter()
        .zip(&data)
        .map(|(line, data)| {
            Dataset::default()
                .name(line.name)
                .marker(Marker::Braille)
                .graph_type(GraphType::Line)
                .style(Style::new().fg(line.color))
                .data(data)
        })
        .collect();
    let widget = Chart::new(datasets)
        .block(Block::bordered().title(title))
        .x_axis(
            Axis::default()
                .bounds(x)
                .labels([format!("{:.1} s", x[0]), format!("{:.1} s", x[1])]),
        )
        .y_axis(
            Axis::default()
                .bounds(y)
                .labels([format!("{:.2}", y[0]), format!("{:.2}", y[1])]),
        )
        .hidden_legend_constraints((Constraint::Percentage(40), Constraint::Percentage(60)));
    frame.render_widget(widget, area);
}

/// How a closed-loop run shows its progress (`host-sim trace`, `host-sim
/// pil`): a progress bar, or the live view, which also paces the run to
/// real time so that a person can follow it.
pub struct Watch {
    view: Option<(Screen, Live)>,
    bar: indicatif::ProgressBar,
    rate_hz: f64,
    started: Instant,
}

impl Watch {
    /// The live view of `source` if `view.view`, else a progress bar drawn
    /// with `template` (indicatif's).
    pub fn new(
        view: ViewArg,
        source: &str,
        config: &Config,
        template: &str,
    ) -> anyhow::Result<Watch> {
        let rate_hz = f64::from(config.control_rate_hz);
        let (view, bar) = if view.view {
            let screen = Screen::open()?;
            let live = Live::new(source, rate_hz, config.scales);
            (Some((screen, live)), indicatif::ProgressBar::hidden())
        } else {
            let bar = indicatif::ProgressBar::new(0);
            bar.set_style(
                indicatif::ProgressStyle::with_template(template)
                    .context("progress bar template")?,
            );
            (None, bar)
        };
        Ok(Watch {
            view,
            bar,
            rate_hz,
            started: Instant::now(),
        })
    }

    /// After tick `k` of `n`: redraw; with the view, wait for the tick's
    /// time, and stop the run (an error) when the operator quits.
    pub fn tick(&mut self, k: usize, n: usize, outcome: &Ticked) -> anyhow::Result<()> {
        let Some((screen, live)) = &mut self.view else {
            if k == 1 {
                self.bar.set_length(n as u64);
            }
            self.bar.set_position(k as u64);
            return Ok(());
        };
        live.push(&outcome.record);
        let due = self.started + Duration::from_secs_f64(k as f64 / self.rate_hz);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        if screen.refresh(live)? {
            bail!("stopped with q at tick {k} of {n}; nothing written");
        }
        Ok(())
    }

    /// The run is over and its files written (`note` says which): clear
    /// the bar, or show the view's last state until the operator quits.
    pub fn finish(mut self, note: &str) -> anyhow::Result<()> {
        self.bar.finish_and_clear();
        if let Some((screen, live)) = &mut self.view {
            live.set_note(note);
            screen.hold(live)?;
        }
        Ok(())
    }
}

/// The live view on this terminal: the alternate screen in raw mode,
/// given back when the screen is dropped.
pub struct Screen {
    terminal: Terminal<CrosstermBackend<Stdout>>,
    drawn: Option<Instant>,
}

impl Screen {
    /// Take over the terminal; an error if standard output is not one.
    pub fn open() -> anyhow::Result<Screen> {
        if !io::stdout().is_terminal() {
            bail!("--view needs a terminal, and standard output is not one (drop --view, or run the command in a terminal)");
        }
        enable_raw_mode().context("putting the terminal in raw mode")?;
        let mut stdout = io::stdout();
        if let Err(e) = execute!(stdout, EnterAlternateScreen) {
            let _ = disable_raw_mode();
            return Err(e).context("entering the terminal's alternate screen");
        }
        let terminal = Terminal::new(CrosstermBackend::new(stdout));
        match terminal {
            Ok(terminal) => Ok(Screen {
                terminal,
                drawn: None,
            }),
            Err(e) => {
                restore();
                Err(e).context("opening the terminal")
            }
        }
    }

    /// Redraw `live` if the last frame is older than 50 ms, and read the
    /// keys typed since: `true` when the operator asked to quit (`q`,
    /// `Esc` or `Ctrl-C`).
    pub fn refresh(&mut self, live: &Live) -> anyhow::Result<bool> {
        if self.drawn.is_none_or(|t| t.elapsed() >= REDRAW) {
            self.terminal
                .draw(|f| live.draw(f))
                .context("drawing the live view")?;
            self.drawn = Some(Instant::now());
        }
        quit_typed(Duration::ZERO)
    }

    /// The run is over: show its last state until the operator quits.
    pub fn hold(&mut self, live: &mut Live) -> anyhow::Result<()> {
        live.finish();
        loop {
            self.terminal
                .draw(|f| live.draw(f))
                .context("drawing the live view")?;
            if quit_typed(Duration::from_millis(200))? {
                return Ok(());
            }
        }
    }
}

impl Drop for Screen {
    fn drop(&mut self) {
        let _ = self.terminal.show_cursor();
        restore();
    }
}

/// Leave the alternate screen and raw mode.
fn restore() {
    let _ = execute!(io::stdout(), LeaveAlternateScreen);
    let _ = disable_raw_mode();
}

/// Was `q`, `Esc` or `Ctrl-C` typed (waiting at most `wait` for a key)?
fn quit_typed(wait: Duration) -> anyhow::Result<bool> {
    let mut wait = wait;
    while event::poll(wait).context("reading the terminal's keys")? {
        wait = Duration::ZERO;
        if let Event::Key(k) = event::read().context("reading the terminal's keys")? {
            let ctrl_c =
                k.code == KeyCode::Char('c') && k.modifiers.contains(KeyModifiers::CONTROL);
            if k.kind == KeyEventKind::Press
                && (matches!(k.code, KeyCode::Char('q') | KeyCode::Esc) || ctrl_c)
            {
                return Ok(true);
            }
        }
    }
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cable_joint::controller::RawSample;
    use cable_joint::telemetry::Inputs;
    use cable_joint::units::{AdcCode, DacCode};
    use ratatui::backend::TestBackend;

    fn tick(k: u32, fault: u8) -> TickRecord {
        let t = f64::from(k) / 2000.0;
        TickRecord {
            tick: k,
            raw: RawSample {
                current: AdcCode(2048 + 82),
                ..Default::default()
            },
            inputs: Inputs(0),
            dac: DacCode(2048),
            current_ref_a: 0.25,
            current_applied_a: 0.25,
            theta_ref_rad: 30f32.to_radians(),
            theta_hat_rad: (30.0 - 2.0 * (-t).exp() as f32).to_radians(),
            f_ext_hat_n: 0.5,
            f_ext_fused_n: 0.49,
            f_ext_lo_n: 0.21,
            f_ext_hi_n: 0.77,
            mode: Mode::JointClosedLoop.code(),
            fault,
            drive_enable: fault == 0,
            phase: Phase::Running.code(),
            cycles: 1000,
            stage_cycles: [0; 4],
        }
    }

    fn screen_text(live: &Live) -> String {
        let mut t = Terminal::new(TestBackend::new(140, 40)).unwrap();
        t.draw(|f| live.draw(f)).unwrap();
        let buf = t.backend().buffer().clone();
        let area = buf.area;
        (0..area.height)
            .map(|y| {
                (0..area.width)
                    .map(|x| buf[(x, y)].symbol().to_string())
                    .collect::<String>()
                    + "\n"
            })
            .collect()
    }

    #[test]
    fn the_view_shows_the_newest_state_and_the_bound() {
        let mut live = Live::new("tcp:127.0.0.1:5555", 2000.0, Scales::default());
        for k in 0..12_000 {
            live.push(&tick(k, 0));
        }
        live.set_note("recording loading.csv");
        let text = screen_text(&live);
        for want in [
            "cable joint · tcp:127.0.0.1:5555",
            "tick 11999 (6.00 s)",
            "phase running",
            "drive on",
            "fault none",
            "reference 30.00",
            "estimate 0.49  bound [0.21, 0.77]",
            "command 0.250",
            "12000 records",
            "recording loading.csv",
            "1.0 s",
            "6.0 s",
        ] {
            assert!(text.contains(want), "{want:?} missing from\n{text}");
        }
        // Only the window's ticks are kept: 5 s at 2 kHz.
        assert!((10_000..=10_001).contains(&live.points.len()));
        // Lines are drawn: braille dots in the chart areas.
        assert!(text.chars().any(|c| ('\u{2801}'..='\u{28ff}').contains(&c)));
    }

    #[test]
    fn a_fault_is_named_and_its_first_tick_kept() {
        let mut live = Live::new("sim", 2000.0, Scales::default());
        for k in 0..100 {
            live.push(&tick(k, 0));
        }
        for k in 100..200 {
            live.push(&tick(k, Fault::DriveFault.code()));
        }
        live.finish();
        let text = screen_text(&live);
        let drive = Fault::DriveFault.to_string();
        assert!(text.contains(&format!("FAULT 21: {drive}")), "{text}");
        assert!(text.contains("drive off"), "{text}");
        assert!(text.contains("first fault 21 at tick 100"), "{text}");
        assert!(text.contains("run finished: q quits"), "{text}");
    }

    #[test]
    fn a_view_before_any_telemetry_says_it_waits() {
        let live = Live::new("tcp:127.0.0.1:5555", 2000.0, Scales::default());
        assert!(screen_text(&live).contains("waiting for telemetry"));
    }

    #[test]
    fn a_restarted_firmware_starts_the_charts_over() {
        let mut live = Live::new("sim", 2000.0, Scales::default());
        for k in 0..500 {
            live.push(&tick(k, 0));
        }
        live.push(&tick(3, 0));
        assert_eq!(live.points.len(), 1);
        assert_eq!(live.records(), 501);
        assert_eq!(live.lost(), 0);
    }

    #[test]
    fn records_the_stream_lost_are_counted_at_its_decimation() {
        let mut live = Live::new("sim", 2000.0, Scales::default());
        // A record every 4th tick, ticks 40 to 76 lost (10 records).
        for k in (0..200).step_by(4).filter(|k| !(40..80).contains(k)) {
            live.push(&tick(k, 0));
        }
        assert_eq!(live.lost(), 10);
        assert!(screen_text(&live).contains("40 records (10 lost)"));
    }

    #[test]
    fn records_before_a_decimation_request_took_effect_are_not_counted_as_lost() {
        let mut live = Live::new("sim", 2000.0, Scales::default()).asked_every(Some(4));
        // The boot streams every tick; the request takes effect at tick 99.
        for k in 0..99 {
            live.push(&tick(k, 0));
        }
        for k in (100..400).step_by(4) {
            live.push(&tick(k, 0));
        }
        assert_eq!(live.lost(), 0);
        assert!(!screen_text(&live).contains("lost"));
        // Then ticks 200 to 236 lost.
        let mut live = Live::new("sim", 2000.0, Scales::default()).asked_every(Some(4));
        for k in (0..99).chain((100..400).step_by(4).filter(|k| !(200..240).contains(k))) {
            live.push(&tick(k, 0));
        }
        assert_eq!(live.lost(), 10);
    }
}
