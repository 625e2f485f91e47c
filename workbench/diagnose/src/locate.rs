//! Where an unexplained residual is, beyond its channel and worst window: the operating
//! region its excess concentrates in, and the measured signal (or its rate of change)
//! it follows — the inputs of the block a missing mechanism or a wrong map sits in. A
//! residual that follows the SuT speed's rate of change points at the speed loop's
//! dynamics; one that follows a load torque, at that side's maps.

use model_core::Channel;

use super::preparation::Prepared;

/// Least |correlation| for a signal to be named as what the residual follows.
const FOLLOWS_MIN: f64 = 0.3;

/// The operating region holding the largest share of channel `c`'s excess error (over
/// the noise) in `sim`: (name, share of the excess, share of the samples).
pub(super) fn region(p: &Prepared, c: usize, sim: &[Vec<f32>]) -> Option<(String, f64, f64)> {
    let excess: Vec<f64> = p
        .idx
        .iter()
        .map(|&t| p.weights.at(c, t) * (p.meas[c][t] - f64::from(sim[c][t])).powi(2) - 1.0)
        .collect();
    let total: f64 = excess.iter().sum();
    if total <= 0.0 || p.regions.is_empty() {
        return None;
    }
    let n = excess.len().max(1) as f64;
    p.regions
        .iter()
        .map(|(name, mask)| {
            let (mut e, mut k) = (0.0, 0usize);
            for (x, _) in excess.iter().zip(mask).filter(|(_, m)| **m) {
                e += x;
                k += 1;
            }
            (name.clone(), e / total, k as f64 / n)
        })
        .filter(|(_, share, _)| *share > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// The measured signal, or its rate of change (`d/dt`), that channel `c`'s residual in
/// `sim` correlates with most, with the correlation; `None` below [`FOLLOWS_MIN`].
pub(super) fn follows(
    p: &Prepared,
    channels: &[Channel],
    c: usize,
    sim: &[Vec<f32>],
) -> Option<(String, f64)> {
    let r: Vec<f64> = p.idx.iter().map(|&t| p.meas[c][t] - f64::from(sim[c][t])).collect();
    let mut best: Option<(String, f64)> = None;
    for (k, ch) in channels.iter().enumerate() {
        let x: Vec<f64> = p.idx.iter().map(|&t| p.meas[k][t]).collect();
        let dx: Vec<f64> = std::iter::once(0.0).chain(x.windows(2).map(|w| w[1] - w[0])).collect();
        for (name, sig) in [(ch.name().to_owned(), &x), (format!("d/dt {}", ch.name()), &dx)] {
            let rho = correlation(&r, sig);
            if rho.abs() >= FOLLOWS_MIN && best.as_ref().is_none_or(|(_, b)| rho.abs() > b.abs()) {
                best = Some((name, rho));
            }
        }
    }
    best
}

/// Pearson correlation of `a` and `b` (0 when either is constant).
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()).max(1) as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (dx, dy) = (x - ma, y - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::correlation;

    #[test]
    fn correlation_of_a_line_and_its_mirror() {
        let a: Vec<f64> = (0..50).map(f64::from).collect();
        let b: Vec<f64> = a.iter().map(|x| 3.0 - 2.0 * x).collect();
        assert!((correlation(&a, &a) - 1.0).abs() < 1e-12);
        assert!((correlation(&a, &b) + 1.0).abs() < 1e-12);
        assert_eq!(correlation(&a, &[1.0; 50]), 0.0);
    }
}
