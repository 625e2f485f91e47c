//! A one-line progress bar on stderr for long campaigns (loading dozens of 70 s runs
//! takes a while). Drawn only when stderr is a terminal, so logs and pipes stay clean.

use std::cell::Cell;
use std::io::{IsTerminal, Write};
use std::time::Instant;

/// Width of the bar in characters.
const BAR: usize = 30;

/// A progress bar over `total` items.
#[derive(Debug)]
pub struct Progress {
    enabled: bool,
    label: String,
    total: usize,
    done: Cell<usize>,
    start: Instant,
}

impl Progress {
    /// A bar shown when stderr is a terminal.
    pub fn new(label: &str, total: usize) -> Self {
        Self::with(std::io::stderr().is_terminal(), label, total)
    }

    /// A bar that never draws (tests, library use).
    pub fn hidden() -> Self {
        Self::with(false, "", 0)
    }

    fn with(enabled: bool, label: &str, total: usize) -> Self {
        Self { enabled, label: label.into(), total, done: Cell::new(0), start: Instant::now() }
    }

    /// Start a new phase over `total` items (keeps the enabled state).
    pub fn phase(&self, label: &str, total: usize) -> Self {
        Self::with(self.enabled, label, total)
    }

    /// One item done; `item` names it.
    pub fn tick(&self, item: &str) {
        let done = self.done.get() + 1;
        self.done.set(done);
        if self.enabled {
            eprint!("\r{}", self.line(done, item));
            let _ = std::io::stderr().flush();
        }
    }

    /// Clear the line.
    pub fn finish(&self) {
        if self.enabled {
            eprint!("\r{:width$}\r", "", width = BAR + 60);
            let _ = std::io::stderr().flush();
        }
    }

    /// Items done so far.
    pub fn done(&self) -> usize {
        self.done.get()
    }

    fn line(&self, done: usize, item: &str) -> String {
        let total = self.total.max(1);
        let fill = (done.min(total) * BAR) / total;
        let item: String = item.chars().take(28).collect();
        format!(
            "{} [{}{}] {done}/{} {:.0} s {item:<28}",
            self.label,
            "=".repeat(fill),
            " ".repeat(BAR - fill),
            self.total,
            self.start.elapsed().as_secs_f64()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_progress_counts_and_draws_a_bar() {
        let p = Progress::with(false, "runs", 4);
        p.tick("a.csv");
        p.tick("b.csv");
        assert_eq!(p.done(), 2);
        let l = p.line(2, "b.csv");
        assert!(l.starts_with("runs [==============="), "{l}");
        assert!(l.contains("2/4"));
        assert_eq!(Progress::hidden().phase("x", 3).line(3, "").matches('=').count(), BAR);
    }
}
