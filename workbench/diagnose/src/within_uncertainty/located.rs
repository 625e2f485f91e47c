//! Whether a member of the set clears located structure: the residual's test per
//! channel and time span ([`crate::verdict::windows_in`], the one `compare` and the
//! verdict read) on the set's refit, with the member and without it.
//!
//! The estimate's maps, moving within their uncertainty at a prior cost the thinning
//! makes small, can take most of a one-channel fault's energy over a whole run: a 40 ms
//! lag on C_Kistler_L the verdict read at 0.0403 ± 0.0058 s (truth 0.0407) was "no longer
//! needed" by the set's refit (its return to 0 cost under the material bar), yet the model
//! without it left C_Kistler_L with structure at the transients (proof 31's 1,008,954, read
//! for this rule: later proofs start above it). Energy over the whole run is not the
//! test the verdict holds a model to; located structure is (issue item 4).

use std::sync::Arc;

use super::{Point, Problem};
use crate::engine::MOVES_SHARE;
use crate::preparation::flagged_windows;
use crate::verdict::windows_in;

impl Problem<'_> {
    /// Whether the set's refit at `with` clears structure the refit without `cause`
    /// (`without`, a problem whose free parameters lack it, fitted here) leaves on a
    /// channel the cause moves: then the member is needed whatever its energy.
    pub(super) fn clears_located(
        &self,
        with: &Point,
        cause: &str,
        without: &Problem,
    ) -> Result<bool, String> {
        let mine = self.moved_by(with, cause);
        let fit = without.fit(vec![0.0; without.unknowns.len()])?;
        let on_mine = |pb: &Problem, x: &[f64]| -> Result<bool, String> {
            let sim = pb.twin.run_data(&Arc::new(pb.data(x)), &pb.effects(x), pb.p.stride)?;
            let dt = pb.twin.dt_s() * pb.p.stride as f64;
            let windows = windows_in(pb.p, &pb.twin.resolution(), dt, &sim);
            Ok(flagged_windows(&windows).iter().any(|(c, _)| mine.contains(c)))
        };
        Ok(on_mine(without, &fit.best.x)? && !on_mine(self, &with.x)?)
    }

    /// The channels carrying at least [`MOVES_SHARE`] of `cause`'s weighted response at
    /// `at` (its free parameters' Jacobian columns), the verdict's rule for what a cause
    /// moves.
    fn moved_by(&self, at: &Point, cause: &str) -> Vec<usize> {
        let first = self.unknowns.len() - self.free.len();
        let own = (0..self.free.len()).filter(|&k| self.free[k].0.cause == cause);
        let mut per = vec![0.0; self.w.len()];
        for col in own.filter_map(|k| at.jacobian.get(first + k)) {
            for ((p, jc), wc) in per.iter_mut().zip(col).zip(&self.w) {
                *p += jc.iter().zip(wc).map(|(j, q)| q * j * j).sum::<f64>();
            }
        }
        let total: f64 = per.iter().sum();
        (0..per.len()).filter(|&c| total > 0.0 && per[c] >= MOVES_SHARE * total).collect()
    }
}
