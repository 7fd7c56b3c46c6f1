//! Progress on stderr: one spinner per stage, hidden when stderr is not a terminal.

use std::cell::RefCell;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Where progress goes: a terminal's stderr, or nowhere (tests, `eval`'s parallel trials).
pub struct Progress {
    visible: bool,
    current: RefCell<Option<ProgressBar>>,
}

impl Progress {
    /// Spinners on stderr; indicatif draws nothing when stderr is not a terminal.
    pub fn stderr() -> Self {
        Self {
            visible: true,
            current: RefCell::new(None),
        }
    }

    /// No spinners; warnings still go to stderr.
    pub fn hidden() -> Self {
        Self {
            visible: false,
            current: RefCell::new(None),
        }
    }

    /// Starts the spinner of a stage.
    pub fn start(&self, stage: &str) {
        let bar = if self.visible {
            ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
        } else {
            ProgressBar::hidden()
        };
        let style = ProgressStyle::with_template("{spinner:.cyan} {msg:<9} {elapsed:>4}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner());
        bar.set_style(style);
        bar.set_message(stage.to_string());
        bar.enable_steady_tick(Duration::from_millis(100));
        *self.current.borrow_mut() = Some(bar);
    }

    /// Ends the current stage's spinner; the run's summary reports the stage's time.
    pub fn finish(&self) {
        if let Some(bar) = self.current.borrow_mut().take() {
            bar.finish_and_clear();
        }
    }

    /// Ends the current spinner without a result (the stage failed).
    pub fn abandon(&self) {
        if let Some(bar) = self.current.borrow_mut().take() {
            bar.finish_and_clear();
        }
    }

    /// Prints a warning on stderr without tearing the spinner.
    pub fn warn(&self, message: &str) {
        match self.current.borrow().as_ref() {
            Some(bar) => bar.suspend(|| eprintln!("warning: {message}")),
            None => eprintln!("warning: {message}"),
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.abandon();
    }
}
