//! The measurement chain replayed over a run's physical values. A diagnosis tries the
//! chain's parameters (a gain, an offset, a lag and a delay per channel) by the hundred;
//! they change what the bench records, not what the drivetrain does, so the drivetrain
//! need not run again for each. One run of the model with its chain neutral keeps the
//! physical values of the measured channels; model-core's own chain, applied to them
//! step by step as the model applies it, then gives bit for bit what the model with that
//! chain records (tested below).

use model_core::chain::{Chain, ChainState, N_MEASURED};
use model_core::{Channel, Effects, Inputs, MEASURED, N_CHANNELS};

use super::{Keep, ModelOptions, TwinError};

/// The physical values of the measured channels at every step of one run.
pub struct Physical {
    dt_us: u32,
    /// The run's effects, with the chain neutral.
    physics: Effects,
    /// `[step][MEASURED index]`.
    rows: Vec<[f32; N_MEASURED]>,
}

impl Physical {
    /// Whether `fx` differs from this run's effects in the measurement chain at most.
    /// An offset of -0 is refused: `v + -0` keeps the sign of a zero `v` that the
    /// neutral run's `v + 0` has already made +0.
    pub fn covers(&self, fx: &Effects) -> bool {
        neutral_chain(fx) == self.physics
            && fx.sensor_offset.iter().all(|k| k.to_bits() != (-0.0f32).to_bits())
    }
}

/// `fx` with every channel's gain 1, offset 0, no lag and no delay.
pub fn neutral_chain(fx: &Effects) -> Effects {
    let n = Effects::NONE;
    Effects {
        sensor_gain: n.sensor_gain,
        sensor_offset: n.sensor_offset,
        sensor_lag_s: n.sensor_lag_s,
        sensor_delay_s: n.sensor_delay_s,
        ..*fx
    }
}

impl ModelOptions {
    /// Run the twin over `inputs` with `fx`'s physics and a neutral chain, keeping the
    /// physical values of the measured channels.
    pub fn run_physical(&self, dt_us: u32, fx: &Effects, inputs: &[Inputs]) -> Result<Physical, TwinError> {
        let physics = neutral_chain(fx);
        let mut model = self.model(dt_us, physics)?;
        let rows = inputs
            .iter()
            .map(|inp| {
                let o = model.step(inp);
                core::array::from_fn(|i| o.get(MEASURED[i]))
            })
            .collect();
        Ok(Physical { dt_us, physics, rows })
    }

    /// As [`ModelOptions::run_kept`] with `fx` on the run `ph` was taken from, by
    /// replaying `fx`'s chain over `ph`; `None` when that cannot give the same bits (`fx`
    /// changes more than the chain, or a channel is not measured).
    pub fn replay(
        &self,
        ph: &Physical,
        fx: &Effects,
        channels: &[Channel],
        keep: Keep,
    ) -> Option<Result<Vec<Vec<f32>>, TwinError>> {
        if !ph.covers(fx) {
            return None;
        }
        let mut at = [usize::MAX; N_CHANNELS];
        for (i, c) in MEASURED.iter().enumerate() {
            at[*c as usize] = i;
        }
        if channels.iter().any(|c| at[*c as usize] == usize::MAX) {
            return None;
        }
        // The model's own checks of the effects, with its errors.
        if let Err(e) = self.model(ph.dt_us, *fx) {
            return Some(Err(e));
        }
        let dt_s = f64::from(ph.dt_us) * 1e-6;
        let chain =
            Chain::<f32>::new(fx.sensor_gain, fx.sensor_offset, fx.sensor_lag_s, fx.sensor_delay_s, dt_s);
        let mut state = ChainState::default();
        let mut rec = self.sensors.recorder(channels, dt_s, ph.rows.len(), keep);
        for row in &ph.rows {
            let m = chain.apply(&mut state, row);
            rec.record(|c| m[at[c as usize]]);
        }
        Some(Ok(rec.finish()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::{Builtin, Profile};

    fn inputs(b: Builtin, ts: f32, ls: f32, seconds: u64) -> Vec<Inputs> {
        let p = Profile::new(b.sets(), ts, ls).expect("a built-in profile");
        (0..seconds * 1000).map(|k| Inputs { sp: p.at(k * 1000), supply_v: 24.0 }).collect()
    }

    fn bits(v: &[Vec<f32>]) -> Vec<Vec<u32>> {
        v.iter().map(|c| c.iter().map(|x| x.to_bits()).collect()).collect()
    }

    /// Gains, offsets, lags and delays on several channels (speed channels through the
    /// encoder window included), kept whole and strided: the replay equals the model
    /// run with that chain, bit for bit, on the physics of the base effects.
    #[test]
    fn a_replayed_chain_is_the_model_with_that_chain() {
        let m = ModelOptions::default();
        let mut base = Effects::NONE;
        base.differential_friction.coulomb_nm = 2.0;
        base.sensor_gain[12] = 1.03;
        let inp = inputs(Builtin::TP14, 1.0, 0.5, 12);
        let ph = m.run_physical(1000, &base, &inp).expect("the twin runs");
        let channels: Vec<Channel> = MEASURED.to_vec();
        let mut chains = vec![base];
        let mut fx = base;
        fx.sensor_gain[2] = 0.97;
        fx.sensor_offset[3] = -1.5;
        fx.sensor_offset[1] = 12.0;
        fx.sensor_lag_s[4] = 0.04;
        fx.sensor_lag_s[12] = 0.01;
        fx.sensor_delay_s[1] = 0.06;
        fx.sensor_delay_s[13] = 0.003;
        chains.push(fx);
        let mut zero_offset = base;
        zero_offset.sensor_offset[5] = 0.0;
        chains.push(zero_offset);
        for fx in &chains {
            for keep in [Keep::ALL, Keep { first: 2, stride: 5 }] {
                let want = m.run_kept(1000, *fx, &inp, &channels, keep).expect("the twin runs");
                let got = m.replay(&ph, fx, &channels, keep).expect("a chain change").expect("valid");
                assert_eq!(bits(&got), bits(&want), "{keep:?}");
            }
        }
    }

    /// A change beyond the chain, an offset of -0 or a derived channel is not replayed;
    /// an invalid chain gets the model's error.
    #[test]
    fn only_chain_changes_are_replayed() {
        let m = ModelOptions::default();
        let inp = inputs(Builtin::TP07, 1.0, 1.0, 1);
        let ph = m.run_physical(1000, &Effects::NONE, &inp).expect("the twin runs");
        let mut physical = Effects::NONE;
        physical.supply_resistance = 0.01;
        assert!(m.replay(&ph, &physical, &[Channel::IDc], Keep::ALL).is_none());
        let mut minus_zero = Effects::NONE;
        minus_zero.sensor_offset[0] = -0.0;
        assert!(m.replay(&ph, &minus_zero, &[Channel::IDc], Keep::ALL).is_none());
        assert!(m.replay(&ph, &Effects::NONE, &[Channel::PDpu], Keep::ALL).is_none());
        let mut bad = Effects::NONE;
        bad.sensor_lag_s[0] = -1.0;
        assert!(matches!(m.replay(&ph, &bad, &[Channel::IDc], Keep::ALL), Some(Err(_))));
    }
}
