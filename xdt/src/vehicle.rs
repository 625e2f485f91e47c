//! The Kyburz DXP's longitudinal dynamics: masses, wheels, rolling resistance, drag and
//! grade (values and origins in `data/vehicle.toml`).

use crate::data as d;

/// The vehicle's parameters; defaults from `data/vehicle.toml`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Vehicle {
    /// [kg] the mass the xDT drives.
    pub mass_kg: f32,
    /// [kg] published empty mass (documentation and checks).
    pub mass_empty_kg: f32,
    /// [kg] published payload.
    pub payload_kg: f32,
    /// [kg] published gross vehicle mass.
    pub mass_gross_kg: f32,
    /// [km/h] published top speed; every cycle target is capped at it.
    pub top_speed_kmh: f32,
    /// [%] published gradeability.
    pub gradeability_pct: f32,
    /// [-] number of wheels (their rotating inertia adds to the mass).
    pub wheels: f32,
    /// [m] rolling radius of the driven wheels.
    pub wheel_radius_m: f32,
    /// [kg m^2] rotating inertia of one wheel.
    pub wheel_inertia_kg_m2: f32,
    /// [-] rolling-resistance coefficient.
    pub rolling_resistance: f32,
    /// [m/s] speed over which rolling resistance ramps in (continuous through 0).
    pub rolling_speed_eps_m_s: f32,
    /// [m^2] drag area c_d A.
    pub cd_a_m2: f32,
    /// [kg/m^3] air density.
    pub air_density_kg_m3: f32,
    /// [m/s^2] gravity.
    pub gravity_m_s2: f32,
    /// [-] gearbox and differential efficiency (force-balance checks only).
    pub driveline_efficiency: f32,
}

impl Default for Vehicle {
    fn default() -> Self {
        Self {
            mass_kg: d::VEHICLE_MASS_KG,
            mass_empty_kg: d::VEHICLE_MASS_EMPTY_KG,
            payload_kg: d::VEHICLE_PAYLOAD_KG,
            mass_gross_kg: d::VEHICLE_MASS_GROSS_KG,
            top_speed_kmh: d::VEHICLE_TOP_SPEED_KMH,
            gradeability_pct: d::VEHICLE_GRADEABILITY_PCT,
            wheels: d::VEHICLE_WHEELS,
            wheel_radius_m: d::VEHICLE_WHEEL_RADIUS_M,
            wheel_inertia_kg_m2: d::VEHICLE_WHEEL_INERTIA_KG_M2,
            rolling_resistance: d::VEHICLE_ROLLING_RESISTANCE,
            rolling_speed_eps_m_s: d::VEHICLE_ROLLING_SPEED_EPS_M_S,
            cd_a_m2: d::VEHICLE_CD_A_M2,
            air_density_kg_m3: d::VEHICLE_AIR_DENSITY_KG_M3,
            gravity_m_s2: d::VEHICLE_GRAVITY_M_S2,
            driveline_efficiency: d::VEHICLE_DRIVELINE_EFFICIENCY,
        }
    }
}

/// A key that is not a vehicle parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UnknownKey;

/// Every key of `vehicle.toml`, in file order.
pub const KEYS: [&str; 15] = [
    "mass_empty_kg",
    "payload_kg",
    "mass_gross_kg",
    "mass_kg",
    "top_speed_kmh",
    "gradeability_pct",
    "wheels",
    "wheel_radius_m",
    "wheel_inertia_kg_m2",
    "rolling_resistance",
    "rolling_speed_eps_m_s",
    "cd_a_m2",
    "air_density_kg_m3",
    "gravity_m_s2",
    "driveline_efficiency",
];

impl Vehicle {
    /// Set a parameter by its `vehicle.toml` key (a vehicle file read at run time on the
    /// host goes through here, as the build goes through the constants).
    pub fn set(&mut self, key: &str, v: f32) -> Result<(), UnknownKey> {
        *self.field(key).ok_or(UnknownKey)? = v;
        Ok(())
    }

    /// A parameter by its key.
    pub fn get(&self, key: &str) -> Option<f32> {
        let mut c = *self;
        c.field(key).map(|f| *f)
    }

    fn field(&mut self, key: &str) -> Option<&mut f32> {
        Some(match key {
            "mass_kg" => &mut self.mass_kg,
            "mass_empty_kg" => &mut self.mass_empty_kg,
            "payload_kg" => &mut self.payload_kg,
            "mass_gross_kg" => &mut self.mass_gross_kg,
            "top_speed_kmh" => &mut self.top_speed_kmh,
            "gradeability_pct" => &mut self.gradeability_pct,
            "wheels" => &mut self.wheels,
            "wheel_radius_m" => &mut self.wheel_radius_m,
            "wheel_inertia_kg_m2" => &mut self.wheel_inertia_kg_m2,
            "rolling_resistance" => &mut self.rolling_resistance,
            "rolling_speed_eps_m_s" => &mut self.rolling_speed_eps_m_s,
            "cd_a_m2" => &mut self.cd_a_m2,
            "air_density_kg_m3" => &mut self.air_density_kg_m3,
            "gravity_m_s2" => &mut self.gravity_m_s2,
            "driveline_efficiency" => &mut self.driveline_efficiency,
            _ => return None,
        })
    }

    /// The first parameter outside its physical range: `(key, what is expected)`.
    pub fn validate(&self) -> Result<(), (&'static str, &'static str)> {
        let positive = "a finite number > 0";
        let non_negative = "a finite number >= 0";
        let checks: [(&'static str, bool, &'static str); 15] = [
            ("mass_kg", pos(self.mass_kg), positive),
            ("mass_empty_kg", pos(self.mass_empty_kg), positive),
            ("payload_kg", non_neg(self.payload_kg), non_negative),
            ("mass_gross_kg", pos(self.mass_gross_kg), positive),
            ("top_speed_kmh", pos(self.top_speed_kmh), positive),
            ("gradeability_pct", pos(self.gradeability_pct), positive),
            ("wheels", pos(self.wheels), positive),
            ("wheel_radius_m", pos(self.wheel_radius_m), positive),
            ("wheel_inertia_kg_m2", non_neg(self.wheel_inertia_kg_m2), non_negative),
            ("rolling_resistance", non_neg(self.rolling_resistance), non_negative),
            ("rolling_speed_eps_m_s", pos(self.rolling_speed_eps_m_s), positive),
            ("cd_a_m2", non_neg(self.cd_a_m2), non_negative),
            ("air_density_kg_m3", non_neg(self.air_density_kg_m3), non_negative),
            ("gravity_m_s2", pos(self.gravity_m_s2), positive),
            (
                "driveline_efficiency",
                pos(self.driveline_efficiency) && self.driveline_efficiency <= 1.0,
                "in (0, 1]",
            ),
        ];
        match checks.iter().find(|(_, ok, _)| !ok) {
            Some((k, _, why)) => Err((k, why)),
            None => Ok(()),
        }
    }

    /// [kg] translational mass plus the wheels' rotating inertia, `m + n J_w / r^2`.
    pub fn equivalent_mass(&self) -> f32 {
        let r = self.wheel_radius_m;
        self.mass_kg + self.wheels * self.wheel_inertia_kg_m2 / (r * r)
    }

    /// [N] the road's resistance at speed `v` [m/s] on a slope of sine `sin` and cosine
    /// `cos`, + opposing forward motion: rolling (ramped in over `rolling_speed_eps_m_s`,
    /// so continuous through standstill), aerodynamic drag, and the grade.
    #[inline]
    pub fn road_force(&self, v: f32, sin: f32, cos: f32) -> f32 {
        let weight = self.mass_kg * self.gravity_m_s2;
        let ramp = crate::num::clamp(v / self.rolling_speed_eps_m_s, -1.0, 1.0);
        let rolling = self.rolling_resistance * weight * cos * ramp;
        let aero = 0.5 * self.air_density_kg_m3 * self.cd_a_m2 * v * if v < 0.0 { -v } else { v };
        rolling + aero + weight * sin
    }
}

fn pos(v: f32) -> bool {
    v.is_finite() && v > 0.0
}

fn non_neg(v: f32) -> bool {
    v.is_finite() && v >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_key_sets_its_own_field() {
        for (i, k) in KEYS.iter().enumerate() {
            let mut v = Vehicle::default();
            v.set(k, 1000.0 + i as f32).unwrap();
            assert_eq!(v.get(k), Some(1000.0 + i as f32), "{k}");
            for other in KEYS.iter().filter(|o| *o != k) {
                assert_eq!(v.get(other), Vehicle::default().get(other), "{k} changed {other}");
            }
        }
        assert_eq!(Vehicle::default().set("mass", 1.0), Err(UnknownKey));
    }

    #[test]
    fn published_masses_add_up() {
        let v = Vehicle::default();
        assert!(v.validate().is_ok());
        assert!(v.mass_empty_kg + v.payload_kg <= v.mass_gross_kg);
        let mut bad = v;
        bad.driveline_efficiency = 1.2;
        assert_eq!(bad.validate().unwrap_err().0, "driveline_efficiency");
    }

    /// Hand numbers: 510 kg at 10 m/s on the flat: rolling 0.015 x 510 x 9.80665 = 75.02 N,
    /// drag 0.5 x 1.204 x 0.85 x 100 = 51.17 N.
    #[test]
    fn road_force_by_hand() {
        let v = Vehicle::default();
        let f = v.road_force(10.0, 0.0, 1.0);
        assert!((f - (75.02 + 51.17)).abs() < 0.05, "{f}");
        // Standstill on the flat: nothing; on a slope: the weight's component.
        assert_eq!(v.road_force(0.0, 0.0, 1.0), 0.0);
        let s = 0.1f32 / (1.0f32 + 0.01).sqrt();
        assert!((v.road_force(0.0, s, 1.0) - 510.0 * 9.80665 * s).abs() < 0.01);
        // Continuous through zero, odd in the speed.
        assert!((v.road_force(-3.0, 0.0, 1.0) + v.road_force(3.0, 0.0, 1.0)).abs() < 1e-3);
    }
}
