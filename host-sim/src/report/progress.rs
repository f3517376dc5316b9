//! The report's progress on stderr: a spinner on a terminal, plain lines
//! otherwise.

use std::time::Instant;

/// Progress lines on stderr (`[  12.3 s] clean: ...`).
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    start: Instant,
    quiet: bool,
    /// A spinner with the current step and the elapsed time, when stderr is
    /// a terminal; plain lines otherwise (a log file, CI).
    /// (One per report run, kept to the end of the process so that the
    /// settings that carry it stay `Copy`; [`Progress::finish`] clears it.)
    bar: Option<&'static indicatif::ProgressBar>,
}

impl Progress {
    /// Start the clock (and the spinner, on a terminal).
    pub fn new(quiet: bool) -> Self {
        use std::io::IsTerminal as _;
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let bar = indicatif::ProgressBar::new_spinner();
            if let Ok(style) =
                indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
            {
                bar.set_style(style);
            }
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            &*Box::leak(Box::new(bar))
        });
        Self {
            start: Instant::now(),
            quiet,
            bar,
        }
    }

    /// Seconds since the start.
    pub fn elapsed_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// One step: a line kept above the spinner on a terminal, a plain line
    /// on stderr otherwise.
    pub fn line(&self, tag: &str, msg: &str) {
        if self.quiet {
            return;
        }
        let text = format!("[{:6.1} s] {tag}: {msg}", self.elapsed_s());
        match &self.bar {
            Some(bar) => {
                bar.println(&text);
                bar.set_message(format!("{tag}: {msg}"));
            }
            None => eprintln!("{text}"),
        }
    }

    /// Clear the spinner (the lines above it stay).
    pub fn finish(&self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}
