//! Presenting a comparison: a terminal table, JSON for scripts, and a self-contained
//! HTML report with inline SVG charts (one plotter, `svg`, on plotters' SVG backend).

pub mod html;
pub mod json;
pub mod svg;
pub mod table;

/// A number with about 4 significant digits, for tables and captions.
pub fn num(v: f64) -> String {
    if !v.is_finite() {
        return "-".into();
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e6).contains(&a) {
        format!("{v:.3e}")
    } else if a >= 1000.0 {
        format!("{v:.0}")
    } else if a >= 100.0 {
        format!("{v:.1}")
    } else if a >= 10.0 {
        format!("{v:.2}")
    } else if a >= 1.0 {
        format!("{v:.3}")
    } else {
        format!("{v:.4}")
    }
}

/// A 0..1 share as a percentage.
pub fn pct(v: f64) -> String {
    if !v.is_finite() {
        "-".into()
    } else {
        format!("{:.0} %", 100.0 * v)
    }
}

/// Relative change from `before` to `after` as a signed percentage (`-61 %`; `0 %` when it
/// rounds to nothing, so no `-0 %`); `-` when there is no finite, positive `before`.
pub fn change_pct(before: f64, after: f64) -> String {
    if !(before > 0.0 && before.is_finite() && after.is_finite()) {
        return "-".into();
    }
    let c = (100.0 * (after - before) / before).round();
    if c == 0.0 {
        "0 %".into()
    } else {
        format!("{c:+.0} %")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short() {
        assert_eq!(num(0.0), "0");
        assert_eq!(num(2.0), "2.000");
        assert_eq!(num(-12.345), "-12.35");
        assert_eq!(num(1234.4), "1234");
        assert_eq!(num(1.5e-7), "1.500e-7");
        assert_eq!(num(f64::NAN), "-");
        assert_eq!(pct(0.724), "72 %");
        assert_eq!(change_pct(2.0, 0.5), "-75 %");
        assert_eq!(change_pct(2.0, 1.999), "0 %");
        assert_eq!(change_pct(1.0, 1.2), "+20 %");
        assert_eq!(change_pct(0.0, 1.0), "-");
    }
}
