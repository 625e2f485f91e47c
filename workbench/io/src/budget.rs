//! How much a command may hold in memory or write to disk. A command estimates what a
//! run will cost *before* it allocates or writes (a file sampled at 1 s becomes 1000
//! times as many samples on the twin's 1 ms grid; a 1e6 s profile at 10 µs is 1e11
//! rows) and refuses with the estimate and the flag that lifts the limit, instead of
//! running out of memory or filling the disk half-way.

use clap::Args;

/// Default budget [GB]: a few GB, below what a laptop or the CI machine has free.
pub const DEFAULT_GB: f64 = 4.0;

/// The flag every command that holds or writes a run takes.
#[derive(Debug, Clone, Copy, PartialEq, Args)]
pub struct BudgetArgs {
    /// Most memory the command may hold, and most it may write, [GB]; a run estimated
    /// beyond it is refused up front with the estimate
    #[arg(long = "budget-gb", value_name = "GB", default_value_t = DEFAULT_GB, value_parser = parse_gb)]
    pub budget_gb: f64,
}

impl Default for BudgetArgs {
    /// The flag's default, for callers in code.
    fn default() -> Self {
        Self { budget_gb: DEFAULT_GB }
    }
}

impl BudgetArgs {
    /// The budget the flag sets.
    pub fn budget(&self) -> Budget {
        Budget { bytes: self.budget_gb * 1e9 }
    }
}

fn parse_gb(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a size in GB (a number > 0, e.g. 8 or 0.5)")),
    }
}

/// A limit in bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    pub bytes: f64,
}

impl Default for Budget {
    fn default() -> Self {
        Self { bytes: DEFAULT_GB * 1e9 }
    }
}

impl Budget {
    /// `Err` naming what would be done (`doing`, e.g. "comparing run.csv"), the estimate,
    /// what it is made of (`why`) and the flag value that would allow it, when
    /// `estimate` [bytes] is over the budget. A non-finite estimate is over any budget.
    pub fn check(&self, doing: &str, estimate: f64, why: &str) -> Result<(), String> {
        if estimate.is_finite() && estimate <= self.bytes {
            return Ok(());
        }
        let need = if estimate.is_finite() {
            format!("--budget-gb {} allows it", gb_text((estimate / 1e9 * 1.1).max(0.1)))
        } else {
            "no budget allows it".to_string()
        };
        Err(format!(
            "{doing} would take about {} ({why}): more than the budget of {}; {need}",
            bytes_text(estimate),
            bytes_text(self.bytes)
        ))
    }
}

/// `1.2 GB`, `350 MB`, `2.0e+03 GB` for sizes in messages.
pub fn bytes_text(b: f64) -> String {
    if !b.is_finite() {
        "an unbounded size".to_string()
    } else if b >= 1e12 {
        format!("{:.1e} GB", b / 1e9)
    } else if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else {
        format!("{:.0} MB", (b / 1e6).max(1.0))
    }
}

fn gb_text(gb: f64) -> String {
    if gb >= 10.0 {
        format!("{}", gb.ceil())
    } else {
        format!("{:.1}", (gb * 10.0).ceil() / 10.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn over_budget_names_estimate_and_flag() {
        let b = Budget { bytes: 4e9 };
        assert!(b.check("x", 3.9e9, "").is_ok());
        let e = b.check("comparing a.csv", 38e9, "60000000 samples").unwrap_err();
        assert!(e.contains("comparing a.csv would take about 38.0 GB (60000000 samples)"), "{e}");
        assert!(e.contains("budget of 4.0 GB; --budget-gb 42 allows it"), "{e}");
        let e = b.check("writing", 1.6e15, "1e11 rows").unwrap_err();
        assert!(e.contains("1.6e6 GB"), "{e}");
        assert!(b.check("x", f64::INFINITY, "").unwrap_err().contains("no budget allows it"));
        assert!(b.check("x", f64::NAN, "").is_err());
    }

    #[test]
    fn flag_values() {
        assert_eq!(parse_gb("8"), Ok(8.0));
        assert!(parse_gb("0").is_err());
        assert!(parse_gb("-1").is_err());
        assert!(parse_gb("inf").is_err());
        assert!(parse_gb("lots").unwrap_err().contains("not a size in GB"));
    }
}
