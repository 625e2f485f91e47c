//! `simrod xil`: the XiL loop closed offline. The bench twin and the vehicle-and-road
//! twin (`simrod-xdt`) run together through the RT platform's delay and sample time, on
//! a built-in drive cycle; every channel plus the vehicle's speed and the cycle's target
//! go to a CSV, and the run is summarised: cycle tracking, energy per km, peak flange
//! torque, the loop's stability, and with `--margin` its delay margin.
//!
//! Everything the user gives is checked before the run (exit code 2); I/O and a
//! diverging run are runtime errors (exit code 1), and then no output is written.

use std::fmt::Write as _;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use clap::Args;
use model_core::{Channel, Config, Maps};
use simrod_check::limits::Limits;
use simrod_io::budget::BudgetArgs;
use simrod_xdt::margin::{delay_margin, Criterion, Envelope, Found, Margin, Outcome};
use simrod_xdt::vehicle::{Vehicle, KEYS};
use simrod_xdt::{Cycle, LoopParams, Timing, XilLoop, XilOutputs};

use crate::atomic::write_atomic;
use crate::error::{CmdError, FileError};
use crate::sim_csv::{header_with, RowWriter};
use crate::simulate::{check_out_path, check_run_size, ModelArgs};
use crate::twin::args::file_error;

/// The twin's step in XiL runs [µs]: the bench's 1 kHz; loop times are whole steps.
pub const XIL_DT_US: u32 = 1000;

/// Columns after the twin's channels, `(name, unit)`, in the order of [`extra_values`].
pub const EXTRA_COLUMNS: [(&str, &str); 8] = [
    ("v_vehicle", "km/h"),
    ("v_target", "km/h"),
    ("v_cycle", "km/h"),
    ("distance", "m"),
    ("grade", "%"),
    ("road_torque", "N m"),
    ("load_torque_sp_L", "N m"),
    ("load_torque_sp_R", "N m"),
];

/// Bytes a CSV row takes: the simulate row and the extra columns.
const XIL_ROW_BYTES: f64 = crate::simulate::SIMULATE_ROW_BYTES + 80.0;

/// The closed loop's vehicle and timing, shared by `simrod xil` and `simrod check
/// --cycle` (each only with a cycle).
#[derive(Debug, Clone, Args)]
pub struct LoopArgs {
    /// Vehicle file, the format of xdt/data/vehicle.toml (`name = number  # comment`);
    /// keys not given keep the built-in Kyburz DXP's values.
    #[arg(long, value_name = "FILE.toml", requires = "cycle")]
    pub vehicle: Option<PathBuf>,

    /// The RT platform's loop delay [ms]: set points computed from a sample reach the
    /// bench this much later. Whole twin steps, at most 250 of them (250 ms at `xil`'s
    /// 1 ms, 25 ms at `check`'s 100 µs).
    #[arg(long, value_name = "D", default_value_t = LoopParams::default().loop_delay_ms, allow_negative_numbers = true, requires = "cycle")]
    pub loop_delay_ms: f32,

    /// The xDT's sample time [ms], whole ms >= 1 (set points held between samples).
    #[arg(long, value_name = "T", default_value_t = LoopParams::default().loop_dt_ms, allow_negative_numbers = true, requires = "cycle")]
    pub loop_dt_ms: f32,
}

/// Arguments of `simrod xil`.
#[derive(Debug, Clone, Args)]
pub struct XilArgs {
    /// Drive cycle: ece15 (UN ECE R83 urban cycle), delivery (10 stops at 25 km/h),
    /// hill (15 km/h over 8 % up and -6 % down). Targets are capped at the vehicle's
    /// top speed and at what the bench reaches (its 2100 rpm at 24 V).
    #[arg(long, value_name = "NAME", value_parser = parse_cycle)]
    pub cycle: Cycle,

    #[command(flatten)]
    pub looping: LoopArgs,

    #[command(flatten)]
    pub model: ModelArgs,

    /// Limits file for the report's table of `check` margins (default: the built-in
    /// workbench/data/limits.toml).
    #[arg(long, value_name = "FILE.toml")]
    pub limits: Option<PathBuf>,

    /// Output CSV: every channel, then the vehicle's speed, the target, the cycle's own
    /// target, distance, grade, road torque and the load torques asked; replaced
    /// atomically.
    #[arg(long, short = 'o', value_name = "FILE.csv")]
    pub out: Option<PathBuf>,

    /// Also find the loop's delay margin on this cycle (a bisection: about ten runs).
    #[arg(long)]
    pub margin: bool,

    #[command(flatten)]
    pub budget: BudgetArgs,
}

/// `--cycle` value.
pub fn parse_cycle(s: &str) -> Result<Cycle, String> {
    Cycle::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Cycle::ALL.iter().map(|c| c.name()).collect();
        format!("unknown cycle; known: {}", names.join(", "))
    })
}

/// Read a vehicle file: `name = number` lines with the keys of `vehicle.toml`; what it
/// does not set keeps the built-in value. Errors name the file and line.
pub fn load_vehicle(path: &Path) -> Result<Vehicle, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::io(path, &e))?;
    parse_vehicle(path, &text)
}

/// [`load_vehicle`] on text already read.
pub fn parse_vehicle(path: &Path, text: &str) -> Result<Vehicle, FileError> {
    let known = |k: &str| KEYS.contains(&k);
    let lines = model_data::parse_params(text, &known).map_err(|e| match e.line {
        0 => FileError::whole(path, e.msg),
        n => FileError::at(path, n, 1, format!("{} (vehicle keys: {})", e.msg, KEYS.join(", "))),
    })?;
    let mut v = Vehicle::default();
    for l in lines {
        if let model_data::ParamLine::Entry { key, value, .. } = l {
            // Known keys only got through the parser.
            let _ = v.set(&key, value);
        }
    }
    v.validate().map_err(|(key, why)| {
        let line = text.lines().position(|l| l.split('=').next().is_some_and(|k| k.trim() == key));
        let msg = format!("{key} = {}: expected {why}", v.get(key).unwrap_or(f32::NAN));
        match line {
            Some(i) => FileError::at(path, i + 1, 1, msg),
            None => FileError::whole(path, msg),
        }
    })?;
    Ok(v)
}

/// The extra columns' values of one step.
fn extra_values(o: &XilOutputs) -> [f32; 8] {
    let x = &o.xdt;
    [
        x.v_mps * 3.6,
        x.target_mps * 3.6,
        x.cycle_mps * 3.6,
        x.distance_m,
        x.slope.pct,
        x.road_torque_nm,
        x.load_torque_nm[0],
        x.load_torque_nm[1],
    ]
}

/// A validated closed loop: cycle, vehicle, timing and twin (at `config.dt_us`).
#[derive(Debug, Clone)]
pub struct XilSpec {
    pub cycle: Cycle,
    pub config: Config,
    pub vehicle: Vehicle,
    pub timing: Timing,
    /// [ms] the loop's sample time and delay as given.
    pub loop_dt_ms: f32,
    pub loop_delay_ms: f32,
    pub supply_v: f32,
    pub data: Option<std::sync::Arc<crate::datadir::ModelData>>,
    pub title: String,
}

impl XilSpec {
    /// The loop `l` describes on `cycle`, with the twin of `model_args` stepped at
    /// `dt_us` (loop times must be whole steps of it). Every value checked, the loop
    /// built once.
    pub fn new(cycle: Cycle, l: &LoopArgs, model_args: &ModelArgs, dt_us: u32) -> Result<Self, CmdError> {
        let timing = Timing::from_ms(l.loop_dt_ms, l.loop_delay_ms, dt_us).map_err(|m| {
            CmdError::Usage(format!(
                "--loop-dt-ms {} --loop-delay-ms {} at a {dt_us} µs twin step: {m}",
                l.loop_dt_ms, l.loop_delay_ms
            ))
        })?;
        let vehicle = match &l.vehicle {
            Some(p) => load_vehicle(p).map_err(|e| file_error("--vehicle", e))?,
            None => Vehicle::default(),
        };
        let model = model_args.load()?;
        if let Some(path) = &model_args.effects {
            crate::simulate::check_delay(&model.effects, dt_us)
                .map_err(|m| CmdError::Usage(format!("{}: {m}", path.display())))?;
        }
        let title = format!(
            "xil {}: {} | vehicle {} ({} kg) | loop dt {} ms, delay {} ms | supply {} V | {}",
            cycle.name(),
            cycle.description(),
            l.vehicle.as_deref().map_or("built-in DXP".into(), |p| p.display().to_string()),
            vehicle.mass_kg,
            l.loop_dt_ms,
            l.loop_delay_ms,
            model.supply_v,
            model_args.describe()
        );
        let spec = XilSpec {
            cycle,
            config: model.config(dt_us, model.effects),
            vehicle,
            timing,
            loop_dt_ms: l.loop_dt_ms,
            loop_delay_ms: l.loop_delay_ms,
            supply_v: model.supply_v,
            data: model.data.clone(),
            title,
        };
        spec.run(spec.maps()?, &spec.config)?; // the checks, before any output
        Ok(spec)
    }

    /// The twin's maps (`--data-dir`'s, or the built-in ones).
    pub fn maps(&self) -> Result<Maps<'_>, CmdError> {
        match &self.data {
            None => Ok(Maps::builtin()),
            Some(d) => d.maps().map_err(|e| CmdError::Usage(format!("--data-dir: {e}"))),
        }
    }

    /// The loop on `maps` with the twin's configuration `config` (the spec's, or a
    /// Monte Carlo sample's).
    pub fn run<'a>(&self, maps: Maps<'a>, config: &Config) -> Result<XilLoop<'a>, CmdError> {
        let tuning = LoopParams::default().tuning;
        XilLoop::new(config, maps, &self.vehicle, &tuning, self.cycle.route(), self.timing, self.supply_v)
            .map_err(|e| CmdError::Usage(format!("the XiL loop cannot be built: {e:?}")))
    }

    /// The loop's delay margin on its cycle, found at the bench's 1 ms twin step
    /// ([`XIL_DT_US`], as `simrod xil --margin`; the delay line holds 250 ms there)
    /// whatever the spec's step: `(margin, [ms] per twin step of the search)`.
    pub fn margin(&self) -> Result<(Margin, f64), CmdError> {
        let period = Timing::from_ms(self.loop_dt_ms, 0.0, XIL_DT_US)
            .map_err(|m| CmdError::Usage(format!("--loop-dt-ms {}: {m}", self.loop_dt_ms)))?
            .period;
        let config = Config { dt_us: XIL_DT_US, ..self.config };
        let m = delay_margin(
            &config,
            self.maps()?,
            &self.vehicle,
            &LoopParams::default().tuning,
            self.cycle.route(),
            period,
            self.supply_v,
            Criterion::default(),
        )
        .map_err(|e| CmdError::Usage(format!("the XiL loop cannot be built: {e:?}")))?;
        Ok((m, f64::from(XIL_DT_US) * 1e-3))
    }
}

impl LoopArgs {
    /// The input files the arguments name.
    pub fn inputs(&self, model: &ModelArgs) -> simrod_io::guard::Inputs {
        model.inputs().file("--vehicle", self.vehicle.as_deref())
    }
}

impl XilArgs {
    /// The input files the arguments name.
    pub fn inputs(&self) -> simrod_io::guard::Inputs {
        self.looping.inputs(&self.model).file("--limits", self.limits.as_deref())
    }
}

/// What a run gave, for the report.
#[derive(Debug, Clone, Default)]
pub struct XilReport {
    pub steps: u64,
    pub duration_s: f64,
    /// [km/h] RMS and largest |target - vehicle speed| (target capped as driven).
    pub track_rms_kmh: f64,
    pub track_max_kmh: f64,
    /// [km/h] the same against the cycle's own target.
    pub cycle_rms_kmh: f64,
    /// [km/h] the cap and the cycle's peak; share of the time the cycle is above the cap.
    pub cap_kmh: f64,
    pub cycle_peak_kmh: f64,
    pub capped_share: f64,
    pub distance_m: f64,
    /// [Wh/km] from P_DPU (the supply) and P_SuT_inv (what the vehicle's battery gives).
    pub supply_wh_per_km: f64,
    pub sut_wh_per_km: f64,
    /// [N m] peak |flange torque|, its channel and time [s].
    pub peak_flange_nm: f32,
    pub peak_channel: Option<Channel>,
    pub peak_at_s: f64,
    /// Steps with a load torque beyond the load map (clipped).
    pub clipped_steps: u64,
    /// [N m] largest oscillation envelope; the instability found, if any.
    pub max_envelope_nm: f32,
    pub unstable: Option<(f64, String)>,
}

/// Run the loop to the end of its cycle, writing rows to `out` if given.
pub fn run(lp: XilLoop<'_>, mut out: Option<&mut dyn Write>) -> io::Result<XilReport> {
    let cap = f64::from(lp.xdt().cap_mps()) * 3.6;
    let mut env = Envelope::new(Criterion::default(), f64::from(lp.model().dt_us()) * 1e-6);
    let mut r = XilReport { cap_kmh: cap, ..XilReport::default() };
    let (mut sq, mut sq_cycle, mut e_dpu, mut e_sut, mut above) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0u64);
    let dt = f64::from(lp.model().dt_us()) * 1e-6;
    let mut rows = RowWriter::new();
    if let Some(w) = out.as_mut() {
        w.write_all(header_with(&EXTRA_COLUMNS).as_bytes())?;
    }
    for (k, o) in lp.enumerate() {
        if let Some(c) = o.bench.non_finite() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "the loop diverged at step {} (t = {:.3} s): {} is {}",
                    k + 1,
                    o.bench.t_s(),
                    c.name(),
                    o.bench.get(c)
                ),
            ));
        }
        let (v, target, cycle) = (
            f64::from(o.xdt.v_mps) * 3.6,
            f64::from(o.xdt.target_mps) * 3.6,
            f64::from(o.xdt.cycle_mps) * 3.6,
        );
        sq += (target - v) * (target - v);
        sq_cycle += (cycle - v) * (cycle - v);
        r.track_max_kmh = r.track_max_kmh.max((target - v).abs());
        r.cycle_peak_kmh = r.cycle_peak_kmh.max(cycle);
        above += u64::from(cycle > target);
        e_dpu += f64::from(o.bench.get(Channel::PDpu)) * dt;
        e_sut += f64::from(o.bench.get(Channel::PSutInv)) * dt;
        for ch in [Channel::CKistlerL, Channel::CKistlerR] {
            let m = o.bench.get(ch).abs();
            if m > r.peak_flange_nm {
                (r.peak_flange_nm, r.peak_channel, r.peak_at_s) = (m, Some(ch), o.bench.t_s());
            }
        }
        r.clipped_steps += u64::from(o.xdt.clipped.iter().any(|c| *c));
        let found = env.push([o.bench.get(Channel::CKistlerL), o.bench.get(Channel::CKistlerR)]);
        if let (None, Some(f)) = (&r.unstable, found) {
            let what = match f {
                Found::Growing(g) => {
                    format!("growing oscillation of the flange torque ({g:.0}x over its rise)")
                }
                Found::Sustained(e) => {
                    format!("sustained oscillation of the flange torque (envelope {e:.1} N m)")
                }
            };
            r.unstable = Some((o.bench.t_s(), what));
        }
        r.distance_m = f64::from(o.xdt.distance_m);
        r.steps += 1;
        r.duration_s = o.bench.t_s();
        if let Some(w) = out.as_mut() {
            rows.write_row_with(*w, &o.bench, &extra_values(&o))?;
        }
    }
    let n = r.steps.max(1) as f64;
    r.track_rms_kmh = (sq / n).sqrt();
    r.cycle_rms_kmh = (sq_cycle / n).sqrt();
    r.capped_share = above as f64 / n;
    r.max_envelope_nm = env.max_envelope_nm();
    let km = (r.distance_m / 1000.0).max(1e-9);
    r.supply_wh_per_km = e_dpu / 3600.0 / km;
    r.sut_wh_per_km = e_sut / 3600.0 / km;
    Ok(r)
}

impl XilReport {
    /// The summary `simrod xil` prints.
    pub fn render(&self, title: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{title}");
        let _ =
            writeln!(s, "  {} steps, {:.1} s, {:.1} m driven", self.steps, self.duration_s, self.distance_m);
        let _ = writeln!(
            s,
            "  target cap {:.2} km/h (the vehicle's top speed and the bench's reach); the cycle (peak {:.1} km/h) \
             is above it {:.1} % of the time",
            self.cap_kmh,
            self.cycle_peak_kmh,
            100.0 * self.capped_share
        );
        let _ = writeln!(
            s,
            "  cycle tracking: RMS {:.2} km/h, max {:.2} km/h (of the capped target; {:.2} km/h RMS of the cycle's own)",
            self.track_rms_kmh, self.track_max_kmh, self.cycle_rms_kmh
        );
        let _ = writeln!(
            s,
            "  energy: {:.1} Wh/km from the supply (P_DPU: SuT and load motors), {:.1} Wh/km into the SuT inverter \
             (P_SuT_inv: the vehicle's battery)",
            self.supply_wh_per_km, self.sut_wh_per_km
        );
        let _ = writeln!(
            s,
            "  peak flange torque {:.1} N m ({} at {:.3} s); rating 200 N m (Kistler 4550A200)",
            self.peak_flange_nm,
            self.peak_channel.map_or("-", Channel::name),
            self.peak_at_s
        );
        let _ = writeln!(
            s,
            "  road load beyond the load motors' map (clipped) in {} of {} steps",
            self.clipped_steps, self.steps
        );
        match &self.unstable {
            None => {
                let _ = writeln!(
                    s,
                    "  stability: stable (largest oscillation envelope of the flange torques {:.2} N m)",
                    self.max_envelope_nm
                );
            }
            Some((t, what)) => {
                let _ = writeln!(s, "  stability: UNSTABLE from {t:.1} s: {what}");
            }
        }
        s
    }
}

/// What a run judged by the instability criterion did, in words.
pub fn outcome_text(o: &Outcome) -> String {
    match o {
        Outcome::Stable => "stable".into(),
        Outcome::Growing { at_s, growth } => format!("growing oscillation at {at_s:.1} s ({growth:.0}x)"),
        Outcome::Sustained { at_s, envelope_nm } => {
            format!("sustained oscillation at {at_s:.1} s (envelope {envelope_nm:.1} N m)")
        }
        Outcome::OverRating { at_s, torque_nm } => {
            format!("flange rating reached at {at_s:.1} s ({torque_nm:.1} N m)")
        }
        Outcome::NonFinite { at_s } => format!("diverged at {at_s:.1} s"),
    }
}

/// `simrod xil`.
pub fn execute(args: &XilArgs) -> Result<(), CmdError> {
    if let Some(out) = &args.out {
        args.inputs().check("--out", out).map_err(CmdError::Usage)?;
        check_out_path(out)?;
    }
    let spec = XilSpec::new(args.cycle, &args.looping, &args.model, XIL_DT_US)?;
    let limits = match &args.limits {
        Some(p) => Limits::load(p).map_err(|e| file_error("--limits", e))?,
        None => Limits::builtin()?,
    };
    let maps = spec.maps()?;
    let lp = spec.run(maps, &spec.config)?;
    if let Some(out) = &args.out {
        check_run_size(out, lp.total_steps() as f64, XIL_DT_US, &args.budget, XIL_ROW_BYTES, 0.0)?;
    }
    let runtime = |e: io::Error, what: &str| match e.kind() {
        io::ErrorKind::InvalidData => CmdError::Runtime(e.to_string()),
        _ => CmdError::Runtime(format!("cannot write {what}: {e}")),
    };
    let report = match &args.out {
        Some(out) => {
            let mut report = None;
            write_atomic(out, |w| {
                report = Some(run(lp, Some(w))?);
                Ok(())
            })
            .map_err(|e| runtime(e, &out.display().to_string()))?;
            report.ok_or_else(|| CmdError::Runtime("the run produced no report".into()))?
        }
        None => run(lp, None).map_err(|e| runtime(e, "the run"))?,
    };
    let mut text = report.render(&spec.title);
    text.push_str(&crate::xil_run::limits_table(&args.cycle, &args.looping, &args.model, &limits)?);
    if args.margin {
        let (m, step_ms) = spec.margin()?;
        let ms = |steps: u32| f64::from(steps) * step_ms;
        let line = match (m.stable_steps, m.unstable) {
            (None, _) => "  delay margin: none, the loop is unstable without delay".to_string(),
            (Some(d), None) => format!("  delay margin: at least {} ms (the delay line's end)", ms(d)),
            (Some(d), Some((u, v))) => format!(
                "  delay margin: {} ms ({:.1}x the loop delay); at {} ms: {} ({} runs, criterion: see simrod_xdt::margin)",
                ms(d),
                ms(d) / f64::from(spec.loop_delay_ms).max(1e-9),
                ms(u),
                outcome_text(&v.outcome),
                m.runs
            ),
        };
        text.push_str(&line);
        text.push('\n');
    }
    if let Some(out) = &args.out {
        let _ = writeln!(text, "wrote {}", out.display());
    }
    let mut stdout = io::stdout().lock();
    match stdout.write_all(text.as_bytes()).and_then(|()| stdout.flush()) {
        Err(e) if e.kind() != io::ErrorKind::BrokenPipe => {
            Err(CmdError::Runtime(format!("cannot write to stdout: {e}")))
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vehicle_file_errors_name_the_line() {
        let p = Path::new("v.toml");
        let v = parse_vehicle(p, "# a heavier round\nmass_kg = 600 # [kg]\n").unwrap();
        assert_eq!(v.mass_kg, 600.0);
        assert_eq!(v.wheel_radius_m, Vehicle::default().wheel_radius_m);
        let e = parse_vehicle(p, "mass_kg = 600\nmass = 3\n").unwrap_err();
        assert_eq!((e.line, e.message.contains("unknown parameter `mass`")), (Some(2), true), "{e}");
        let e = parse_vehicle(p, "\nwheel_radius_m = -0.2\n").unwrap_err();
        assert_eq!(e.line, Some(2), "{e}");
        assert!(e.message.contains("wheel_radius_m = -0.2: expected a finite number > 0"), "{e}");
        let e = parse_vehicle(p, "mass_kg = x\n").unwrap_err();
        assert_eq!(e.line, Some(1), "{e}");
        assert!(parse_cycle("ECE15").is_ok());
        assert!(parse_cycle("udds").unwrap_err().contains("ece15, delivery, hill"));
    }

    #[test]
    fn report_of_a_run_with_its_csv() {
        let timing = Timing::new(1, 2).unwrap();
        let lp = XilLoop::builtin(&Config::default(), Cycle::Ece15, timing, 24.0).unwrap();
        let mut buf = Vec::new();
        let r = run(lp, Some(&mut buf)).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let mut lines = text.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(head.len(), 1 + model_core::N_CHANNELS + EXTRA_COLUMNS.len());
        assert_eq!(head.last(), Some(&"load_torque_sp_R [N m]"));
        assert_eq!(lines.count() as u64, r.steps);
        assert_eq!(r.steps, 195_000);
        assert!(r.track_rms_kmh < 1.0 && r.unstable.is_none(), "{r:?}");
        assert!(r.peak_flange_nm > 50.0 && r.peak_flange_nm < 200.0, "{r:?}");
        assert!(r.sut_wh_per_km > 20.0 && r.sut_wh_per_km < 150.0, "{r:?}");
        assert!(r.capped_share > 0.3, "{r:?}");
    }
}
