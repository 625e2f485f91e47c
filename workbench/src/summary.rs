//! The end-of-run summary: how long, how fast, and the range of the main channels.
//! A library type so that every command that runs the model (simulate, a demo without
//! output file, ...) prints the same table.

use std::fmt;
use std::time::Duration;

use model_core::{Channel, Outputs};

/// The channels a bench engineer looks at first: speed, axle torques and speeds,
/// the powers, supply current and DC voltage.
pub const MAIN_CHANNELS: &[Channel] = &[
    Channel::SuTMotorEnc,
    Channel::CKistlerL,
    Channel::CKistlerR,
    Channel::TKistlerL,
    Channel::TKistlerR,
    Channel::PSutInv,
    Channel::PLml,
    Channel::PLmr,
    Channel::PDpu,
    Channel::IDpu27,
    Channel::VDc,
];

/// Range and mean of one channel over a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChannelStats {
    pub channel: Channel,
    pub min: f32,
    pub max: f32,
    /// Mean over the steps, accumulated in f64 so long runs do not lose precision.
    pub mean: f64,
}

/// What a run did; `Display` renders the table `simrod simulate` prints.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// One-line description of the run (profile, scales, options).
    pub title: String,
    /// [µs] simulated time.
    pub duration_us: u64,
    pub steps: u64,
    /// Wall time of the whole run: model plus output.
    pub wall: Duration,
    /// Part of `wall` spent writing output (zero without an output).
    pub output_wall: Duration,
    /// One entry per [`MAIN_CHANNELS`], in that order.
    pub channels: Vec<ChannelStats>,
}

impl Summary {
    /// Simulated seconds.
    pub fn duration_s(&self) -> f64 {
        self.duration_us as f64 * 1e-6
    }

    /// Steps per wall-clock second (model and output together).
    pub fn steps_per_s(&self) -> f64 {
        self.steps as f64 / self.wall.as_secs_f64().max(1e-9)
    }

    /// Simulated time over wall time: > 1 means faster than the bench.
    pub fn real_time_factor(&self) -> f64 {
        self.duration_s() / self.wall.as_secs_f64().max(1e-9)
    }

    /// Stats of `c`, if it is one of the summarised channels.
    pub fn get(&self, c: Channel) -> Option<&ChannelStats> {
        self.channels.iter().find(|s| s.channel == c)
    }
}

/// Collects the channel statistics step by step, without storing the run.
#[derive(Debug, Clone)]
pub struct StatsAccumulator {
    min: Vec<f32>,
    max: Vec<f32>,
    sum: Vec<f64>,
    steps: u64,
    last_t_us: u64,
}

impl Default for StatsAccumulator {
    fn default() -> Self {
        Self::new()
    }
}

impl StatsAccumulator {
    pub fn new() -> Self {
        let n = MAIN_CHANNELS.len();
        Self {
            min: vec![f32::INFINITY; n],
            max: vec![f32::NEG_INFINITY; n],
            sum: vec![0.0; n],
            steps: 0,
            last_t_us: 0,
        }
    }

    /// Take one step's outputs into account.
    pub fn observe(&mut self, o: &Outputs) {
        for (((c, mn), mx), s) in
            MAIN_CHANNELS.iter().zip(&mut self.min).zip(&mut self.max).zip(&mut self.sum)
        {
            let v = o.get(*c);
            // min/max ignore NaN; the sum does not, so a NaN shows up in the mean.
            *mn = mn.min(v);
            *mx = mx.max(v);
            *s += f64::from(v);
        }
        self.steps += 1;
        self.last_t_us = o.t_us;
    }

    /// Steps seen so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The summary; `wall` and `output_wall` as measured by the caller.
    pub fn finish(self, title: String, wall: Duration, output_wall: Duration) -> Summary {
        let n = self.steps;
        let channels = MAIN_CHANNELS
            .iter()
            .enumerate()
            .map(|(i, &channel)| ChannelStats {
                channel,
                min: self.min.get(i).copied().unwrap_or(f32::NAN),
                max: self.max.get(i).copied().unwrap_or(f32::NAN),
                mean: if n == 0 { f64::NAN } else { self.sum.get(i).copied().unwrap_or(f64::NAN) / n as f64 },
            })
            .collect();
        Summary { title, duration_us: self.last_t_us, steps: n, wall, output_wall, channels }
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        writeln!(f, "{}", self.title)?;
        writeln!(
            f,
            "  duration {:.3} s, {} steps, wall {:.1} ms (output {:.1} ms), {:.0} steps/s, real-time factor {:.0}x",
            self.duration_s(),
            self.steps,
            ms(self.wall),
            ms(self.output_wall),
            self.steps_per_s(),
            self.real_time_factor(),
        )?;
        writeln!(f, "  {:<14} {:<5} {:>12} {:>12} {:>12}", "channel", "unit", "min", "max", "mean")?;
        for s in &self.channels {
            if self.steps == 0 {
                writeln!(
                    f,
                    "  {:<14} {:<5} {:>12} {:>12} {:>12}",
                    s.channel.name(),
                    s.channel.unit(),
                    "-",
                    "-",
                    "-"
                )?;
            } else {
                writeln!(
                    f,
                    "  {:<14} {:<5} {:>12} {:>12} {:>12}",
                    s.channel.name(),
                    s.channel.unit(),
                    fixed3(f64::from(s.min)),
                    fixed3(f64::from(s.max)),
                    fixed3(s.mean)
                )?;
            }
        }
        Ok(())
    }
}

/// Three decimals, without the "-0.000" that tiny negative values would print.
fn fixed3(v: f64) -> String {
    let s = format!("{v:.3}");
    if s == "-0.000" {
        "0.000".to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outputs(t_us: u64, v: f32) -> Outputs {
        let mut o = Outputs { t_us, ..Outputs::default() };
        o.values.iter_mut().for_each(|x| *x = v);
        o
    }

    #[test]
    fn min_max_mean_and_rates() {
        let mut acc = StatsAccumulator::new();
        for (i, v) in [1.0f32, -3.0, 5.0, 1.0].into_iter().enumerate() {
            acc.observe(&outputs(1000 * (i as u64 + 1), v));
        }
        let s = acc.finish("t".into(), Duration::from_millis(2), Duration::ZERO);
        assert_eq!(s.steps, 4);
        assert_eq!(s.duration_us, 4000);
        assert_eq!(s.channels.len(), MAIN_CHANNELS.len());
        let v = s.get(Channel::VDc).unwrap();
        assert_eq!((v.min, v.max, v.mean), (-3.0, 5.0, 1.0));
        assert!((s.steps_per_s() - 2000.0).abs() < 1e-6);
        assert!((s.real_time_factor() - 2.0).abs() < 1e-9);
        let text = s.to_string();
        for c in MAIN_CHANNELS {
            assert!(text.contains(c.name()), "{text}");
        }
        assert!(text.contains("-3.000") && text.contains("5.000"), "{text}");
    }

    #[test]
    fn no_negative_zero_in_the_table() {
        assert_eq!(fixed3(-0.0), "0.000");
        assert_eq!(fixed3(-0.0004), "0.000");
        assert_eq!(fixed3(-0.0005001), "-0.001");
        assert_eq!(fixed3(12.3456), "12.346");
    }

    #[test]
    fn empty_run_prints_dashes_not_infinities() {
        let s = StatsAccumulator::new().finish("t".into(), Duration::ZERO, Duration::ZERO);
        let text = s.to_string();
        assert!(!text.contains("inf") && !text.contains("NaN"), "{text}");
    }
}
