//! The improve-the-model loop's memory: every `simrod compare` run appends one record to
//! `<meas-stem>.simrod-history.jsonl` next to the measurement (one JSON object per line),
//! so `simrod history` can show the error per channel falling as effects are added.
//!
//! A record: time, the measurement's path and SHA-256 (so a replaced file shows), the
//! effects compared (canonical effect-file text, its path and a one-line summary), the
//! options, and per-channel RMSE / NRMSE / fit plus the worst channel.
//!
//! Append-only and crash-safe: a record is one line written with a single `write` on a
//! file opened `O_APPEND`, so concurrent writers never interleave and a crash leaves at
//! most a torn last line. Readers skip a torn or unreadable line with a warning; a
//! writer that finds the file not ending in a newline starts its record on a new line,
//! so one torn record never swallows the next.

use std::fs::OpenOptions;
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use model_core::Effects;
use serde::{Deserialize, Serialize};

use crate::compare::CompareResult;
use crate::effects_file::{format_effects, parse_effects, summarize_effects};

/// File name suffix of a history, after the measurement's stem.
pub const SUFFIX: &str = ".simrod-history.jsonl";

/// Record format version (`"simrod_history"`); readers skip records of other versions.
pub const VERSION: u32 = 1;

/// The channels the history table and plot show by default: one or two per part of the
/// bench (motor speed, flange torques and speed, supply, SuT inverter), so any effect in
/// the library moves at least one of them.
pub const MAIN_CHANNELS: [&str; 8] =
    ["SuTMotorEnc", "C_Kistler_L", "C_Kistler_R", "T_Kistler_L", "I_DPU 2.7", "I_DC", "V_DC", "P_SuT_inv"];

/// A file the run used, identified by content.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileRef {
    /// As the user gave it.
    pub path: String,
    /// Absolute path, when it could be resolved.
    #[serde(default)]
    pub absolute: Option<String>,
    /// SHA-256 of the content (hex), when it could be read.
    #[serde(default)]
    pub sha256: Option<String>,
}

/// The effects a comparison ran with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectsRef {
    /// The effect file, if one was given.
    #[serde(default)]
    pub file: Option<FileRef>,
    /// Canonical effect-file text (`format_effects`): loads back to the same effects.
    pub toml: String,
    /// One line, e.g. `differential_friction(coulomb_nm=4, viscous_nm_s_per_rad=0)`.
    pub summary: String,
}

/// The options of the comparison that change the twin or the figures.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct OptionsRec {
    pub params: String,
    pub speed_target: String,
    pub coupling: String,
    pub supply_v: f32,
    pub inputs: String,
    pub window_s: f64,
    pub mapping: Option<String>,
    pub allow_gaps: bool,
    /// The model data directory (`--data-dir`); `None`: the built-in data.
    pub data_dir: Option<String>,
    /// [s] the speed-counting window the twin's speeds were averaged over
    /// (`--speed-window-s`); `None` in records written before it was recorded.
    #[serde(default)]
    pub speed_window_s: Option<f64>,
}

/// One channel's error figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelRec {
    pub name: String,
    #[serde(default)]
    pub unit: String,
    #[serde(default)]
    pub derived: bool,
    /// `None` when not finite.
    pub rmse: Option<f64>,
    pub nrmse: Option<f64>,
    #[serde(default)]
    pub fit_percent: Option<f64>,
}

/// One comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// [`VERSION`].
    pub simrod_history: u32,
    /// UTC, RFC 3339.
    pub timestamp: String,
    #[serde(default)]
    pub unix_ms: u64,
    pub measurement: FileRef,
    pub effects: EffectsRef,
    #[serde(default)]
    pub options: OptionsRec,
    pub channels: Vec<ChannelRec>,
    #[serde(default)]
    pub worst_channel: Option<String>,
}

impl Entry {
    /// The record of a comparison of `meas` with `effects` (from `effects_path`, if any).
    pub fn new(
        r: &CompareResult,
        meas: &Path,
        effects: &Effects,
        effects_path: Option<&Path>,
        options: OptionsRec,
    ) -> Self {
        let now = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
        let fin = |v: f64| v.is_finite().then_some(v);
        Self {
            simrod_history: VERSION,
            timestamp: utc_rfc3339(now.as_secs()),
            unix_ms: u64::try_from(now.as_millis()).unwrap_or(u64::MAX),
            measurement: file_ref(meas),
            effects: EffectsRef {
                file: effects_path.map(file_ref),
                toml: format_effects(effects).unwrap_or_default(),
                summary: summarize_effects(effects),
            },
            options,
            channels: r
                .channels
                .iter()
                .map(|c| ChannelRec {
                    name: c.name.clone(),
                    unit: c.unit.clone(),
                    derived: c.derived,
                    rmse: fin(c.metrics.rmse),
                    nrmse: fin(c.metrics.nrmse),
                    fit_percent: c.metrics.fit_percent.and_then(fin),
                })
                .collect(),
            worst_channel: r.worst_channel().map(|c| c.name.clone()),
        }
    }

    /// The effects this iteration compared, rebuilt from the recorded text.
    pub fn effects(&self) -> Option<Effects> {
        parse_effects(&self.effects.toml, "history record").ok()
    }

    /// A channel's NRMSE (0..1), if recorded and finite.
    pub fn nrmse(&self, channel: &str) -> Option<f64> {
        self.channels.iter().find(|c| c.name == channel).and_then(|c| c.nrmse)
    }

    /// A channel's RMSE, if recorded and finite.
    pub fn rmse(&self, channel: &str) -> Option<f64> {
        self.channels.iter().find(|c| c.name == channel).and_then(|c| c.rmse)
    }
}

/// Path, absolute path and content hash of a file (the parts that can be had).
pub fn file_ref(p: &Path) -> FileRef {
    FileRef {
        path: p.display().to_string(),
        absolute: std::fs::canonicalize(p).ok().map(|a| a.display().to_string()),
        sha256: std::fs::read(p).ok().map(|b| crate::sha256::hex_digest(&b)),
    }
}

/// The history file of a measurement: `dir/stem.simrod-history.jsonl`. A history file
/// given as the measurement is its own history.
pub fn path_for(meas: &Path) -> PathBuf {
    let name = meas.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    if name.ends_with(SUFFIX) {
        return meas.to_path_buf();
    }
    let stem = meas.file_stem().map_or_else(|| name.clone(), |s| s.to_string_lossy().into_owned());
    meas.with_file_name(format!("{stem}{SUFFIX}"))
}

/// Append one record as one line (see the module doc for why this is crash-safe).
/// Concurrent appends take turns ([`AppendLock`]): the check for a torn last record must
/// not read another process's record while it is being written.
pub fn append(path: &Path, e: &Entry) -> io::Result<()> {
    let json = serde_json::to_string(e).map_err(io::Error::other)?;
    let _turn = AppendLock::take(path)?;
    let mut f = OpenOptions::new().create(true).append(true).read(true).open(path)?;
    let mut line = String::with_capacity(json.len() + 2);
    if f.metadata()?.len() > 0 {
        let mut last = [0u8; 1];
        f.seek(SeekFrom::End(-1))?;
        f.read_exact(&mut last)?;
        if last[0] != b'\n' {
            line.push('\n'); // close a torn record so it stays one skipped line
        }
    }
    line.push_str(&json);
    line.push('\n');
    // One write of the whole record: with O_APPEND it lands at the end in one piece.
    let n = f.write(line.as_bytes())?;
    if n != line.len() {
        return Err(io::Error::new(
            io::ErrorKind::WriteZero,
            format!("short write ({n} of {} bytes)", line.len()),
        ));
    }
    f.sync_data()
}

/// `<history>.lock`, held while one process appends: created with `create_new` (atomic
/// on every local file system), removed on drop. A lock older than [`STALE_LOCK_S`] is
/// one a killed process left, and is taken over.
struct AppendLock(PathBuf);

/// [s] after which a lock is taken to be left behind (an append takes milliseconds).
const STALE_LOCK_S: u64 = 10;

impl AppendLock {
    fn take(history: &Path) -> io::Result<Self> {
        let mut name = history.as_os_str().to_owned();
        name.push(".lock");
        let lock = PathBuf::from(name);
        let start = std::time::Instant::now();
        loop {
            match OpenOptions::new().write(true).create_new(true).open(&lock) {
                Ok(_) => return Ok(Self(lock)),
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {
                    let age = std::fs::metadata(&lock)
                        .and_then(|m| m.modified())
                        .ok()
                        .and_then(|t| t.elapsed().ok());
                    if age.is_some_and(|a| a.as_secs() >= STALE_LOCK_S) {
                        let _ = std::fs::remove_file(&lock);
                    } else if start.elapsed().as_secs() >= 3 * STALE_LOCK_S {
                        return Err(io::Error::other(format!(
                            "{} is held by another simrod",
                            lock.display()
                        )));
                    }
                    std::thread::sleep(std::time::Duration::from_millis(5));
                }
                Err(e) => return Err(e),
            }
        }
    }
}

impl Drop for AppendLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// A history as read: the records in order, and what was skipped.
#[derive(Debug, Clone, Default)]
pub struct History {
    pub path: PathBuf,
    pub entries: Vec<Entry>,
    /// One message per skipped line.
    pub warnings: Vec<String>,
}

/// Read a history; a missing file is an empty history.
pub fn read(path: &Path) -> io::Result<History> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(e),
    };
    Ok(parse(path, &bytes))
}

/// Parse history bytes (see [`read`]).
pub fn parse(path: &Path, bytes: &[u8]) -> History {
    let mut h = History { path: path.to_path_buf(), ..History::default() };
    let complete = bytes.last().is_none_or(|b| *b == b'\n');
    let lines: Vec<&[u8]> = bytes.split(|b| *b == b'\n').collect();
    // `split` yields an empty piece after a final newline.
    let count = if complete { lines.len().saturating_sub(1) } else { lines.len() };
    for (i, raw) in lines.iter().take(count).enumerate() {
        let text = String::from_utf8_lossy(raw);
        if text.trim().is_empty() {
            continue;
        }
        let torn = !complete && i + 1 == count;
        match serde_json::from_str::<Entry>(&text) {
            Ok(e) if e.simrod_history == VERSION => h.entries.push(e),
            Ok(e) => h.warnings.push(format!(
                "{}:{}: record version {} is not {VERSION}; skipped",
                path.display(),
                i + 1,
                e.simrod_history
            )),
            Err(_) if torn => h.warnings.push(format!(
                "{}:{}: incomplete last line (an interrupted write); skipped",
                path.display(),
                i + 1
            )),
            Err(err) => h.warnings.push(format!(
                "{}:{}: not a history record ({err}); skipped",
                path.display(),
                i + 1
            )),
        }
    }
    h
}

/// `YYYY-MM-DDThh:mm:ssZ` for a Unix time (civil-from-days, proleptic Gregorian).
pub fn utc_rfc3339(unix_s: u64) -> String {
    let days = (unix_s / 86_400) as i64;
    let rem = unix_s % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem / 60 % 60, rem % 60)
}

/// The channels to tabulate: the main ones that some record has (all recorded ones with
/// `all`), in record order.
pub fn shown_channels(entries: &[Entry], all: bool) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for e in entries {
        for c in &e.channels {
            if (all || MAIN_CHANNELS.contains(&c.name.as_str())) && !names.contains(&c.name) {
                names.push(c.name.clone());
            }
        }
    }
    if !all {
        names.sort_by_key(|n| MAIN_CHANNELS.iter().position(|m| m == n));
    }
    names
}

/// Notes on a history worth telling: records of different measurement contents.
pub fn notes(h: &History) -> Vec<String> {
    let mut out = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for e in &h.entries {
        if let Some(s) = e.measurement.sha256.as_deref() {
            if !seen.contains(&s) {
                seen.push(s);
            }
        }
    }
    if seen.len() > 1 {
        let per: Vec<String> = h
            .entries
            .iter()
            .enumerate()
            .map(|(i, e)| {
                // Hand-edited records may hold anything: take characters, not bytes.
                let short: String = e.measurement.sha256.as_deref().unwrap_or("?").chars().take(8).collect();
                format!("{}: {short}", i + 1)
            })
            .collect();
        out.push(format!(
            "the measurement's content changed between iterations (sha256 prefixes {}): their errors are not comparable",
            per.join(", ")
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(n: u32, effects: &str, nrmse: f64) -> Entry {
        Entry {
            simrod_history: VERSION,
            timestamp: utc_rfc3339(1_700_000_000 + u64::from(n)),
            unix_ms: 0,
            measurement: FileRef { path: "m.csv".into(), absolute: None, sha256: Some("ab".repeat(32)) },
            effects: EffectsRef { file: None, toml: effects.into(), summary: format!("it {n}") },
            options: OptionsRec::default(),
            channels: vec![ChannelRec {
                name: "I_DC".into(),
                unit: "A".into(),
                derived: false,
                rmse: Some(nrmse * 10.0),
                nrmse: Some(nrmse),
                fit_percent: None,
            }],
            worst_channel: Some("I_DC".into()),
        }
    }

    #[test]
    fn dates_are_utc_civil() {
        assert_eq!(utc_rfc3339(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc_rfc3339(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc_rfc3339(1_700_000_000), "2023-11-14T22:13:20Z");
        assert_eq!(utc_rfc3339(4_107_542_399), "2100-02-28T23:59:59Z");
    }

    #[test]
    fn history_path_sits_next_to_the_measurement() {
        assert_eq!(path_for(Path::new("runs/m.csv")), Path::new("runs/m.simrod-history.jsonl"));
        assert_eq!(path_for(Path::new("m.mat")), Path::new("m.simrod-history.jsonl"));
        let h = Path::new("runs/m.simrod-history.jsonl");
        assert_eq!(path_for(h), h);
    }

    #[test]
    fn appends_one_line_per_record_and_reads_them_in_order() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("m.simrod-history.jsonl");
        assert!(read(&p).unwrap().entries.is_empty());
        for n in 0..3 {
            append(&p, &entry(n, "", 0.1 / f64::from(n + 1))).unwrap();
        }
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(text.lines().count(), 3);
        assert!(text.ends_with('\n'));
        let h = read(&p).unwrap();
        assert!(h.warnings.is_empty(), "{:?}", h.warnings);
        let got: Vec<&str> = h.entries.iter().map(|e| e.effects.summary.as_str()).collect();
        assert_eq!(got, ["it 0", "it 1", "it 2"]);
        assert_eq!(h.entries[1], entry(1, "", 0.05));
    }

    #[test]
    fn a_torn_last_line_is_skipped_and_does_not_swallow_the_next_record() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("h.simrod-history.jsonl");
        append(&p, &entry(0, "", 0.1)).unwrap();
        // A crash halfway through the second record.
        let full = serde_json::to_string(&entry(1, "", 0.2)).unwrap();
        let mut f = OpenOptions::new().append(true).open(&p).unwrap();
        f.write_all(&full.as_bytes()[..full.len() / 2]).unwrap();
        drop(f);
        let h = read(&p).unwrap();
        assert_eq!(h.entries.len(), 1);
        assert_eq!(h.warnings.len(), 1);
        assert!(h.warnings[0].contains(":2: incomplete last line"), "{}", h.warnings[0]);

        append(&p, &entry(2, "", 0.3)).unwrap();
        let h = read(&p).unwrap();
        let got: Vec<&str> = h.entries.iter().map(|e| e.effects.summary.as_str()).collect();
        assert_eq!(got, ["it 0", "it 2"]);
        assert_eq!(h.warnings.len(), 1);
        assert!(h.warnings[0].contains(":2: not a history record"), "{}", h.warnings[0]);
    }

    #[test]
    fn garbage_and_other_versions_are_skipped_with_warnings() {
        let mut other = serde_json::to_value(entry(9, "", 0.1)).unwrap();
        other["simrod_history"] = serde_json::json!(99);
        let text = format!(
            "{}\n\nnot json\n{}\n{}\n",
            serde_json::to_string(&entry(0, "", 0.1)).unwrap(),
            other,
            serde_json::to_string(&entry(1, "", 0.1)).unwrap()
        );
        let h = parse(Path::new("h"), text.as_bytes());
        assert_eq!(h.entries.len(), 2);
        assert_eq!(h.warnings.len(), 2, "{:?}", h.warnings);
        assert!(h.warnings[0].starts_with("h:3: not a history record"));
        assert!(h.warnings[1].starts_with("h:4: record version 99"));
    }

    #[test]
    fn changed_measurement_content_is_noted_even_for_odd_hashes() {
        let mut h = History::default();
        assert!(notes(&h).is_empty());
        h.entries.push(entry(0, "", 0.1));
        h.entries.push(entry(1, "", 0.1));
        assert!(notes(&h).is_empty());
        h.entries[1].measurement.sha256 = Some("ééééééééé".into());
        let n = notes(&h);
        assert_eq!(n.len(), 1);
        assert!(n[0].contains("1: abababab, 2: éééééééé"), "{}", n[0]);
    }

    #[test]
    fn recorded_effects_load_back() {
        let mut fx = Effects::NONE;
        fx.differential_friction.coulomb_nm = 3.977;
        let e = entry(0, &format_effects(&fx).unwrap(), 0.1);
        assert_eq!(e.effects(), Some(fx));
        assert_eq!(entry(0, "", 0.1).effects(), Some(Effects::NONE));
    }
}
