//! A closed loop's delay margin as a condition of approval: the loop must stay stable at
//! a safety factor K times the RT platform's loop delay. The margin itself is found by
//! the caller (for the XiL loop, `simrod_xdt::margin::delay_margin`); this is what the
//! check reports and judges.

use serde_json::{json, Value};

/// A loop's delay margin against its loop delay.
#[derive(Debug, Clone, PartialEq)]
pub struct DelayMargin {
    /// [ms] the largest loop delay found stable; `None`: unstable without delay.
    pub margin_ms: Option<f64>,
    /// The margin is a lower bound: the longest delay tried was still stable.
    pub at_least: bool,
    /// [ms] the loop delay of the test.
    pub loop_delay_ms: f64,
    /// K: the margin must be at least K × the loop delay.
    pub factor: f64,
    /// What the smallest unstable delay found did, e.g. `at 32 ms: sustained oscillation`.
    pub beyond: Option<String>,
    /// Runs the search made.
    pub runs: u32,
}

impl DelayMargin {
    /// [ms] K × the loop delay.
    pub fn required_ms(&self) -> f64 {
        self.factor * self.loop_delay_ms
    }

    /// Whether the margin is at least K × the loop delay.
    pub fn passes(&self) -> bool {
        self.margin_ms.is_some_and(|m| m >= self.required_ms())
    }

    /// One line: the margin, the loop delay, the factor and the verdict.
    pub fn text(&self) -> String {
        let need =
            format!("{} x the {} ms loop delay = {} ms", self.factor, self.loop_delay_ms, self.required_ms());
        let margin = match self.margin_ms {
            None => return format!("delay margin: none, the loop is unstable without delay (needed {need})"),
            Some(m) if self.at_least => format!("at least {m} ms"),
            Some(m) => format!("{m} ms"),
        };
        let beyond = self.beyond.as_deref().map_or(String::new(), |b| format!("; {b}"));
        if self.passes() {
            format!("delay margin {margin} >= {need}: inside{beyond}")
        } else {
            format!("DELAY MARGIN {margin} < {need}: refused{beyond}")
        }
    }

    /// `{"margin_ms", "at_least", "loop_delay_ms", "factor", "required_ms", "passes",
    /// "beyond", "runs"}`.
    pub fn to_json(&self) -> Value {
        json!({
            "margin_ms": self.margin_ms,
            "at_least": self.at_least,
            "loop_delay_ms": self.loop_delay_ms,
            "factor": self.factor,
            "required_ms": self.required_ms(),
            "passes": self.passes(),
            "beyond": self.beyond,
            "runs": self.runs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_margin_must_cover_k_times_the_delay() {
        let d = DelayMargin {
            margin_ms: Some(31.0),
            at_least: false,
            loop_delay_ms: 15.0,
            factor: 3.0,
            beyond: None,
            runs: 9,
        };
        assert!(!d.passes());
        assert!(d.text().contains("31 ms < 3 x the 15 ms loop delay = 45 ms"), "{}", d.text());
        let d = DelayMargin { loop_delay_ms: 2.0, ..d };
        assert!(d.passes(), "{}", d.text());
        assert!(!DelayMargin { margin_ms: None, ..d }.passes());
    }
}
