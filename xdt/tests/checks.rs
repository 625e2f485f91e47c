//! The DXP's published performance against the parameter set (vehicle.toml + the twin's
//! drive): the force balance of `simrod_xdt::checks`.

use model_core::Params;
use simrod_xdt::checks::{gradeability, top_speed, torque_for_grade, TopSpeedLimit};
use simrod_xdt::Vehicle;

/// 45 km/h published. The governor (Curtis Max Speed Fwd, 5000 rpm) sets it, through the
/// gear ratio and the wheel radius, both assumed: the ratio 11.05 comes from the
/// forward speed limits (2100/190 rpm) while the reverse pair gives 10.0 (a 10 % spread
/// in the thesis's own tables), and the radius is a tyre class, +-5 %. Tolerance
/// +-12 %: those two in quadrature, rounded up.
#[test]
fn top_speed_is_the_published_45_kmh() {
    let v = Vehicle::default();
    let (top, limit) = top_speed(&v, &Params::default());
    let kmh = top * 3.6;
    eprintln!("top speed {kmh:.2} km/h ({limit:?}), published {} km/h", v.top_speed_kmh);
    assert_eq!(limit, TopSpeedLimit::MaxSpeed, "the DXP is governed, not power-limited, at its top speed");
    assert!((kmh - 45.0).abs() <= 0.12 * 45.0, "{kmh} km/h");
}

/// 30 % published, load not stated. A FINDING, asserted as one: the parameter set
/// brackets the figure between the published empty mass (300 kg) and the gross mass
/// (510 kg), but climbs only about 20 % fully laden, because model-core's motor torque
/// limit (25 N m, ASSUMED in parameters.toml) is below what 30 % laden needs (about
/// 36 N m at the motor). The 25 N m with the 5000 rpm governor make a corner power of
/// 25 x 523.6 = 13.1 kW; 45 km/h and 30 % laden need 1.51 kN x 12.5 m/s / 0.95 = 19.9 kW,
/// whatever the wheel and gear. When the torque limit is revised, this test says so.
#[test]
fn gradeability_brackets_30_percent_but_not_laden() {
    let v = Vehicle::default();
    let p = Params::default();
    let at = |m: f32| gradeability(&v, &p, f64::from(m), 0.0);
    let (empty, gross) = (at(v.mass_empty_kg), at(v.mass_gross_kg));
    let need = torque_for_grade(&v, &p, f64::from(v.mass_gross_kg), v.gradeability_pct.into());
    eprintln!(
        "gradeability {empty:.1} % empty ({} kg), {gross:.1} % gross ({} kg); 30 % at gross needs {need:.1} N m \
         at the motor (parameters.toml: {} N m)",
        v.mass_empty_kg, v.mass_gross_kg, p.motor_torque_max_nm
    );
    let published = f64::from(v.gradeability_pct);
    assert!(empty >= published && gross < published, "{empty} % .. {gross} %");
    assert!(need > f64::from(p.motor_torque_max_nm), "{need} N m");
    // The balance: at the torque it names, the gross vehicle climbs exactly 30 %.
    let p2 = Params { motor_torque_max_nm: need as f32, ..p };
    assert!((gradeability(&v, &p2, f64::from(v.mass_gross_kg), 0.0) - published).abs() < 0.01);
}
