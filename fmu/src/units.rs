//! The units the twin's declarations use, in SI base units, for the model
//! description's `<UnitDefinitions>`: an importer can then convert (rpm to rad/s,
//! percent to one) and check connections. The declarations name units as strings
//! (`"N m"`, `"rpm"`); a unit not listed here stops the model description's
//! generation, naming it, so a new unit in model-core cannot reach an FMU undefined.

/// A unit as SI base-unit exponents and a factor: `value_SI = factor * value`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseUnit {
    pub kg: i8,
    pub m: i8,
    pub s: i8,
    pub a: i8,
    pub rad: i8,
    pub factor: f64,
}

const ONE: BaseUnit = BaseUnit { kg: 0, m: 0, s: 0, a: 0, rad: 0, factor: 1.0 };

/// The dimensionless "unit" of factors and counts: no unit attribute at all.
pub const DIMENSIONLESS: &str = "-";

/// The SI definition of `unit`; `None` for a unit this table does not know.
pub fn base_unit(unit: &str) -> Option<BaseUnit> {
    let u = match unit {
        "s" => BaseUnit { s: 1, ..ONE },
        "A" => BaseUnit { a: 1, ..ONE },
        // V = W/A = kg m^2 s^-3 A^-1.
        "V" => BaseUnit { kg: 1, m: 2, s: -3, a: -1, ..ONE },
        "W" => BaseUnit { kg: 1, m: 2, s: -3, ..ONE },
        "ohm" => BaseUnit { kg: 1, m: 2, s: -3, a: -2, ..ONE },
        "N m" => BaseUnit { kg: 1, m: 2, s: -2, ..ONE },
        "N m/rad" => BaseUnit { kg: 1, m: 2, s: -2, rad: -1, ..ONE },
        "N m s/rad" => BaseUnit { kg: 1, m: 2, s: -1, rad: -1, ..ONE },
        "rpm" => BaseUnit { s: -1, rad: 1, factor: 2.0 * std::f64::consts::PI / 60.0, ..ONE },
        "deg" => BaseUnit { rad: 1, factor: std::f64::consts::PI / 180.0, ..ONE },
        "%" => BaseUnit { factor: 0.01, ..ONE },
        _ => return None,
    };
    Some(u)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_units_are_consistent() {
        // W = V A, ohm = V / A, N m s/rad * rad/s = N m.
        let (v, a, w, ohm) = (
            base_unit("V").unwrap(),
            base_unit("A").unwrap(),
            base_unit("W").unwrap(),
            base_unit("ohm").unwrap(),
        );
        assert_eq!((v.kg + a.kg, v.m + a.m, v.s + a.s, v.a + a.a), (w.kg, w.m, w.s, w.a));
        assert_eq!((v.kg - a.kg, v.m - a.m, v.s - a.s, v.a - a.a), (ohm.kg, ohm.m, ohm.s, ohm.a));
        let rpm = base_unit("rpm").unwrap();
        assert!((rpm.factor * 60.0 - 2.0 * std::f64::consts::PI).abs() < 1e-15);
        assert!(base_unit("furlong").is_none());
        assert!(base_unit(DIMENSIONLESS).is_none());
    }
}
