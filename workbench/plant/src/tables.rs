//! The bench's maps in f64: piecewise linear (1-D) and bilinear (2-D), edges clamped.
//! The plant's own interpolation (it shares only the data with the twin).

use std::cell::Cell;

use model_core::table::{Table1, Table2};

/// A strictly increasing grid that remembers the last interval it found: queries move
/// slowly from one evaluation to the next, so the search starts there (a plain binary
/// search per lookup was most of the plant's run time).
#[derive(Debug, Clone)]
pub(crate) struct Grid {
    pub(crate) x: Vec<f64>,
    last: Cell<usize>,
}

impl Grid {
    pub(crate) fn new(x: &[f32]) -> Self {
        Self { x: x.iter().map(|&v| f64::from(v)).collect(), last: Cell::new(0) }
    }

    /// Interval `i` and fraction `f` with `q = x[i] + f (x[i+1] - x[i])`, clamped to the
    /// grid.
    fn locate(&self, q: f64) -> (usize, f64) {
        let x = &self.x;
        let n = x.len();
        if n < 2 || q <= x[0] {
            return (0, 0.0);
        }
        if q >= x[n - 1] {
            return (n - 2, 1.0);
        }
        // x[0] < q < x[n-1]: walk from the last interval to the one with x[i] <= q < x[i+1].
        let mut i = self.last.get().min(n - 2);
        while q < x[i] {
            i -= 1;
        }
        while q >= x[i + 1] {
            i += 1;
        }
        self.last.set(i);
        (i, (q - x[i]) / (x[i + 1] - x[i]))
    }
}

/// `y(x)`.
#[derive(Debug, Clone)]
pub(crate) struct Lut1 {
    x: Grid,
    y: Vec<f64>,
}

impl Lut1 {
    pub(crate) fn new(t: &Table1<'_>) -> Self {
        Self { x: Grid::new(t.x()), y: t.y().iter().map(|&v| f64::from(v)).collect() }
    }

    pub(crate) fn at(&self, q: f64) -> f64 {
        if self.y.len() < 2 {
            return self.y.first().copied().unwrap_or(0.0);
        }
        let (i, f) = self.x.locate(q);
        self.y[i] + f * (self.y[i + 1] - self.y[i])
    }
}

/// `z(x, y)` with x the throttle set point and y the load set point; `z` row-major by y.
#[derive(Debug, Clone)]
pub(crate) struct Lut2 {
    x: Grid,
    y: Grid,
    z: Vec<f64>,
}

impl Lut2 {
    pub(crate) fn new(t: &Table2<'_>) -> Self {
        Self { x: Grid::new(t.x()), y: Grid::new(t.y()), z: t.z().iter().map(|&v| f64::from(v)).collect() }
    }

    pub(crate) fn at(&self, qx: f64, qy: f64) -> f64 {
        let nx = self.x.x.len();
        let (ix, fx) = self.x.locate(qx);
        let (iy, fy) = self.y.locate(qy);
        let z = |r: usize, c: usize| self.z.get(r * nx + c).copied().unwrap_or(0.0);
        let (ix1, iy1) = ((ix + 1).min(nx.saturating_sub(1)), (iy + 1).min(self.y.x.len().saturating_sub(1)));
        let lo = z(iy, ix) + fx * (z(iy, ix1) - z(iy, ix));
        let hi = z(iy1, ix) + fx * (z(iy1, ix1) - z(iy1, ix));
        lo + fy * (hi - lo)
    }
}

/// The maps the plant runs on, in f64.
#[derive(Debug, Clone)]
pub(crate) struct Tables {
    pub(crate) throttle_input: Lut1,
    pub(crate) speed: [Lut1; 2],
    pub(crate) friction: [Lut1; 2],
    pub(crate) load_torque: [Lut2; 2],
    pub(crate) load_power: [Lut2; 2],
    pub(crate) sut_power: Lut2,
}

impl Tables {
    pub(crate) fn new(m: &model_core::Maps<'_>) -> Self {
        Self {
            throttle_input: Lut1::new(&m.throttle_input),
            speed: [Lut1::new(&m.speed_fwd), Lut1::new(&m.speed_rev)],
            friction: [Lut1::new(&m.friction[0]), Lut1::new(&m.friction[1])],
            load_torque: [Lut2::new(&m.load_torque[0]), Lut2::new(&m.load_torque[1])],
            load_power: [Lut2::new(&m.load_power[0]), Lut2::new(&m.load_power[1])],
            sut_power: Lut2::new(&m.sut_power),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_interpolate_and_clamp() {
        let t = Lut1 { x: Grid::new(&[0.0, 1.0, 3.0]), y: vec![0.0, 10.0, 30.0] };
        assert_eq!(t.at(-1.0), 0.0);
        assert_eq!(t.at(2.0), 20.0);
        assert_eq!(t.at(0.5), 5.0); // searching down from the last interval
        assert_eq!(t.at(1.0), 10.0);
        assert_eq!(t.at(9.0), 30.0);
        // z = 2x + 3y is reproduced by bilinear interpolation.
        let t2 = Lut2 {
            x: Grid::new(&[0.0, 1.0, 4.0]),
            y: Grid::new(&[-1.0, 2.0]),
            z: vec![-3.0, -1.0, 5.0, 6.0, 8.0, 14.0],
        };
        assert!((t2.at(2.0, 0.5) - 5.5).abs() < 1e-12);
    }
}
