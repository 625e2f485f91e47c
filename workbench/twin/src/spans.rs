//! The channels' operating spans (`workbench/data/channel_spans.toml`, each with its
//! origin): what `compare` normalises a near-constant channel by, and what a measured
//! value must stay near to be a measurement of that channel at all ([`crate::plausible`]).

const SPANS_TOML: &str = include_str!("../../data/channel_spans.toml");

/// The documented operating span of channel `name` [its unit], if it has one.
pub fn operating_span(name: &str) -> Option<f64> {
    static SPANS: std::sync::OnceLock<Vec<(String, f64)>> = std::sync::OnceLock::new();
    let spans = SPANS.get_or_init(|| {
        let table: toml::Table = toml::from_str(SPANS_TOML).unwrap_or_default();
        table.iter().filter_map(|(k, v)| Some((k.clone(), v.get("span")?.as_float()?))).collect()
    });
    spans.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
}
