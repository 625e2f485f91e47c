//! Effects of the real bench that the twin does not have (bench-only): each declared
//! once below with its physics, its parameters' units, the values they accept and a
//! realistic range (what the random-case generator draws from). All parameters default
//! to 0, and an effect is on while its first parameter is non-zero; the other
//! parameters are checked only then. The twin's own effects (model-core's library) are
//! simulated by the plant too, each with the plant's own code (see [`crate::plant`]).

use std::fmt;

/// One parameter of a bench-only effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamDecl {
    pub name: &'static str,
    pub unit: &'static str,
    pub doc: &'static str,
    /// Accepted values, inclusive.
    pub valid: (f64, f64),
    /// Magnitudes a real bench shows (the generator draws uniformly from them).
    pub realistic: (f64, f64),
}

/// A bench-only effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectDecl {
    pub id: &'static str,
    pub doc: &'static str,
    pub params: &'static [ParamDecl],
}

/// Why a parameter was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum KeyError {
    UnknownEffect(String),
    UnknownParameter { effect: &'static str, param: String, accepted: Vec<&'static str> },
    OutOfRange { effect: &'static str, param: &'static str, value: f64, valid: (f64, f64) },
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownEffect(id) => {
                let ids: Vec<_> = PLANT_EFFECTS.iter().map(|e| e.id).collect();
                write!(f, "unknown bench effect `{id}`; bench effects are {}", ids.join(", "))
            }
            Self::UnknownParameter { effect, param, accepted } => {
                write!(f, "[{effect}]: unknown parameter `{param}`; expected {}", accepted.join(", "))
            }
            Self::OutOfRange { effect, param, value, valid } => write!(
                f,
                "[{effect}]: {param} = {value} is invalid: {param} must be in [{}, {}]",
                valid.0, valid.1
            ),
        }
    }
}

impl std::error::Error for KeyError {}

macro_rules! plant_effects {
    ($(
        $(#[doc = $doc:literal])*
        $id:ident: $ty:ident {
            $( $(#[doc = $pdoc:literal])* $p:ident: $unit:literal, valid $vlo:literal..=$vhi:literal,
                realistic $rlo:literal..=$rhi:literal; )+
        }
    )+) => {
        $(
            $(#[doc = $doc])*
            #[derive(Debug, Clone, Copy, PartialEq, Default)]
            pub struct $ty { $( $(#[doc = $pdoc])* pub $p: f64, )+ }
        )+

        /// Every bench-only effect's parameters (all 0: none).
        #[derive(Debug, Clone, Copy, PartialEq, Default)]
        pub struct PlantEffects { $( pub $id: $ty, )+ }

        /// The bench-only effects, in file order.
        pub const PLANT_EFFECTS: &[EffectDecl] = &[$(
            EffectDecl {
                id: stringify!($id),
                doc: concat!($($doc),*),
                params: &[$(ParamDecl {
                    name: stringify!($p),
                    unit: $unit,
                    doc: concat!($($pdoc),*),
                    valid: ($vlo, $vhi),
                    realistic: ($rlo, $rhi),
                },)+],
            },
        )+];

        impl PlantEffects {
            /// A parameter's value; `None` for an unknown effect or parameter.
            pub fn get(&self, id: &str, param: &str) -> Option<f64> {
                match (id, param) {
                    $($( (stringify!($id), stringify!($p)) => Some(self.$id.$p), )+)+
                    _ => None,
                }
            }

            fn slot(&mut self, id: &str, param: &str) -> Option<&mut f64> {
                match (id, param) {
                    $($( (stringify!($id), stringify!($p)) => Some(&mut self.$id.$p), )+)+
                    _ => None,
                }
            }
        }
    };
}

impl PlantEffects {
    /// True when no bench-only effect is on.
    pub fn is_none(&self) -> bool {
        PLANT_EFFECTS.iter().all(|e| !self.is_on(e.id))
    }

    /// Whether effect `id` is on (its first parameter non-zero).
    pub fn is_on(&self, id: &str) -> bool {
        let first = decl(id).and_then(|e| e.params.first());
        first.and_then(|p| self.get(id, p.name)).is_some_and(|v| v != 0.0)
    }

    /// Whether `id` names a bench-only effect.
    pub fn is_plant_effect(id: &str) -> bool {
        decl(id).is_some()
    }

    /// Set a parameter (range checked by [`PlantEffects::check`]).
    pub fn set(&mut self, id: &str, param: &str, value: f64) -> Result<(), KeyError> {
        let Some(e) = decl(id) else { return Err(KeyError::UnknownEffect(id.to_owned())) };
        match self.slot(id, param) {
            Some(v) => {
                *v = value;
                Ok(())
            }
            None => Err(KeyError::UnknownParameter {
                effect: e.id,
                param: param.to_owned(),
                accepted: e.params.iter().map(|p| p.name).collect(),
            }),
        }
    }

    /// Every parameter of every effect that is on within its accepted values (the first
    /// parameter always).
    pub fn check(&self) -> Result<(), KeyError> {
        for e in PLANT_EFFECTS {
            let on = self.is_on(e.id);
            for (i, p) in e.params.iter().enumerate() {
                let v = self.get(e.id, p.name).unwrap_or(0.0);
                let ok = v.is_finite() && v >= p.valid.0 && v <= p.valid.1;
                if (i == 0 || on) && !ok {
                    return Err(KeyError::OutOfRange {
                        effect: e.id,
                        param: p.name,
                        value: v,
                        valid: p.valid,
                    });
                }
            }
        }
        Ok(())
    }

    /// `(effect, parameter, value)` of every effect that is on.
    pub fn entries(&self) -> Vec<(&'static str, &'static str, f64)> {
        let mut out = Vec::new();
        for e in PLANT_EFFECTS.iter().filter(|e| self.is_on(e.id)) {
            for p in e.params {
                out.push((e.id, p.name, self.get(e.id, p.name).unwrap_or(0.0)));
            }
        }
        out
    }
}

/// The declaration of bench-only effect `id`.
pub fn decl(id: &str) -> Option<&'static EffectDecl> {
    PLANT_EFFECTS.iter().find(|e| e.id == id)
}

plant_effects! {
    /// Stribeck friction: extra friction on both load-side nodes at low axle speed,
    /// `peak exp(-(w/w_s)^2)` against the motion, a shape the cubic/linear friction map
    /// cannot make (lubricant film not yet built up). Origin: the classical Stribeck curve;
    /// magnitudes ASSUMED (a few N m on maps of 8 N m at 20 rpm).
    stribeck_friction: Stribeck {
        /// extra friction torque near standstill, per side
        peak_nm: "N m", valid 0.0..=50.0, realistic 2.0..=8.0;
        /// axle speed over which it decays
        speed_rpm: "rpm", valid 0.1..=1000.0, realistic 10.0..=40.0;
    }
    /// Thermal drift of the busbar-to-inverter connector: it heats with `I² R`,
    /// `tau dT/dt = -T + G I² R`, and its resistance rises, `R = R0 (1 + alpha T)`.
    /// Copper: alpha = 0.0039/K; G and tau ASSUMED for a bolted lug (0.1 K/W, 20 s).
    connector_resistance_drift: ConnectorDrift {
        /// steady temperature rise per watt dissipated
        k_per_w: "K/W", valid 0.0..=10.0, realistic 0.05..=0.3;
        /// temperature coefficient of resistance (copper 0.0039)
        alpha_per_k: "1/K", valid 0.0..=0.01, realistic 0.0035..=0.0043;
        /// thermal time constant
        time_constant_s: "s", valid 0.1..=100000.0, realistic 10.0..=60.0;
    }
    /// Gearbox warm-up: the oil's viscosity falls as the gearbox warms over a run, and
    /// with it the axle friction: the friction maps are scaled by `max(0.2, 1 - d T)`,
    /// `tau dT/dt = -T + G P_friction`. A cold-start run (the thesis's campaigns began
    /// cold) shows friction falling by 10–30 % over minutes. Values ASSUMED.
    gearbox_warmup: GearboxWarmup {
        /// relative friction drop per kelvin of warming
        drop_per_k: "1/K", valid 0.0..=0.05, realistic 0.005..=0.015;
        /// steady temperature rise per watt of friction power
        k_per_w: "K/W", valid 0.0..=1.0, realistic 0.05..=0.15;
        /// thermal time constant
        time_constant_s: "s", valid 1.0..=100000.0, realistic 60.0..=300.0;
    }
    /// Gear-mesh torque ripple at the differential case: `(A + r |T|) sin(z theta_m)`,
    /// `z` ripple periods per motor revolution (the mesh frequency, aliased by a 1 kHz
    /// DAQ above 500 Hz). Transmission error of a spur stage; values ASSUMED.
    gear_mesh_ripple: MeshRipple {
        /// ripple amplitude at the case, axle frame
        amplitude_nm: "N m", valid 0.0..=20.0, realistic 0.3..=1.5;
        /// additional amplitude per N m transmitted
        relative: "-", valid 0.0..=0.2, realistic 0.01..=0.03;
        /// ripple periods per motor revolution (teeth of the input pinion)
        periods_per_rev: "-", valid 1.0..=200.0, realistic 13.0..=23.0;
    }
    /// Progressive (hardening) coupling stiffness: the elastomer coupling's torque is
    /// `k phi (1 + (phi/phi_d)^2)`: its secant stiffness doubles at the twist `phi_d`.
    /// Elastomer couplings (BIPEX-S) are progressive; `phi_d` ASSUMED around their rated
    /// twist of 1–3 degrees.
    progressive_coupling: ProgressiveCoupling {
        /// twist at which the secant stiffness has doubled
        doubling_twist_deg: "deg", valid 0.0..=90.0, realistic 1.0..=3.0;
    }
    /// Bearing and seal drag on the SuT gearbox output shafts, before the torque flanges
    /// (so the flanges do not see it, the SuT power does): quadratic in speed,
    /// `T = T_200 (w/200 rpm)|w/200 rpm|` per side. Values ASSUMED.
    bearing_drag: BearingDrag {
        /// drag per side at 200 rpm axle speed
        at_200rpm_nm: "N m", valid 0.0..=50.0, realistic 0.5..=2.0;
    }
    /// The DPU supply in current limit: above `limit` its voltage droops,
    /// `V = V_set - R_droop (I - limit)`. ASSUMED limit and droop of a 24 V lab supply
    /// (the runs draw up to ~300 A at their peaks; a steeper droop collapses the busbars
    /// under the constant-power loads, which the plant reports as an error).
    supply_current_limit: SupplyLimit {
        /// supply current where the droop starts
        limit_a: "A", valid 0.0..=2000.0, realistic 200.0..=260.0;
        /// droop resistance above the limit
        droop_ohm: "ohm", valid 0.001..=10.0, realistic 0.01..=0.04;
    }
    /// DC-link capacitance of the SuT inverter, fed through the connector resistance,
    /// with the inverter's current ripple: `C dV/dt = (V_b - V)/R - (P/V + a sin(z theta_m))`.
    /// `I_DC` is the connector current, `V_DC` the link voltage. Values ASSUMED (Curtis
    /// 24 V controllers carry a few mF; ripple at 6 per electrical period, 2 pole pairs).
    dc_link: DcLink {
        /// link capacitance
        capacitance_f: "F", valid 0.0..=1.0, realistic 0.002..=0.02;
        /// inverter current ripple amplitude
        ripple_a: "A", valid 0.0..=200.0, realistic 2.0..=10.0;
        /// ripple periods per motor revolution
        periods_per_rev: "-", valid 1.0..=100.0, realistic 6.0..=24.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_get_check_and_messages() {
        let mut fx = PlantEffects::default();
        assert!(fx.is_none());
        fx.set("stribeck_friction", "peak_nm", 5.0).unwrap();
        assert!(!fx.is_none() && fx.is_on("stribeck_friction"));
        // speed_rpm is 0, outside its range, once the effect is on.
        let e = fx.check().unwrap_err().to_string();
        assert_eq!(e, "[stribeck_friction]: speed_rpm = 0 is invalid: speed_rpm must be in [0.1, 1000]");
        fx.set("stribeck_friction", "speed_rpm", 30.0).unwrap();
        fx.check().unwrap();
        assert_eq!(fx.get("stribeck_friction", "speed_rpm"), Some(30.0));
        let e = fx.set("stribeck_friction", "width", 1.0).unwrap_err().to_string();
        assert!(e.contains("expected peak_nm, speed_rpm"), "{e}");
        let e = fx.set("nonsense", "x", 1.0).unwrap_err().to_string();
        assert!(e.contains("bench effects are stribeck_friction, connector_resistance_drift"), "{e}");
        fx.set("dc_link", "capacitance_f", f64::NAN).unwrap();
        assert!(fx.check().is_err());
    }

    #[test]
    fn realistic_ranges_are_valid() {
        for e in PLANT_EFFECTS {
            assert!(!e.doc.is_empty(), "{}", e.id);
            for p in e.params {
                let (lo, hi) = p.realistic;
                assert!(lo <= hi && lo >= p.valid.0 && hi <= p.valid.1, "{}.{}", e.id, p.name);
                assert!(!p.doc.is_empty(), "{}.{}", e.id, p.name);
            }
            assert!(e.params[0].realistic.0 > 0.0, "{}: realistic must switch it on", e.id);
        }
    }
}
