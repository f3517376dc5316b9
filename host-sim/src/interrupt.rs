//! Ctrl-C and `kill`: a command stopped by a signal leaves no temporary
//! file behind, and `link` keeps what it received.
//!
//! [`install`] (from `main`) takes SIGINT, SIGTERM and SIGHUP on a thread of
//! its own. While a [`Graceful`] guard is alive (`link`'s receiving loop),
//! the first signal only sets [`requested`]: the loop ends as its `q` key
//! ends it, and the recording is written. Otherwise, and on a second
//! signal, every temporary file a live [`Outputs`](crate::output::Outputs)
//! staged and every directory one made is removed
//! ([`crate::output::remove_staged`]; the targets are as they were, or all
//! replaced if a commit was under way) and the process exits with `128 +`
//! the signal's number, as a shell reports a process the signal ended.

use std::sync::atomic::{AtomicBool, Ordering};

/// A [`Graceful`] guard is alive.
static GRACEFUL: AtomicBool = AtomicBool::new(false);
/// A signal arrived while one was.
static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Take SIGINT, SIGTERM and SIGHUP as the module says.
///
/// # Errors
/// The handlers or their thread cannot be set up.
pub fn install() -> std::io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            for signal in signals.forever() {
                if GRACEFUL.load(Ordering::SeqCst) && !REQUESTED.swap(true, Ordering::SeqCst) {
                    eprintln!(
                        "\nhost-sim: signal {signal}: stopping; what was received is kept (send it \
                         again to stop at once)"
                    );
                    continue;
                }
                let _held = crate::output::remove_staged();
                eprintln!(
                    "\nhost-sim: stopped by signal {signal}: no output half-written, its \
                     temporary files removed"
                );
                std::process::exit(128 + signal);
            }
        })?;
    Ok(())
}

/// While alive, the first signal asks the holder to stop ([`requested`])
/// instead of ending the process.
#[derive(Debug)]
pub struct Graceful(());

impl Graceful {
    /// Start a stretch in which the first signal only asks.
    pub fn new() -> Self {
        REQUESTED.store(false, Ordering::SeqCst);
        GRACEFUL.store(true, Ordering::SeqCst);
        Self(())
    }
}

impl Default for Graceful {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for Graceful {
    fn drop(&mut self) {
        GRACEFUL.store(false, Ordering::SeqCst);
    }
}

/// A signal asked the [`Graceful`] holder to stop.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}
