//! A one-line progress bar on stderr for long campaigns (loading dozens of 70 s runs
//! takes a while), drawn by `indicatif`. Its stderr target draws nothing when stderr is
//! not a terminal, so logs and pipes stay clean.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Layout of the line: phase, bar, count, elapsed time, current item.
const TEMPLATE: &str = "{prefix} [{bar:30}] {pos}/{len} {elapsed} {wide_msg}";

/// A progress bar over `total` items.
#[derive(Debug)]
pub struct Progress {
    bar: ProgressBar,
    /// Whether phases started from this one draw.
    enabled: bool,
}

impl Progress {
    /// A bar on stderr (drawn only when stderr is a terminal).
    pub fn new(label: &str, total: usize) -> Self {
        Self::with(true, label, total)
    }

    /// A bar that never draws (tests, library use, `--quiet`).
    pub fn hidden() -> Self {
        Self::with(false, "", 0)
    }

    fn with(enabled: bool, label: &str, total: usize) -> Self {
        let target = if enabled { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
        let style = ProgressStyle::with_template(TEMPLATE)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("== ");
        let bar = ProgressBar::with_draw_target(Some(total as u64), target)
            .with_style(style)
            .with_prefix(label.to_string());
        Self { bar, enabled }
    }

    /// Start a new phase over `total` items (keeps the enabled state).
    pub fn phase(&self, label: &str, total: usize) -> Self {
        Self::with(self.enabled, label, total)
    }

    /// One item done; `item` names it.
    pub fn tick(&self, item: &str) {
        self.bar.set_message(item.to_string());
        self.bar.inc(1);
    }

    /// Clear the line.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }

    /// Items done so far.
    pub fn done(&self) -> usize {
        usize::try_from(self.bar.position()).unwrap_or(usize::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_progress_counts_and_stays_hidden() {
        let p = Progress::with(false, "runs", 4);
        p.tick("a.csv");
        p.tick("b.csv");
        assert_eq!(p.done(), 2);
        assert_eq!(p.bar.length(), Some(4));
        assert_eq!(p.bar.message(), "b.csv");
        assert!(p.bar.is_hidden());
        let q = Progress::hidden().phase("x", 3);
        assert!(q.bar.is_hidden() && q.done() == 0 && q.bar.prefix() == "x");
        // The template parses (a typo would silently fall back to the default bar).
        assert!(ProgressStyle::with_template(TEMPLATE).is_ok());
    }
}
