//! Whether a cause credited beyond the estimate is a constant there: the verdict's
//! constancy test ([`crate::constancy`]) on the set's settled refit, at the estimated
//! maps. A plant that warms up or an offset that drifts adds beyond the estimate as the
//! nearest constant of the library (a gearbox warm-up as an axle friction scale, a drifting
//! voltage offset as a gain), which the verdict refuses on the identified maps for its
//! drift; credited beyond the estimate without the test, it was claimed (proof 28: 2 of
//! its 4 false claims). The test is run where the claim is made: the maps as estimated,
//! so that what a map's error does band by band is not read as the cause's drift.

use rayon::prelude::*;

use super::{Point, Problem};
use crate::library::{current_value, with_values, ParamSpec};
use crate::preparation::energy;
use crate::refit::Fit;
use crate::uncertainty::parameter_std;

impl Problem<'_> {
    /// The first cause of the set at `at` outside `kept` (the verdict's members, tested
    /// by the verdict) whose parameter drifts over the run, with speed or with the load,
    /// and why, said for the user. The set's other parameters and the maps are held at
    /// the refit; the cause's own are differentiated on the full fit samples (one run
    /// per parameter).
    pub(super) fn drifting(&self, at: &Point, kept: &[&str]) -> Result<Option<(String, String)>, String> {
        let own: Vec<usize> =
            (0..self.free.len()).filter(|&k| !kept.contains(&self.free[k].0.cause)).collect();
        if own.is_empty() {
            return Ok(None);
        }
        let data = std::sync::Arc::new(self.data(&at.x));
        let values = self.values(&at.x);
        let all: Vec<&ParamSpec> = self.free.iter().map(|(s, _)| s).collect();
        let stride = self.p.stride;
        let sim = self.twin.run_data(&data, &self.effects(&at.x), stride)?;
        let columns: Vec<Result<Vec<Vec<f64>>, String>> = own
            .par_iter()
            .map(|&k| {
                let s = all[k];
                let step = if values[k] + s.delta <= s.upper { s.delta } else { -s.delta };
                let mut moved = values.clone();
                moved[k] += step;
                let y = self.twin.run_data(&data, &with_values(&self.fx, &all, &moved), stride)?;
                let col = y.iter().zip(&sim);
                Ok(col
                    .map(|(a, b)| {
                        a.iter().zip(b).map(|(a, b)| (f64::from(*a) - f64::from(*b)) / step).collect()
                    })
                    .collect())
            })
            .collect();
        let jac = columns.into_iter().collect::<Result<Vec<_>, String>>()?;
        let specs: Vec<&ParamSpec> = own.iter().map(|&k| all[k]).collect();
        let starts: Vec<f64> = specs.iter().map(|s| current_value(&self.fx, s)).collect();
        let energy = energy(self.p, &sim);
        let own_values = own.iter().map(|&k| values[k]).collect();
        let fit = Fit { values: own_values, sim, jac, energy, profile: Vec::new(), held: None };
        let drift = parameter_std(self.p, &fit, &specs, &starts, self.twin.dt_s()).drift;
        Ok(drift.map(|d| {
            let why = format!(
                "its {} {} ({:.4} to {:.4}) beside the estimated maps",
                d.param,
                d.along.what(),
                d.first,
                d.last
            );
            (d.cause.to_string(), why)
        }))
    }
}
