//! From a road-load torque to a load motor's set point: the inverse of the twin's load
//! torque map (`model-core/data/load_torque_*.csv`, (throttle %, load %) -> axle torque
//! [N m], + regenerating) on the map's own grid.
//!
//! Why invert the map rather than close a torque loop: the load motors are current
//! controlled and the map is the bench's identified current -> torque relation, so the
//! inverse is the set point the bench's own model says gives the torque, with no extra
//! loop whose dynamics would add to the XiL loop's (the delay margin is the loop's, not a
//! torque controller's). At a fixed throttle the bilinear map is piecewise linear in the
//! load set point with breaks at the grid, so the inverse is exact there. What the map does
//! not hold stays unemulated: the regeneration's fade below `regen_fade_rpm` and the
//! motoring torque's back-EMF fade (both speed-dependent, outside the map); a torque
//! beyond the map's range is clipped to its end and flagged.

use model_core::table::{locate_hinted, Table2};

use crate::num::invert_monotone_hinted;

/// Why a load map cannot be inverted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NotMonotone {
    /// Column (throttle grid index) where the torque falls with a rising load set point.
    pub column: usize,
}

/// A load torque map that is non-decreasing in the load set point at every throttle.
#[derive(Debug, Clone, Copy)]
pub struct LoadInverse<'a> {
    map: Table2<'a>,
}

impl<'a> LoadInverse<'a> {
    /// Check `map` can be inverted: every column non-decreasing along the load axis.
    pub fn new(map: Table2<'a>) -> Result<Self, NotMonotone> {
        let (nx, z) = (map.x().len(), map.z());
        for column in 0..nx {
            let col = z.iter().skip(column).step_by(nx.max(1));
            let mut prev = f32::NEG_INFINITY;
            for v in col {
                if *v < prev {
                    return Err(NotMonotone { column });
                }
                prev = *v;
            }
        }
        Ok(Self { map })
    }

    /// The load set point [%] at throttle set point `thr` [%] that the map gives
    /// `torque` [N m] for, and whether `torque` lay beyond the map (clipped).
    #[inline]
    pub fn set_point(&self, thr: f32, torque: f32) -> (f32, bool) {
        self.set_point_hinted(thr, torque, &mut LoadHint::default())
    }

    /// [`LoadInverse::set_point`] with search hints (see `table::locate_hinted`): the
    /// same result, in fewer instructions.
    #[inline]
    pub fn set_point_hinted(&self, thr: f32, torque: f32, hint: &mut LoadHint) -> (f32, bool) {
        let (x, y, z) = (self.map.x(), self.map.y(), self.map.z());
        let nx = x.len();
        let (ix, tx) = locate_hinted(x, thr, &mut hint.throttle);
        let row = |j: usize| {
            let z0 = z.get(j * nx + ix).copied().unwrap_or(0.0);
            let z1 = z.get(j * nx + ix + 1).copied().unwrap_or(z0);
            (y.get(j).copied().unwrap_or(0.0), z0 + tx * (z1 - z0))
        };
        invert_monotone_hinted(y.len(), row, torque, &mut hint.load)
    }
}

/// The last intervals found by [`LoadInverse::set_point_hinted`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoadHint {
    throttle: usize,
    load: usize,
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::Maps;

    /// Through the map forward again, the set point gives the torque asked for.
    #[test]
    fn inverse_round_trips_through_the_map() {
        let maps = Maps::builtin();
        for side in 0..2 {
            let inv = LoadInverse::new(maps.load_torque[side]).unwrap();
            for thr in [0.0f32, 12.5, 35.0, 64.0, 78.0, 95.0] {
                for tq in [-68.0f32, -31.0, -2.5, 0.0, 0.7, 13.0, 52.0, 72.0] {
                    let (sp, clipped) = inv.set_point(thr, tq);
                    assert!(!clipped, "side {side} thr {thr} tq {tq}");
                    let back = maps.load_torque[side].eval(thr, sp);
                    assert!((back - tq).abs() < 1e-3, "side {side} thr {thr}: {tq} -> {sp} % -> {back}");
                }
            }
            // Beyond the map: clipped to its ends, flagged.
            let (sp, clipped) = inv.set_point(50.0, 200.0);
            assert!(clipped && (sp - 60.0).abs() < 1e-4, "{sp}");
            let (sp, clipped) = inv.set_point(50.0, -200.0);
            assert!(clipped && sp == -100.0, "{sp}");
        }
    }

    #[test]
    fn a_falling_column_is_refused() {
        let x = [0.0f32, 1.0];
        let y = [0.0f32, 1.0, 2.0];
        let z = [0.0f32, 0.0, 1.0, 2.0, 0.5, 3.0];
        let t = Table2::new(&x, &y, &z).unwrap();
        assert_eq!(LoadInverse::new(t).unwrap_err(), NotMonotone { column: 0 });
    }
}
