//! Lookup tables: interpolation, clamping, grid checks, hinted search.

use model_core::table::*;

#[test]
fn interpolates_and_clamps() {
    let t = Table1::new(&[0.0, 1.0, 3.0], &[0.0, 10.0, 30.0]).unwrap();
    assert_eq!(t.eval(0.5), 5.0);
    assert_eq!(t.eval(2.0), 20.0);
    assert_eq!(t.eval(-5.0), 0.0);
    assert_eq!(t.eval(7.0), 30.0);
    assert_eq!(t.eval(1.0), 10.0);
    assert_eq!(t.eval(f32::NAN), 0.0);
}

#[test]
fn hinted_search_equals_plain_search() {
    let x = [-3.0f32, -1.0, 0.0, 0.5, 2.0, 7.0];
    let mut hint = 0;
    let mut q = -5.0f32;
    while q < 9.0 {
        for start in 0..x.len() + 2 {
            let mut h = start;
            assert_eq!(locate_hinted(&x, q, &mut h), locate(&x, q), "q={q} hint={start}");
        }
        assert_eq!(locate_hinted(&x, q, &mut hint), locate(&x, q));
        q += 0.037;
    }
    let mut h = 2;
    assert_eq!(locate_hinted(&x, f32::NAN, &mut h), locate(&x, f32::NAN));
}

#[test]
fn rejects_bad_grids() {
    assert_eq!(Table1::new(&[0.0, 0.0], &[1.0, 2.0]).unwrap_err(), TableError::NotIncreasing);
    assert_eq!(Table1::new(&[0.0], &[1.0]).unwrap_err(), TableError::TooShort);
    assert_eq!(Table1::new(&[0.0, 1.0], &[1.0]).unwrap_err(), TableError::LengthMismatch);
    assert_eq!(Table1::new(&[0.0, f32::NAN], &[1.0, 2.0]).unwrap_err(), TableError::NotFinite);
    assert_eq!(Table2::new(&[0.0, 1.0], &[0.0, 1.0], &[0.0; 3]).unwrap_err(), TableError::LengthMismatch);
}

#[test]
fn bilinear_matches_plane() {
    // z = 2x + 3y is reproduced exactly by bilinear interpolation.
    let x = [0.0, 1.0, 4.0];
    let y = [-1.0, 2.0];
    let mut z = [0.0; 6];
    for (iy, yv) in y.iter().enumerate() {
        for (ix, xv) in x.iter().enumerate() {
            z[iy * 3 + ix] = 2.0 * xv + 3.0 * yv;
        }
    }
    let t = Table2::new(&x, &y, &z).unwrap();
    for &(qx, qy) in &[(0.5f32, 0.0f32), (2.0, 1.5), (3.9, -0.5)] {
        assert!((t.eval(qx, qy) - (2.0 * qx + 3.0 * qy)).abs() < 1e-5);
    }
    assert_eq!(t.eval(10.0, 10.0), 2.0 * 4.0 + 3.0 * 2.0);
}
