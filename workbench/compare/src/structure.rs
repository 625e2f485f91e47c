//! Is anything left in a residual besides noise, *somewhere*? One weighted energy over
//! all channels and the whole run hides a large error that is local (a 40 ms lag in one
//! torque amplifier shows only at transients) or confined to one channel. This test looks
//! per channel and per time window, with multiple-testing control over all of them; it is
//! the one test `compare` reports and `diagnose` must pass before it says "nothing is
//! missing", so the two cannot disagree.
//!
//! The residual is cut into blocks of [`BLOCK_S`]; noise alone makes the block means
//! independent and zero-mean, with a spread estimated robustly from the differences of
//! neighbouring block means (slow structure cancels in a difference, coloured noise is
//! measured as it is, a few transients do not move a median). A window of
//! [`WINDOW_S`] (stepped by half a window) holds `d` blocks; `Σ (b_j/σ_b)²` is χ²(d)
//! under noise alone. A window is *structured* when its p-value is below
//! `alpha / (number of windows tested over all channels)` (Bonferroni: the chance that
//! noise alone flags any window of any channel is at most `alpha`).
//!
//! A block mean averages a mains line (50 or 60 Hz pickup) away, and the noise estimate
//! takes it for noise, so each channel's whole run is also tested for a line near the
//! mains frequencies ([`MAINS_HZ`]): the periodogram's largest value within
//! [`MAINS_DRIFT_HZ`] of each, against the mean of its neighbours 1.5–3 Hz away (noise
//! alone makes their ratio exponential with mean 1). The twin has no mains content, so a
//! line there is structure it cannot explain; it is one more tested "window" of the run.
//!
//! When the sensor's noise is stated, the run's residual faster than the noise estimate's
//! moving average is tested against it too ([`fast_excess`]): the estimate takes model
//! error that fast for noise, a statement does not.

use simrod_numerics::stats::{mad_sigma, moving_mean};

/// [s] block over which the residual is averaged: longer than the bench's noise
/// correlations (amplifier lags of ms, 50 Hz), shorter than a transient's error.
pub const BLOCK_S: f64 = 0.25;
/// [s] window of blocks tested together.
pub const WINDOW_S: f64 = 2.0;
/// Family-wise false-alarm probability over every window of every channel.
pub const ALPHA: f64 = 0.01;
/// A window counts only when its mean squared residual is at least this many times the
/// noise's (σ²): below that, a long quiet run makes any tiny systematic difference
/// "significant" (the physics plant and the twin differ by 1e-3 of a span) without it
/// mattering. 1.25 is the error the diagnosis proof calls honest (within 1.2x of the
/// true model's) with a margin.
pub const MATERIAL: f64 = 1.25;
/// [s] half-width of the moving average whose remainder is the noise ([`noise_sigma`]):
/// slower than a tachometer's counting window, faster than most model error.
pub const NOISE_HALF_S: f64 = 0.125;
/// [Hz] mains frequencies a line is looked for at.
pub const MAINS_HZ: [f64; 2] = [50.0, 60.0];
/// [Hz] how far from its nominal frequency a mains line is looked for.
pub const MAINS_DRIFT_HZ: f64 = 0.5;
/// [Hz] the neighbours giving a line's noise floor: this far from the nominal frequency
/// and up to twice as far, on both sides.
const FLOOR_FROM_HZ: f64 = 1.5;
/// [s] blocks the heterodyned residual is summed over before its spectrum near a line
/// is evaluated; the sum's response (7 % of the power lost 3 Hz off) is divided out.
const LINE_BLOCK_S: f64 = 0.05;

/// One window of one channel's residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// First sample and number of samples.
    pub start: usize,
    pub len: usize,
    /// `Σ (b_j/σ_b)²` over the window's blocks.
    pub chi2: f64,
    /// Blocks in the window (the χ² degrees of freedom).
    pub dof: usize,
    /// Probability that noise alone gives `chi2` or more.
    pub p: f64,
    /// `ln p`, which orders windows whose `p` underflows to 0.
    pub log_p: f64,
    /// Mean residual over the window [the channel's unit].
    pub mean: f64,
    /// Mean squared residual over the window in units of the noise's σ² (or of the
    /// sensor's resolution², when that is larger).
    pub energy_ratio: f64,
    /// Large enough to matter (see [`MATERIAL`]).
    pub material: bool,
    /// For a mains line over the whole run ([`MAINS_HZ`]): its frequency [Hz]; `mean` is
    /// then its amplitude.
    pub line_hz: Option<f64>,
    /// The whole run's part faster than the noise's moving average against the noise
    /// stated for the sensor ([`fast_excess`]): `mean` is then that part's RMS.
    pub fast: bool,
}

impl Window {
    /// Structured at p-value threshold `th` ([`threshold`]) and material.
    pub fn flagged_at(&self, th: f64) -> bool {
        self.p < th && self.material
    }

    /// What the window holds, for a report: the mean residual, or the line.
    pub fn what(&self, unit: &str) -> String {
        match self.line_hz {
            Some(f) => format!("a {f:.2} Hz line of amplitude {:.4} {unit} (mains pickup?)", self.mean),
            None if self.fast => format!(
                "error faster than {:.2} s of RMS {:.4} {unit}, {:.2}x the noise stated for the sensor",
                2.0 * NOISE_HALF_S,
                self.mean,
                self.energy_ratio.sqrt()
            ),
            None => format!("mean twin − measured {:.4} {unit}", self.mean),
        }
    }
}

/// One channel's windows and the noise level of its block means.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelWindows {
    pub windows: Vec<Window>,
    /// [unit] spread of a block mean under noise alone (0: no estimate, nothing tested).
    pub block_sigma: f64,
    /// [unit] the residual's per-sample noise σ ([`noise_sigma`]).
    pub noise_sigma: f64,
}

impl ChannelWindows {
    /// Add a channel's mains-line tests ([`lines`]) to its windows; a channel with no
    /// noise estimate tests nothing, lines included.
    pub fn add_lines(&mut self, lines: impl IntoIterator<Item = Window>) {
        if self.block_sigma > 0.0 {
            self.windows.extend(lines);
        }
    }

    /// The windows structured at p-value threshold `th` ([`threshold`]) and material.
    pub fn flagged(&self, th: f64) -> impl Iterator<Item = &Window> {
        self.windows.iter().filter(move |w| w.flagged_at(th))
    }
}

/// The windows of residual `r` sampled every `dt` seconds (non-finite samples, such as
/// gaps, are left out of their block; a block less than half finite is left out), and
/// its mains lines ([`lines`]). `resolution` [unit]: the largest error the sensor makes
/// by design (a tachometer: one count per window; 0 for none): a residual within it is
/// never material, however regular. `stated`: the noise σ stated for the sensor on each
/// sample, when it is, adds the run's test of the residual's fast part ([`fast_excess`]).
pub fn windows(r: &[f64], dt: f64, resolution: f64, stated: Option<&[f64]>) -> ChannelWindows {
    let mut w = time_windows(r, dt, resolution);
    // Lazy: not computed when the channel tests nothing.
    w.add_lines(mains_lines(r, dt, w.noise_sigma.max(resolution)));
    w.windows.extend(stated.and_then(|sd| fast_excess(r, dt, sd)));
    w
}

/// The whole-run test of residual `r` (samples `dt` apart) against the noise the sensor
/// is stated to have, `stated` (σ per sample, [unit]): the residual's part faster than
/// the moving average of [`noise_sigma`]. The noise estimated from the residual takes
/// model error that fast (a current's ripple, a lag at every transient) for noise and
/// so hides it; a sensor's stated noise does not move with the model. Under that noise
/// alone `Σ (hp/σ)²`, corrected for the average's own share, is χ² with one degree of
/// freedom per sample; material (as a window) when the energy is [`MATERIAL`] times the
/// stated noise's. `mean` is the fast part's RMS [unit]. `None` when `r` is shorter
/// than two averages or `stated` does not match it.
pub fn fast_excess(r: &[f64], dt: f64, stated: &[f64]) -> Option<Window> {
    let h = ((NOISE_HALF_S / dt).round() as usize).max(5);
    let (n, k) = (r.len(), 2 * h + 1);
    if n < 2 * k || stated.len() != n {
        return None;
    }
    let mean = moving_mean(r, h);
    let (mut chi2, mut energy, mut count) = (0.0, 0.0, 0usize);
    for t in h..n - h {
        let (v, s) = (r[t] - mean[t], stated[t]);
        if v.is_finite() && s.is_finite() && s > 0.0 {
            chi2 += (v / s).powi(2);
            energy += v * v;
            count += 1;
        }
    }
    if count < 10 {
        return None;
    }
    let correction = k as f64 / (k as f64 - 1.0);
    let (chi2, energy_ratio) = (chi2 * correction, chi2 * correction / count as f64);
    let even = count & !1;
    let log_p = chi2_log_sf_even(chi2 * even as f64 / count as f64, even.max(2));
    Some(Window {
        start: 0,
        len: n,
        chi2,
        dof: count,
        p: log_p.exp(),
        log_p,
        mean: (energy * correction / count as f64).sqrt(),
        energy_ratio,
        material: energy_ratio >= MATERIAL,
        line_hz: None,
        fast: true,
    })
}

/// The mains-line tests ([`MAINS_HZ`]) of residual `r` sampled every `dt` seconds, as
/// whole-run windows. Apart from [`time_windows`] because a line needs every sample: a
/// caller that thins a long series (a diagnosis's fit samples) tests the lines on the
/// full series and the windows on the thinned one.
pub fn lines(r: &[f64], dt: f64, resolution: f64) -> Vec<Window> {
    let noise = noise_sigma(r, ((NOISE_HALF_S / dt).round() as usize).max(5), resolution);
    if noise.is_nan() || noise <= 0.0 {
        return Vec::new();
    }
    mains_lines(r, dt, noise.max(resolution)).collect()
}

/// The tests of [`lines`] against the per-sample noise σ `noise` (line included), run
/// as they are taken.
fn mains_lines(r: &[f64], dt: f64, noise: f64) -> impl Iterator<Item = Window> + '_ {
    MAINS_HZ.iter().filter_map(move |f| mains_line(r, dt, *f, noise))
}

/// The time windows of [`windows`] without the mains lines.
pub fn time_windows(r: &[f64], dt: f64, resolution: f64) -> ChannelWindows {
    let per_block = ((BLOCK_S / dt).round() as usize).max(1);
    let blocks: Vec<Option<f64>> =
        r.chunks(per_block).filter(|c| c.len() == per_block).map(block_mean).collect();
    let diffs: Vec<f64> = blocks.windows(2).filter_map(|w| Some(w[1]? - w[0]?)).collect::<Vec<f64>>();
    let block_sigma = mad_sigma(&diffs).unwrap_or(0.0) / std::f64::consts::SQRT_2;
    let dof = ((WINDOW_S / BLOCK_S).round() as usize).max(2);
    let step = (dof / 2).max(1);
    let hp = HighPass::new(r, ((NOISE_HALF_S / dt).round() as usize).max(5), Some(resolution));
    let noise = hp.sigma(0, r.len());
    let mut windows = Vec::new();
    if !(block_sigma > 0.0 && block_sigma.is_finite() && noise > 0.0) {
        return ChannelWindows { windows, block_sigma: 0.0, noise_sigma: noise };
    }
    let mut j = 0;
    while j + dof <= blocks.len() {
        let (from, to) = (j * per_block, (j + dof) * per_block);
        // The bench's noise grows at its operating limits: the window's own noise level
        // scales the null of its block means and is what its error is measured against.
        let local = hp.sigma(from, to);
        let null = block_sigma * local / noise;
        windows.extend(window(&blocks[j..j + dof], &r[from..to], from, null, local.max(resolution)));
        j += step;
    }
    ChannelWindows { windows, block_sigma, noise_sigma: noise }
}

/// The test of the window of samples `r` starting at sample `start`, from its block
/// means, the block means' null spread and the level its error is compared with; `None`
/// when too little of it is finite.
fn window(blocks: &[Option<f64>], r: &[f64], start: usize, block_sigma: f64, floor: f64) -> Option<Window> {
    let vals: Vec<f64> = blocks.iter().flatten().copied().collect();
    if vals.len() * 2 < blocks.len() || block_sigma.is_nan() || block_sigma <= 0.0 {
        return None;
    }
    let chi2: f64 = vals.iter().map(|b| (b / block_sigma).powi(2)).sum();
    let mean = vals.iter().sum::<f64>() / vals.len() as f64;
    let (sum2, count) =
        r.iter().filter(|v| v.is_finite()).fold((0.0, 0usize), |(s, c), v| (s + v * v, c + 1));
    let energy_ratio = sum2 / (count.max(1) as f64 * floor * floor).max(f64::MIN_POSITIVE);
    let even = vals.len() & !1;
    let log_p = chi2_log_sf_even(chi2 * even as f64 / vals.len() as f64, even.max(2));
    Some(Window {
        start,
        len: r.len(),
        chi2,
        dof: vals.len(),
        p: log_p.exp(),
        log_p,
        mean,
        energy_ratio,
        material: energy_ratio >= MATERIAL,
        line_hz: None,
        fast: false,
    })
}

/// The test for a line within [`MAINS_DRIFT_HZ`] of `f0` [Hz] in residual `r` (samples
/// `dt` apart) whose per-sample noise σ (line included) is `noise`: the whole run as one
/// window, its amplitude as the mean. `None` when the sampling cannot hold the line or
/// too little of the run is finite.
fn mains_line(r: &[f64], dt: f64, f0: f64, noise: f64) -> Option<Window> {
    let n = r.len();
    let span = n as f64 * dt;
    if 1.0 / dt < 2.5 * (f0 + 2.0 * FLOOR_FROM_HZ) || span < 4.0 / FLOOR_FROM_HZ {
        return None;
    }
    let (z, per) = heterodyne(r, dt, f0)?;
    let used = z.len() * per;
    let df = 1.0 / span;
    let power = |off: f64| spectrum_at(&z, per, dt, off) / (used as f64 * block_response(off, per, dt));
    // Half-bin steps: a line between two Fourier bins loses at most 10 % of its amplitude.
    let search: Vec<f64> = offsets(-MAINS_DRIFT_HZ, MAINS_DRIFT_HZ, 0.5 * df, 241);
    let (peak_at, peak) = search.iter().map(|o| (*o, power(*o))).max_by(|a, b| a.1.total_cmp(&b.1))?;
    let floor_bins: Vec<f64> = offsets(FLOOR_FROM_HZ, 2.0 * FLOOR_FROM_HZ, df, 30)
        .into_iter()
        .flat_map(|o| [o, -o])
        .map(power)
        .collect();
    let floor = floor_bins.iter().sum::<f64>() / floor_bins.len().max(1) as f64;
    if floor.is_nan() || floor <= 0.0 {
        return None;
    }
    let ratio = peak / floor;
    // The largest of `search.len()` exponentials exceeds `ratio` with at most this chance.
    let log_p = ((search.len() as f64).ln() - ratio).min(0.0);
    // Periodogram of a line of amplitude A: N A²/4 over the floor.
    let amp2 = (4.0 * (peak - floor) / used as f64).max(0.0);
    let rest = (noise * noise - 0.5 * amp2).max(f64::MIN_POSITIVE);
    let energy_ratio = (rest + 0.5 * amp2) / rest;
    Some(Window {
        start: 0,
        len: n,
        chi2: 2.0 * ratio,
        dof: 2,
        p: log_p.exp(),
        log_p,
        mean: amp2.sqrt(),
        energy_ratio,
        material: energy_ratio >= MATERIAL,
        line_hz: Some(f0 + peak_at),
        fast: false,
    })
}

/// `r` shifted down by `f0` [Hz] and summed over whole blocks of [`LINE_BLOCK_S`] (a
/// partial last block is left out): the complex block sums (re, im), block `m` centred
/// at `(m + 1/2) per dt − dt/2`, and `per`; non-finite samples count as 0. `None` when
/// less than half the run is finite.
fn heterodyne(r: &[f64], dt: f64, f0: f64) -> Option<(Vec<(f64, f64)>, usize)> {
    let per = ((LINE_BLOCK_S / dt).round() as usize).max(1);
    let finite = r.iter().filter(|v| v.is_finite()).count();
    if finite * 2 < r.len() {
        return None;
    }
    let mut turn = Rotor::new(0.0, std::f64::consts::TAU * f0 * dt);
    let blocks = r
        .chunks_exact(per)
        .map(|c| {
            c.iter().fold((0.0, 0.0), |(re, im), v| {
                let (cos, sin) = turn.next_pair();
                if v.is_finite() {
                    (re + v * cos, im - v * sin)
                } else {
                    (re, im)
                }
            })
        })
        .collect();
    Some((blocks, per))
}

/// `|Σ z e^{-2πi off t}|²` over the heterodyne's blocks (`per` samples of `dt`): the
/// periodogram times its sample count at `off` [Hz] from the heterodyne's frequency.
fn spectrum_at(z: &[(f64, f64)], per: usize, dt: f64, off: f64) -> f64 {
    let w = std::f64::consts::TAU * off;
    let mut turn = Rotor::new(w * 0.5 * (per as f64 - 1.0) * dt, w * per as f64 * dt);
    let (re, im) = z.iter().fold((0.0, 0.0), |(re, im), (a, b)| {
        let (c, s) = turn.next_pair();
        (re + a * c + b * s, im + b * c - a * s)
    });
    re * re + im * im
}

/// The power response of a sum over `per` samples `dt` apart at `off` [Hz] from the
/// frequency it was shifted by, relative to `off = 0`: `(sin(π off per dt) / (per
/// sin(π off dt)))²`.
fn block_response(off: f64, per: usize, dt: f64) -> f64 {
    let x = std::f64::consts::PI * off * dt;
    if x.abs() < 1e-12 {
        return 1.0;
    }
    ((per as f64 * x).sin() / (per as f64 * x.sin())).powi(2)
}

/// `(cos, sin)` of `start + k step` for k = 0, 1, …: a rotation by one complex product
/// a value instead of a cosine and a sine, re-seeded exactly every [`ROTOR_RESEED`]
/// values so the products' rounding never builds up.
struct Rotor {
    start: f64,
    step: f64,
    k: usize,
    cs: (f64, f64),
    by: (f64, f64),
}

const ROTOR_RESEED: usize = 256;

impl Rotor {
    fn new(start: f64, step: f64) -> Self {
        Self { start, step, k: 0, cs: (1.0, 0.0), by: (step.cos(), step.sin()) }
    }

    fn next_pair(&mut self) -> (f64, f64) {
        if self.k.is_multiple_of(ROTOR_RESEED) {
            let a = self.start + self.step * self.k as f64;
            self.cs = (a.cos(), a.sin());
        }
        let out = self.cs;
        let ((c, s), (bc, bs)) = (self.cs, self.by);
        self.cs = (c * bc - s * bs, s * bc + c * bs);
        self.k += 1;
        out
    }
}

/// Offsets from `lo` to `hi` [Hz] `step` apart (Fourier bins of the run), at most `max`
/// of them (evenly thinned).
fn offsets(lo: f64, hi: f64, step: f64, max: usize) -> Vec<f64> {
    let count = (((hi - lo) / step).floor() as usize + 1).max(1);
    let stride = count.div_ceil(max.max(1)).max(1);
    (0..count).step_by(stride).map(|i| lo + i as f64 * step).collect()
}

/// The part of a residual faster than a `2h+1`-sample moving average: the noise, as
/// [`noise_sigma`] measures it, over the whole run or any stretch of it.
///
/// A burst of model error shorter than the average (a current spike of tens of ms the
/// twin does not have) passes the average as if it were noise and would inflate the
/// noise estimate by an order of magnitude, hiding itself and everything else on the
/// channel. So the high-pass part is cut into blocks of the average's length; a block
/// whose mean square is more than [`BURST_VARIANCE`] times the channel's median block,
/// and the block each side of it (the average smears it that far), counts at the level
/// of its neighbours ([`BURST_NEIGHBOURS`] blocks each side that are
/// not bursts) instead, when the bursts hold most of the channel's high-pass energy
/// ([`BURST_DOMINANCE`]). Noise that grows at the operating limits (the bench's grows up
/// to sixfold, 36x in variance) stays noise; a run without dominant bursts is measured
/// exactly as without the rule.
struct HighPass {
    /// Cumulative sums of the squared high-pass values and their count (finite only).
    cum: Vec<(f64, usize)>,
    /// `k/(k-1)`: x − mean(k) of white noise has variance σ²(1 − 1/k).
    correction: f64,
}

/// A block of the high-pass part with more than this many times the channel's median
/// block mean square is a burst of model error, not noise (10x the noise's σ).
pub const BURST_VARIANCE: f64 = 100.0;
/// The rule applies only when the bursts hold this many times the rest's share of the
/// high-pass energy (the noise estimate would be more than √2 too high).
pub const BURST_DOMINANCE: f64 = 2.0;
/// Blocks each side whose median mean square stands for a burst's noise.
const BURST_NEIGHBOURS: usize = 4;

impl HighPass {
    /// `bursts`: leave bursts out, with `Some(floor)` [unit] the sensor's resolution (0
    /// for none; a channel whose median block is quieter than that, a counter at rest,
    /// has no burst below it); `None` counts every sample.
    fn new(r: &[f64], h: usize, bursts: Option<f64>) -> Self {
        let n = r.len();
        let k = 2 * h + 1;
        let mut cum = Vec::with_capacity(n + 1);
        cum.push((0.0, 0));
        if n >= 2 * k {
            let mean = moving_mean(r, h);
            let hp: Vec<f64> =
                (0..n).map(|t| if (h..n - h).contains(&t) { r[t] - mean[t] } else { f64::NAN }).collect();
            let level = bursts.and_then(|floor| burst_levels(&hp, k, floor)).unwrap_or_default();
            for (t, v) in hp.iter().enumerate() {
                let (s, c) = cum[t];
                let sq = level.get(t / k).copied().flatten().unwrap_or(v * v);
                cum.push(if v.is_finite() { (s + sq, c + 1) } else { (s, c) });
            }
        }
        Self { cum, correction: k as f64 / (k as f64 - 1.0) }
    }

    /// σ of the high-pass part over samples `from..to` (0 without enough of them).
    fn sigma(&self, from: usize, to: usize) -> f64 {
        let (Some(a), Some(b)) = (self.cum.get(from), self.cum.get(to)) else { return 0.0 };
        let count = b.1 - a.1;
        if count < 10 {
            return 0.0;
        }
        ((b.0 - a.0) / count as f64 * self.correction).sqrt()
    }
}

/// Per block of `k` high-pass values `hp`: `Some(level)` for a burst (its mean square
/// above [`BURST_VARIANCE`] times the median block's, which is at least `floor²`), the
/// median mean square of its non-burst neighbours standing for its noise; `None` for
/// the others. `None` overall when the bursts do not dominate ([`BURST_DOMINANCE`]).
fn burst_levels(hp: &[f64], k: usize, floor: f64) -> Option<Vec<Option<f64>>> {
    let ms: Vec<Option<f64>> = hp
        .chunks(k)
        .map(|c| {
            let (s, n) =
                c.iter().filter(|v| v.is_finite()).fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
            (n >= 10).then(|| s / n as f64)
        })
        .collect();
    let known: Vec<f64> = ms.iter().flatten().copied().collect();
    let median = simrod_numerics::stats::median(&known)?;
    let limit = BURST_VARIANCE * median.max(floor * floor);
    if limit.is_nan() || limit <= 0.0 {
        return None;
    }
    let loud: Vec<bool> = ms.iter().map(|m| m.is_some_and(|m| m > limit)).collect();
    // The moving average smears a burst over `h` samples each side: into the next
    // block at most, which is then part of it.
    let burst: Vec<bool> =
        (0..ms.len()).map(|b| loud[b.saturating_sub(1)..(b + 2).min(ms.len())].contains(&true)).collect();
    let levels: Vec<Option<f64>> = (0..ms.len())
        .map(|b| {
            if !burst[b] {
                return None;
            }
            let (lo, hi) = (b.saturating_sub(BURST_NEIGHBOURS), (b + BURST_NEIGHBOURS + 1).min(ms.len()));
            let quiet: Vec<f64> = (lo..hi).filter(|&j| !burst[j]).filter_map(|j| ms[j]).collect();
            Some(simrod_numerics::stats::median(&quiet).unwrap_or(median))
        })
        .collect();
    // Only where the bursts dominate the estimate: the twin and the plant differ at
    // fast transients by more than the noise in every run (the true model's error
    // too), and counting that as noise is what the windows' materiality is set against.
    let (plain, kept) = ms.iter().zip(&levels).fold((0.0, 0.0), |(all, rest), (m, l)| {
        let m = m.unwrap_or(0.0);
        (all + m, rest + l.unwrap_or(m))
    });
    (plain > BURST_DOMINANCE * kept).then_some(levels)
}

fn block_mean(c: &[f64]) -> Option<f64> {
    let finite: Vec<f64> = c.iter().copied().filter(|v| v.is_finite()).collect();
    (finite.len() * 2 >= c.len()).then(|| finite.iter().sum::<f64>() / finite.len() as f64)
}

/// Noise σ of a residual: the part faster than a `2h+1`-sample moving average, corrected
/// for the average's own share so that white noise gives an unbiased estimate. Not
/// trimmed: bench noise grows at the operating limits, and trimming would cut exactly
/// that part; only a burst of model error ten times the noise is left out ([`HighPass`]).
/// `resolution`: the sensor's (0 for none). 0 when the series is shorter than two windows.
pub fn noise_sigma(r: &[f64], h: usize, resolution: f64) -> f64 {
    HighPass::new(r, h, Some(resolution)).sigma(0, r.len())
}

/// The noise σ a diagnosis weighs a channel by: [`noise_sigma`] with bursts counted.
/// Left as it was when the burst rule came: with bursts left out the fits weigh a
/// current with fast transient error tens of times more, and tilt towards it (a speed
/// map 3 % off beside a friction and a delay was then taken for a wrong inverter map);
/// the structure test, which decides whether anything is left, leaves them out.
pub fn weighting_sigma(r: &[f64], h: usize) -> f64 {
    HighPass::new(r, h, None).sigma(0, r.len())
}

/// A p-value as the reports print it (`< 1e-300` where it underflows).
pub fn p_text(p: f64) -> String {
    if p < 1e-300 {
        "< 1e-300".to_string()
    } else {
        format!("{p:.0e}")
    }
}

/// The p-value below which a window is structured, for `tested` windows in the family.
pub fn threshold(tested: usize) -> f64 {
    ALPHA / tested.max(1) as f64
}

/// Where [`chi2_log_sf_even`]'s series is scaled down.
const RESCALE: f64 = 1e280;

/// Survival function of χ² with an even number `dof` of degrees of freedom (exact:
/// `e^{-x/2} Σ_{i<dof/2} (x/2)^i / i!`).
pub fn chi2_sf_even(x: f64, dof: usize) -> f64 {
    chi2_log_sf_even(x, dof).exp()
}

/// The natural log of [`chi2_sf_even`], finite where the p-value itself underflows (two
/// windows far beyond 1e-300 are still ordered by how far).
pub fn chi2_log_sf_even(x: f64, dof: usize) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    let h = x / 2.0;
    let mut term = 1.0;
    let mut sum = 1.0;
    // ln of a factor taken out of `term` and `sum` when a whole run's thousands of
    // degrees of freedom ([`fast_excess`]) would overflow them; 0 for a window's few.
    let mut scale = 0.0;
    for i in 1..dof / 2 {
        term *= h / i as f64;
        sum += term;
        if sum > RESCALE {
            term /= RESCALE;
            sum /= RESCALE;
            scale += RESCALE.ln();
        }
    }
    // In logs: e^{-h} underflows long before the sum overflows.
    (sum.ln() + scale - h).min(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use simrod_numerics::stats::Rng;
    use std::f64::consts::PI;

    fn noise(seed: u64, n: usize, sigma: f64) -> Vec<f64> {
        let mut rng = Rng::new(seed, 0);
        (0..n).map(|_| sigma * rng.gauss()).collect()
    }

    #[test]
    fn chi2_tail_matches_known_values() {
        // χ²(2): e^{-x/2}; χ²(8) at 20.09: 0.01 (tables).
        assert!((chi2_sf_even(2.0, 2) - (-1.0f64).exp()).abs() < 1e-12);
        assert!((chi2_sf_even(20.09, 8) - 0.01).abs() < 2e-4);
        assert_eq!(chi2_sf_even(0.0, 8), 1.0);
        assert!(chi2_sf_even(4000.0, 8) >= 0.0);
        // A whole run's degrees of freedom: at the mean about one half, 5 % above it at
        // 20,000 degrees ln p = -14.7 (Wilson–Hilferty: z = 4.92); no overflow.
        assert!((chi2_sf_even(20_000.0, 20_000) - 0.4987).abs() < 2e-3);
        assert!((chi2_log_sf_even(21_000.0, 20_000) + 14.66).abs() < 0.3);
        assert!(chi2_log_sf_even(60_000.0 * 1.3, 60_000) < -1000.0);
    }

    /// Noise as stated (σ three times larger over a third of the run, as at the bench's
    /// limits) is not fast structure; model error of 0.1 amplitude at 8 Hz (two periods
    /// in the moving average, which then passes it whole), which the estimated noise
    /// takes in (the time windows flag nothing), is, with its size.
    #[test]
    fn fast_error_shows_against_the_stated_noise_only() {
        let dt = 1e-3;
        let sd: Vec<f64> =
            (0..60_000).map(|k| if (20_000..40_000).contains(&k) { 0.3 } else { 0.1 }).collect();
        for seed in 40..45u64 {
            let r: Vec<f64> = noise(seed, 60_000, 1.0).iter().zip(&sd).map(|(v, s)| v * s).collect();
            let w = fast_excess(&r, dt, &sd).unwrap();
            assert!(
                (w.energy_ratio - 1.0).abs() < 0.03 && !w.flagged_at(threshold(100)),
                "seed {seed}: {w:?}"
            );
            let f = 2.0 / (251.0 * dt);
            let err: Vec<f64> =
                r.iter().enumerate().map(|(k, v)| v + 0.1 * (2.0 * PI * f * k as f64 * dt).sin()).collect();
            let w = fast_excess(&err, dt, &sd).unwrap();
            assert!(w.flagged_at(threshold(100)) && w.fast, "seed {seed}: {w:?}");
            // The error's mean square 0.005 over σ²: 1/σ² is 100 on two thirds, 11.1 on one.
            assert!((w.energy_ratio - (1.0 + 0.005 * 70.37)).abs() < 0.05, "seed {seed}: {w:?}");
            let tw = windows(&err, dt, 0.0, None);
            assert_eq!(tw.flagged(threshold(tw.windows.len())).count(), 0, "seed {seed}");
            let stated = windows(&err, dt, 0.0, Some(&sd));
            let flagged: Vec<&Window> = stated.flagged(threshold(stated.windows.len())).collect();
            assert_eq!(flagged, [&w], "seed {seed}: the one window the statement adds");
        }
    }

    /// Slow model error is the windows' to find: the fast test removes it with the
    /// moving average. A statement that does not fit the run is no test.
    #[test]
    fn slow_error_is_not_fast_structure() {
        let dt = 1e-3;
        let sd = vec![0.1; 60_000];
        let r: Vec<f64> = noise(50, 60_000, 0.1)
            .iter()
            .enumerate()
            .map(|(k, v)| v + 2.0 * (2.0 * PI * 0.1 * k as f64 * dt).sin())
            .collect();
        let w = fast_excess(&r, dt, &sd).unwrap();
        assert!(!w.material, "{w:?}");
        assert!(fast_excess(&r, dt, &sd[1..]).is_none());
        assert!(fast_excess(&r[..100], dt, &sd[..100]).is_none());
    }

    /// Noise alone, white or coloured (a first-order lag of 20 samples), flags no
    /// window over many channels' worth of runs: the family-wise rate stays near ALPHA.
    #[test]
    fn noise_alone_is_not_structure() {
        let mut flagged = 0;
        for seed in 0..40u64 {
            let mut r = noise(seed, 60_000, 0.5);
            if seed % 2 == 1 {
                let a = (-1.0f64 / 20.0).exp();
                for k in 1..r.len() {
                    r[k] = a * r[k - 1] + (1.0 - a) * r[k];
                }
            }
            let w = windows(&r, 1e-3, 0.0, None);
            let th = threshold(w.windows.len());
            flagged += usize::from(w.flagged(th).count() > 0);
        }
        assert!(flagged <= 2, "{flagged} of 40 noise-only runs flagged");
    }

    /// Far beyond underflow the log survival keeps its order and its value.
    #[test]
    fn the_log_p_value_orders_windows_beyond_underflow() {
        let (a, b) = (chi2_log_sf_even(2000.0, 8), chi2_log_sf_even(4000.0, 8));
        assert_eq!((a.exp(), b.exp()), (0.0, 0.0));
        assert!(b < a && a < -900.0 && b.is_finite(), "{a} {b}");
        assert!((chi2_log_sf_even(20.09, 8) - 0.01f64.ln()).abs() < 0.02);
    }

    fn with_line(mut r: Vec<f64>, dt: f64, f: f64, amp: f64) -> Vec<f64> {
        for (k, v) in r.iter_mut().enumerate() {
            *v += amp * (std::f64::consts::TAU * f * k as f64 * dt + 0.3).sin();
        }
        r
    }

    /// A mains line that only makes the residual 1.25x its noise in RMS (the proof's
    /// missed I_XLML case: a block mean averages it away, the noise estimate takes it
    /// in) is found, with its frequency and amplitude, at 1 ms and at 2 ms sampling, at
    /// 50 and 60 Hz, off the nominal frequency too.
    #[test]
    fn a_mains_line_is_found_with_its_frequency_and_amplitude() {
        for (seed, dt, f, amp) in [(1, 1e-3, 50.03, 0.94), (2, 2e-3, 59.9, 0.94), (3, 1e-3, 50.0, 0.4)] {
            let sigma = if amp > 0.5 { 0.9 } else { 0.5 };
            let r = with_line(noise(seed, (60.0 / dt) as usize, sigma), dt, f, amp);
            let w = windows(&r, dt, 0.0, None);
            let th = threshold(w.windows.len());
            let lines: Vec<&Window> = w.flagged(th).filter(|x| x.line_hz.is_some()).collect();
            assert_eq!(lines.len(), 1, "{f} Hz, amplitude {amp}: {lines:?}");
            let l = lines[0];
            assert!((l.line_hz.unwrap() - f).abs() < 0.02, "frequency {:?} for {f}", l.line_hz);
            assert!((l.mean - amp).abs() < 0.1 * amp, "amplitude {} for {amp}", l.mean);
            assert!(w.flagged(th).all(|x| x.line_hz.is_some()), "only the line is structure");
        }
    }

    /// Noise alone, white or coloured (a 20 ms first-order lag), gives no mains line in
    /// 200 runs; a line away from the mains (40 Hz, the flange mode's alias at 1 kHz) is
    /// not looked for; a line too small to matter is not flagged.
    #[test]
    fn no_line_from_noise_elsewhere_or_too_small() {
        let mut false_lines = 0;
        for seed in 0..200u64 {
            let mut r = noise(100 + seed, 20_000, 0.5);
            if seed % 2 == 1 {
                let a = (-1.0f64 / 20.0).exp();
                for k in 1..r.len() {
                    r[k] = a * r[k - 1] + (1.0 - a) * r[k];
                }
            }
            let w = windows(&r, 1e-3, 0.0, None);
            false_lines += w.flagged(threshold(w.windows.len())).filter(|x| x.line_hz.is_some()).count();
        }
        assert!(false_lines <= 2, "{false_lines} lines in 200 noise-only runs");
        let away = windows(&with_line(noise(7, 60_000, 0.9), 1e-3, 40.0, 0.94), 1e-3, 0.0, None);
        assert_eq!(away.flagged(threshold(away.windows.len())).count(), 0);
        // 0.2 of σ 0.9: RMS 1.012x the noise, far below the material 1.25x.
        let small = windows(&with_line(noise(8, 60_000, 0.9), 1e-3, 50.0, 0.2), 1e-3, 0.0, None);
        let th = threshold(small.windows.len());
        assert!(small.windows.iter().any(|x| x.line_hz.is_some() && x.p < th), "the small line is seen");
        assert_eq!(small.flagged(th).count(), 0, "but not material");
    }

    /// A short local error (a lag's error at three transients: 4 σ decaying in 0.1 s) in noise is
    /// found, where it is.
    #[test]
    fn a_local_error_is_found_where_it_is() {
        let mut r = noise(7, 60_000, 1.0);
        for at in [10_000usize, 30_000, 50_000] {
            for (k, v) in r[at..at + 300].iter_mut().enumerate() {
                *v += 4.0 * (-(k as f64) / 100.0).exp();
            }
        }
        let w = windows(&r, 1e-3, 0.0, None);
        let th = threshold(w.windows.len());
        let hits: Vec<&Window> = w.flagged(th).collect();
        assert!(!hits.is_empty());
        for h in &hits {
            let near =
                [10_000usize, 30_000, 50_000].iter().any(|&a| h.start <= a + 300 && a < h.start + h.len);
            assert!(near, "window at {} is not at a transient", h.start);
        }
    }

    /// On white noise of known σ the estimate is unbiased: with 200 000 samples its own
    /// relative scatter is about `1/sqrt(2n)` = 0.16 %, so 1 % is six of those; without
    /// the `k/(k-1)` correction a 11-sample window would read 4.7 % low and fail.
    #[test]
    fn noise_sigma_is_unbiased_on_white_noise() {
        for (seed, sigma, h) in [(1, 1.0, 5), (2, 0.003, 5), (3, 250.0, 20)] {
            let r: Vec<f64> = noise(seed, 200_000, sigma);
            let est = noise_sigma(&r, h, 0.0);
            assert!((est / sigma - 1.0).abs() < 0.01, "σ {sigma}, h {h}: estimated {est}");
        }
    }

    /// A slow model error under the noise does not count as noise (that is the point of
    /// the moving average): a sine of 20x the noise amplitude with a period of 2 000
    /// samples adds less than 1 % to the estimate.
    #[test]
    fn noise_sigma_ignores_slow_model_error() {
        let r: Vec<f64> = noise(4, 100_000, 1.0)
            .iter()
            .enumerate()
            .map(|(t, v)| v + 20.0 * (2.0 * std::f64::consts::PI * t as f64 / 2000.0).sin())
            .collect();
        let est = noise_sigma(&r, 5, 0.0);
        assert!((est - 1.0).abs() < 0.01, "estimated {est}");
    }

    #[test]
    fn noise_sigma_of_a_short_series_is_zero() {
        assert_eq!(noise_sigma(&[1.0; 21], 5, 0.0), 0.0);
        assert_eq!(noise_sigma(&[], 5, 0.0), 0.0);
    }

    /// Noise that grows at the operating limits (three times as large over a third of
    /// the run, as the bench's does) is still noise.
    #[test]
    fn noise_that_grows_at_the_limits_is_not_structure() {
        for seed in 20..30u64 {
            let r: Vec<f64> = noise(seed, 60_000, 1.0)
                .iter()
                .enumerate()
                .map(|(k, v)| if (20_000..40_000).contains(&k) { 3.0 * v } else { *v })
                .collect();
            let w = windows(&r, 1e-3, 0.0, None);
            assert_eq!(w.flagged(threshold(w.windows.len())).count(), 0, "seed {seed}");
        }
    }

    /// A burst of model error shorter than the noise's moving average (27 ms of a current
    /// 400 σ off, as a supply's current limit the twin lacks gives) is not noise: the
    /// estimate stays within 2 % of the noise (it would read 8.5x without the rule) and
    /// a window over the burst is flagged.
    #[test]
    fn a_burst_of_model_error_is_not_noise() {
        let mut r = noise(31, 60_000, 1.0);
        for v in &mut r[41_042..41_069] {
            *v += 400.0;
        }
        let est = noise_sigma(&r, 125, 0.0);
        assert!((est - 1.0).abs() < 0.02, "estimated {est}");
        let w = windows(&r, 1e-3, 0.0, None);
        let th = threshold(w.windows.len());
        assert!(w.flagged(th).any(|x| x.start <= 41_042 && 41_069 <= x.start + x.len), "burst not flagged");
    }

    /// The bench's largest noise growth at its limits (I_DC: 0.1 A + 0.5 A, sixfold)
    /// in half-second stretches is still noise, not a burst.
    #[test]
    fn sixfold_noise_in_short_stretches_is_not_a_burst() {
        for seed in 40..46u64 {
            let r: Vec<f64> = noise(seed, 60_000, 1.0)
                .iter()
                .enumerate()
                .map(|(k, v)| if (k / 500) % 10 == 3 { 6.0 * v } else { *v })
                .collect();
            let w = windows(&r, 1e-3, 0.0, None);
            assert_eq!(w.flagged(threshold(w.windows.len())).count(), 0, "seed {seed}");
            let mean_var = r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64;
            let est = noise_sigma(&r, 125, 0.0);
            assert!((est / mean_var.sqrt() - 1.0).abs() < 0.03, "seed {seed}: {est} vs {}", mean_var.sqrt());
        }
    }

    /// A tiny systematic difference in a long quiet run is significant but not material.
    #[test]
    fn a_tiny_offset_is_not_material() {
        let r: Vec<f64> = noise(9, 60_000, 1.0).iter().map(|v| v + 0.2).collect();
        let w = windows(&r, 1e-3, 0.0, None);
        let th = threshold(w.windows.len());
        assert!(w.windows.iter().any(|x| x.p < th), "the offset is significant");
        assert_eq!(w.flagged(th).count(), 0, "but not material");
    }

    /// A counting sensor's regular error (a square wave of ±0.8 units over 3 s, no
    /// noise) is within its resolution (0.87): never material; it would be without it.
    #[test]
    fn a_residual_within_the_resolution_is_not_material() {
        let wiggle = noise(11, 60_000, 0.01);
        let r: Vec<f64> =
            (0..60_000).map(|k| if (k / 1500) % 2 == 0 { 0.8 } else { -0.8 } + wiggle[k]).collect();
        let w = windows(&r, 1e-3, 3.0 / 12f64.sqrt(), None);
        let th = threshold(w.windows.len());
        assert_eq!(w.flagged(th).count(), 0);
        assert!(windows(&r, 1e-3, 0.0, None).flagged(th).count() > 0, "material without the resolution");
    }
}
