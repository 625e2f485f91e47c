//! How far the identified model data may be from a real bench: one standard deviation
//! per map and uncertain parameter, each with its origin in the thesis or marked
//! ASSUMED with the reason. One declaration, two readers: the virtual bench perturbs
//! its plant's data by it (`simrod bench --perturb-maps`), and the diagnosis states
//! how far its fitted values may be off because of it (the identified maps are data
//! with this uncertainty, not truth).

/// Width [%] of the blend between the motoring and regenerating uncertainty of the
/// load maps around load set point 0 (`tanh(sp / width)`). ASSUMED: the maps' first
/// rows either side of 0 are at ±20 %, where the blend is 96 % complete.
pub const REGION_WIDTH_PCT: f64 = 10.0;

/// One standard deviation and where it comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sigma {
    /// The standard deviation, in the unit its field names.
    pub value: f64,
    /// Thesis section/table, or `ASSUMED: reason`.
    pub origin: &'static str,
}

impl Sigma {
    pub const fn new(value: f64, origin: &'static str) -> Self {
        Self { value, origin }
    }
}

/// A log-normal uncertainty of one or more parameter keys that share one
/// identification (they get the same factor).
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSigma {
    /// `parameters.toml` keys; all get the same factor.
    pub keys: &'static [&'static str],
    /// The keys' unit (for the summary).
    pub unit: &'static str,
    /// Standard deviation of `ln(true / identified)`; ≈ the relative sigma.
    pub sigma_ln: f64,
    /// Thesis section/table, or `ASSUMED: reason`.
    pub origin: &'static str,
}

/// How far the bench's true data may be from the identified data: one standard
/// deviation per map/parameter, each with its origin (thesis section/table) or marked
/// ASSUMED with the reason.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// Axle friction maps L, R: absolute [N m] (RMS over the map's grid points).
    pub friction_nm: [Sigma; 2],
    /// Friction taper width [rpm]: the change is scaled by `1 − exp(−(ω/ω_t)²)` so a
    /// map that is 0 at standstill stays 0 there.
    pub friction_taper_rpm: Sigma,
    /// Load torque maps, relative [-], where the load motors are motoring (load set
    /// point < 0). Load current maps get the same relative field (same side).
    pub load_torque_motoring_rel: Sigma,
    /// Load torque maps, relative [-], where the load motors regenerate (set point > 0).
    pub load_torque_regen_rel: Sigma,
    /// Load power maps: relative [-], independent of and on top of the torque field
    /// they share (the electrical efficiency of the load drives).
    pub load_power_rel: Sigma,
    /// SuT inverter power map, relative [-], where the SuT draws power (P ≥ 0).
    pub sut_power_rel: Sigma,
    /// SuT inverter power map, relative [-], where the SuT regenerates (P < 0).
    pub sut_power_regen_rel: Sigma,
    /// Speed maps fwd/rev, relative [-] (values strictly between 0 and the limit).
    pub speed_map_rel: Sigma,
    /// Throttle input map, relative [-] (values strictly between deadband and full).
    pub throttle_map_rel: Sigma,
    /// Scalar parameters (log-normal); keys not listed are not perturbed.
    pub params: Vec<ParamSigma>,
}

/// The Curtis identified time rates (table 5.17) that share one value per direction.
pub const IDENT_RATE_GROUPS: [&[&str]; 8] = [
    &["ident.accel_hs_fwd_s", "ident.accel_ls_fwd_s"],
    &["ident.accel_hs_rev_s", "ident.accel_ls_rev_s"],
    &["ident.low_accel_fwd_s"],
    &["ident.low_accel_rev_s"],
    &["ident.neutral_decel_hs_fwd_s", "ident.neutral_decel_ls_fwd_s"],
    &["ident.neutral_decel_hs_rev_s", "ident.neutral_decel_ls_rev_s"],
    &["ident.partial_decel_fwd_s"],
    &["ident.partial_decel_rev_s"],
];

const IDENT_RATE_ORIGIN: &str = "ASSUMED: table 5.17 gives the identified rates without a spread; \
     they are ramp-slope fits, and identified vs programmed differ by 3-5 % (3.98 vs 3.8 s), \
     so 3 % per identification";

impl Uncertainty {
    /// The thesis' identification uncertainty; every number's origin (thesis
    /// section/table, or ASSUMED with the reason) is in its `origin` field.
    pub fn thesis() -> Self {
        let mut params = vec![
            ParamSigma {
                keys: &["coupling_stiffness_identified"],
                unit: "N m/rad",
                sigma_ln: 0.26,
                origin: "table 5.10: 4369 N m/rad, run-to-run spread 3632 N m/rad over the ten \
                         significant runs (5.4, \"the computed variance among those is high\"): \
                         standard error 3632/sqrt(10) = 1149 N m/rad = 26 %",
            },
            ParamSigma {
                keys: &["coupling_stiffness_datasheet"],
                unit: "N m/rad",
                sigma_ln: 0.10,
                origin: "ASSUMED: catalogue value (table 5.10); the thesis cannot tell how it was \
                         computed (5.4); 10 % is a typical elastomer-coupling stiffness tolerance",
            },
            ParamSigma {
                keys: &["sut_inertia"],
                unit: "kg m^2",
                sigma_ln: 0.10,
                origin: "ASSUMED: table 5.8 gives no spread; 5.3.2 says the campaign \"gives just \
                         an idea\" (few points, low inertial torque, outliers discarded): 10 %",
            },
            ParamSigma {
                keys: &["load_inertia_l"],
                unit: "kg m^2",
                sigma_ln: 0.10,
                origin: "ASSUMED: table 5.8 gives no spread; 5.3.2 (few points, outliers): 10 %",
            },
            ParamSigma {
                keys: &["load_inertia_r"],
                unit: "kg m^2",
                sigma_ln: 0.10,
                origin: "ASSUMED: table 5.8 gives no spread; 5.3.2 (few points, outliers): 10 %",
            },
            ParamSigma {
                keys: &["connector_resistance"],
                unit: "ohm",
                sigma_ln: 0.23,
                origin: "table 5.14: sections 2 and 3 give 0.0166 and 0.0255 ohm, mean 0.0196; \
                         the standard error of a two-value mean is half their difference, \
                         0.0045 ohm = 23 %",
            },
            ParamSigma {
                keys: &["coupling_damping"],
                unit: "N m s/rad",
                sigma_ln: 0.30,
                origin: "ASSUMED: the value itself is assumed (docs/MODEL.md, elastomer zeta ~0.064); \
                         elastomer relative damping varies ~30 % with temperature and amplitude",
            },
            ParamSigma {
                keys: &["throttle_volts_per_pct"],
                unit: "V/%",
                sigma_ln: 0.01,
                origin: "ASSUMED: eq. 3.1 is nominal; a PLC analog output's gain error is ~1 %",
            },
        ];
        for keys in IDENT_RATE_GROUPS {
            params.push(ParamSigma { keys, unit: "s", sigma_ln: 0.03, origin: IDENT_RATE_ORIGIN });
        }
        Self {
            friction_nm: [
                Sigma::new(1.7583, "table 5.7: friction fit RMSE, axle L section 2, 1.7583 N m"),
                Sigma::new(2.2156, "table 5.7: friction fit RMSE, axle R section 2, 2.2156 N m"),
            ],
            friction_taper_rpm: Sigma::new(
                10.0,
                "ASSUMED: half the +-20 rpm cubic region of the friction map (5.3.1); the map is \
                 0 at standstill and must stay so",
            ),
            load_torque_motoring_rel: Sigma::new(
                0.03,
                "ASSUMED: the thesis gives no error for the 2-D maps (5.2, fig. 5.14/5.15); \
                 motoring plateaus are well covered by the campaign: 3 %",
            ),
            load_torque_regen_rel: Sigma::new(
                0.09,
                "ASSUMED: regenerating operation was barely identified (6.1.1: \"the lack of \
                 identifications for regenerating operations\"; 7: \"not really analysed\"): \
                 three times the motoring 3 %",
            ),
            load_power_rel: Sigma::new(
                0.02,
                "ASSUMED: electrical maps are \"quite high\" in accuracy (6.1); 2 % for the load \
                 drives' efficiency on top of the torque field",
            ),
            sut_power_rel: Sigma::new(
                0.03,
                "ASSUMED: SuT power map (5.5, fig. 5.42/5.43) validated with \"quite high\" \
                 accuracy (6.1): 3 %",
            ),
            sut_power_regen_rel: Sigma::new(
                0.08,
                "ASSUMED: regenerative electrics \"not really analysed\" (7): 8 % where the SuT \
                 inverter power is negative",
            ),
            speed_map_rel: Sigma::new(
                0.02,
                "ASSUMED: fig. 5.7 gives no error; 6.1 names the speed map as a mismatch source \
                 (point \"2\"): 2 %, limits 2100/500 rpm (table 5.3) kept",
            ),
            throttle_map_rel: Sigma::new(
                0.01,
                "ASSUMED: programmed Curtis input map (3.1.1); 1 % between deadband and full. The \
                 built-in map has no such points (0/0/100/100): only a map with interior points \
                 changes; the chain's gain is perturbed via throttle_volts_per_pct",
            ),
            params,
        }
    }

    /// No perturbation at all (every sigma 0): `perturb` then returns the data unchanged
    /// apart from the comments.
    pub fn none() -> Self {
        Self::thesis().scaled(0.0)
    }

    /// Every sigma times `f` (e.g. 2 for a bench further from the twin).
    pub fn scaled(mut self, f: f64) -> Self {
        let [fl, fr] = &mut self.friction_nm;
        for s in [
            fl,
            fr,
            &mut self.load_torque_motoring_rel,
            &mut self.load_torque_regen_rel,
            &mut self.load_power_rel,
            &mut self.sut_power_rel,
            &mut self.sut_power_regen_rel,
            &mut self.speed_map_rel,
            &mut self.throttle_map_rel,
        ] {
            s.value *= f;
        }
        for p in &mut self.params {
            p.sigma_ln *= f;
        }
        self
    }
}
