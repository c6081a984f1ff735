//! A progress bar on stderr for long work (`indicatif`), drawn only when stderr is a terminal:
//! pipes, files and tests see nothing new.

use std::io::IsTerminal;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use voxd::cancel::Control;

/// Work shorter than this draws no bar.
const QUIET: Duration = Duration::from_millis(300);
/// How often the bar reads the progress.
const TICK: Duration = Duration::from_millis(100);

/// Runs `work` with a fresh [`Control`]; while it runs (past a moment) a bar labelled `what`
/// shows the control's progress on stderr, when stderr is a terminal. The bar is cleared when
/// the work returns.
pub fn with_bar<T>(what: &str, work: impl FnOnce(&Control) -> T) -> T {
    let ctl = Control::new();
    if !std::io::stderr().is_terminal() {
        return work(&ctl);
    }
    std::thread::scope(|s| {
        let (done, finished) = mpsc::channel::<()>();
        let (watched, label) = (ctl.clone(), what.to_string());
        s.spawn(move || {
            if !matches!(finished.recv_timeout(QUIET), Err(RecvTimeoutError::Timeout)) {
                return;
            }
            let bar = ProgressBar::new(1000);
            if let Ok(style) = ProgressStyle::with_template(
                "{msg} [{elapsed_precise}] {wide_bar} {percent:>3}% (eta {eta})",
            ) {
                bar.set_style(style);
            }
            bar.set_message(label);
            loop {
                bar.set_position((watched.progress() * 1000.0) as u64);
                if !matches!(finished.recv_timeout(TICK), Err(RecvTimeoutError::Timeout)) {
                    break;
                }
            }
            bar.finish_and_clear();
        });
        let out = work(&ctl);
        drop(done);
        out
    })
}
