//! Checks shared by the measurement-reader targets (`csv`, `mat`).

use std::path::Path;

use simrod_io::measure::{parse_bytes, LoadOptions};

/// Run `data` through the whole reader pipeline as a file named `name` (the extension
/// picks the reader) and check what an `Ok` promises (workbench/io/src/measure/mod.rs,
/// resample.rs): at least one sample, finite and strictly increasing times, every
/// channel one finite value per sample, channel names unique. Errors must format.
pub fn check_measurement(name: &str, data: &[u8]) {
    let path = Path::new(name);
    match parse_bytes(path, data.to_vec(), &LoadOptions::default()) {
        Err(e) => {
            // Display walks the located message (line/column); it must not panic.
            let _ = e.to_string();
        }
        Ok(loaded) => {
            let m = &loaded.measurement;
            let t = &m.time_s;
            assert!(!t.is_empty(), "Ok with no samples");
            assert!(t.iter().all(|x| x.is_finite()), "Ok with a non-finite time: {t:?}");
            assert!(t.windows(2).all(|w| w[0] < w[1]), "Ok with times not strictly increasing: {t:?}");
            for (i, s) in m.signals.iter().enumerate() {
                assert_eq!(s.values.len(), t.len(), "channel {:?}: length differs from time", s.name);
                if let Some(v) = s.values.iter().find(|v| !v.is_finite()) {
                    panic!("channel {:?}: non-finite value {v} in an Ok result", s.name);
                }
                assert!(
                    m.signals[..i].iter().all(|o| o.name != s.name),
                    "channel {:?} appears twice in an Ok result",
                    s.name
                );
            }
            if let Some(dt) = loaded.resampled_dt {
                assert!(dt.is_finite() && dt > 0.0, "resampled onto dt = {dt}");
            }
        }
    }
}
