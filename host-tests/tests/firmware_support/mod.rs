//! Shared by the firmware tests: prerequisites, building the firmware, running it on
//! QEMU, reading its trace, and the host simulation it must match.
//!
//! The firmware is built by a nested `cargo build` into its own target directory,
//! `target/firmware-tests/build`: the `cargo test` that runs us holds the lock of the
//! workspace's build directory until the tests end, so building into that one would
//! wait forever. Variants (effects compiled in or not) share that directory, so their
//! dependencies are built once; each build's ELFs are copied to
//! `target/firmware-tests/<variant>/` under a lock before the next build can replace
//! them. (A mix-up across concurrent test processes would still be caught: the traces
//! carry the effects they were built with, and the tests check them.)

#![allow(dead_code)] // each test binary uses a part

use std::fs;
use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use model_core::Real as _;
use model_core::{
    Builtin, Config, CouplingStiffness, Effects, Outputs, Params, Profile, RateSet, Simulation, SpeedTarget,
};

#[path = "../../../firmware/src/protocol.rs"]
pub mod protocol;

/// The rate sets traced, in the firmware's order.
pub const RATES: [RateSet; 2] = [RateSet::Programmed, RateSet::Identified];

#[allow(unused_imports)] // each test binary uses a part
pub use host_tests::rt::{firmware_target_dir, root, Mcu, M3_FIXED, M3_SOFT, M4F, STEP_US, SUPPLY_V, TARGET};

/// The binaries of the firmware crate.
#[allow(unused_imports)] // each test binary uses a part
pub use host_tests::rt::BINARIES;

/// Serializes build + copy within this test process.
static BUILD: Mutex<()> = Mutex::new(());

/// Fail, not skip, when a tool the proof needs is missing: a skipped proof looks green.
pub fn require_tools() {
    require_tools_on(&M4F);
}

/// [`require_tools`] for the target of `mcu`.
pub fn require_tools_on(mcu: &Mcu) {
    let target = mcu.target;
    let sysroot = Command::new("rustc")
        .args(["--print", "sysroot"])
        .current_dir(root())
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let target_lib = Path::new(&sysroot).join("lib/rustlib").join(target);
    assert!(
        target_lib.is_dir(),
        "the Rust target {target} is not installed (no {}).\n\
         Install it with: rustup target add {target}",
        target_lib.display()
    );
    match Command::new("qemu-system-arm").arg("--version").stdout(Stdio::null()).status() {
        Ok(s) if s.success() => {}
        Ok(s) => panic!("qemu-system-arm --version failed ({s})"),
        Err(e) => panic!(
            "qemu-system-arm not found ({e}).\n\
             Install it with: apt-get install -y qemu-system-arm"
        ),
    }
}

/// Build the firmware binaries (release) with the effects file `effects` compiled in
/// (or none); the directory `target/firmware-tests/<variant>` holding their ELFs.
pub fn build_firmware(variant: &str, effects: Option<&Path>) -> PathBuf {
    build_firmware_on(&M4F, variant, effects)
}

/// [`build_firmware`] for the core `mcu`.
pub fn build_firmware_on(mcu: &Mcu, variant: &str, effects: Option<&Path>) -> PathBuf {
    require_tools_on(mcu);
    let _guard = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let t0 = Instant::now();
    let dir = host_tests::rt::build_firmware_on(mcu, variant, effects, &[]).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("firmware ({variant}) built in {:.1} s", t0.elapsed().as_secs_f64());
    dir
}

/// What a QEMU run left.
pub struct QemuRun {
    pub stdout: Vec<u8>,
    pub stderr: Vec<u8>,
    pub wall: Duration,
}

/// A running QEMU.
pub struct Qemu {
    child: std::process::Child,
    out: std::thread::JoinHandle<Vec<u8>>,
    err: std::thread::JoinHandle<Vec<u8>>,
    t0: Instant,
    elf: PathBuf,
}

/// Boot `elf` on QEMU's mps2-an386 in `cwd` (semihosting files land there), with
/// `extra` QEMU arguments and `args` on the semihosting command line. Without a
/// `-serial` in `extra`, the UART is not connected.
pub fn spawn_qemu(elf: &Path, cwd: &Path, extra: &[&str], args: &[&str]) -> Qemu {
    spawn_qemu_on(&M4F, elf, cwd, extra, args)
}

/// [`spawn_qemu`] on the board of `mcu`.
pub fn spawn_qemu_on(mcu: &Mcu, elf: &Path, cwd: &Path, extra: &[&str], args: &[&str]) -> Qemu {
    fs::create_dir_all(cwd).expect("create the run directory");
    let mut semi = String::from("enable=on,target=native,arg=firmware");
    for a in args {
        semi.push_str(",arg=");
        semi.push_str(a);
    }
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(["-machine", mcu.machine, "-cpu", mcu.cpu])
        .args(["-display", "none", "-monitor", "none"])
        .args(["-semihosting-config", &semi]);
    if !extra.contains(&"-serial") {
        cmd.args(["-serial", "null"]);
    }
    cmd.args(extra)
        .arg("-kernel")
        .arg(elf)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().expect("start qemu-system-arm");
    // Drain the pipes on threads so a chatty firmware cannot block on a full pipe.
    let mut so = child.stdout.take().expect("piped");
    let mut se = child.stderr.take().expect("piped");
    let out = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = so.read_to_end(&mut v);
        v
    });
    let err = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = se.read_to_end(&mut v);
        v
    });
    Qemu { child, out, err, t0: Instant::now(), elf: elf.to_path_buf() }
}

impl Qemu {
    /// Wait for the exit; fails on a non-zero exit (a firmware panic exits with 1) or
    /// after `timeout`.
    pub fn wait(mut self, timeout: Duration) -> QemuRun {
        let status = loop {
            if let Some(s) = self.child.try_wait().expect("wait for qemu") {
                break s;
            }
            if self.t0.elapsed() > timeout {
                let _ = self.child.kill();
                let _ = self.child.wait();
                panic!("{} did not finish within {timeout:?} on QEMU", self.elf.display());
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let run = QemuRun {
            stdout: self.out.join().unwrap_or_default(),
            stderr: self.err.join().unwrap_or_default(),
            wall: self.t0.elapsed(),
        };
        assert!(
            status.success(),
            "{} failed on QEMU ({status}); a firmware panic exits with 1. Its defmt log \
             is {} bytes on stdout (decode with `defmt-print -e {}`); QEMU's stderr:\n{}",
            self.elf.display(),
            run.stdout.len(),
            self.elf.display(),
            String::from_utf8_lossy(&run.stderr)
        );
        run
    }
}

/// [`spawn_qemu`] without extras, then [`Qemu::wait`].
pub fn run_qemu(elf: &Path, cwd: &Path, timeout: Duration) -> QemuRun {
    spawn_qemu(elf, cwd, &[], &[]).wait(timeout)
}

/// [`run_qemu`] on the board of `mcu`.
pub fn run_qemu_on(mcu: &Mcu, elf: &Path, cwd: &Path, timeout: Duration) -> QemuRun {
    spawn_qemu_on(mcu, elf, cwd, &[], &[]).wait(timeout)
}

/// The host configuration the firmware runs (`firmware::config`).
pub fn config(rates: RateSet, effects: Effects) -> Config {
    Config {
        dt_us: STEP_US,
        params: Params::thesis(rates, CouplingStiffness::Identified),
        speed_target: SpeedTarget::Map,
        effects,
    }
}

/// The host simulation of one traced run.
pub fn host_sim(which: Builtin, rates: RateSet, effects: Effects) -> Simulation<'static> {
    let profile = Profile::builtin(which, 1.0, 1.0).expect("built-in profile");
    Simulation::new(&config(rates, effects), profile, SUPPLY_V).expect("valid config")
}

/// FNV-1a 64 over the little-endian bits of every channel of every step.
pub fn host_hash(which: Builtin, rates: RateSet) -> (u64, u32) {
    hash_steps(host_sim(which, rates, Effects::NONE))
}

/// Lower-case name of a rate set, as in the golden file and messages.
pub fn rates_name(r: RateSet) -> &'static str {
    match r {
        RateSet::Programmed => "programmed",
        RateSet::Identified => "identified",
    }
}

/// One run of a trace file.
pub struct TraceRun {
    pub profile: Builtin,
    pub rates: RateSet,
    pub n_steps: u32,
    /// Byte range of the step records in the file.
    pub records: std::ops::Range<usize>,
    /// The firmware's own FNV-1a 64 over the channel bits.
    pub hash: u64,
}

/// A parsed trace file (format in `firmware/src/protocol.rs`).
pub struct Trace {
    pub bytes: Vec<u8>,
    pub n_channels: usize,
    pub dt_us: u32,
    pub effects: Vec<(String, String, f32)>,
    pub runs: Vec<TraceRun>,
    /// Bytes of a value: 4 (f32 bits, or the fixed-point twin's I17F15 bits).
    pub width: usize,
    /// The values are the fixed-point twin's (the trace's magic says which).
    pub fixed: bool,
}

/// Reads a little-endian record file front to back; a short file or a wrong magic
/// fails the test naming the file (`what`) and the byte.
pub struct Cursor<'a> {
    b: &'a [u8],
    /// Bytes read so far.
    pub pos: usize,
    what: &'a str,
}

#[allow(dead_code)] // each test binary uses part of it
impl<'a> Cursor<'a> {
    pub fn new(b: &'a [u8], what: &'a str) -> Self {
        Self { b, pos: 0, what }
    }
    pub fn take(&mut self, n: usize) -> &[u8] {
        let (what, pos, len) = (self.what, self.pos, self.b.len());
        let s = self
            .b
            .get(self.pos..self.pos + n)
            .unwrap_or_else(|| panic!("{what} truncated at byte {pos} (wanted {n} more of {len})"));
        self.pos += n;
        s
    }
    pub fn u8(&mut self) -> u8 {
        self.take(1)[0]
    }
    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take(2).try_into().unwrap())
    }
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    pub fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take(8).try_into().unwrap())
    }
    pub fn magic(&mut self, m: &[u8], what: &str) {
        let at = self.pos;
        let got = self.take(m.len()).to_vec();
        assert_eq!(got, m, "{}: expected {what} at byte {at}", self.what);
    }
    pub fn string(&mut self) -> String {
        let n = usize::from(self.u8());
        String::from_utf8(self.take(n).to_vec()).expect("utf-8 name")
    }
}

/// Read and check the structure of a trace file.
pub fn read_trace(path: &Path) -> Trace {
    let bytes = fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut c = Cursor::new(&bytes, "trace");
    let fixed = bytes.get(..8) == Some(&protocol::TRACE_MAGIC_FX[..]);
    let width = 4;
    c.magic(if fixed { &protocol::TRACE_MAGIC_FX } else { &protocol::TRACE_MAGIC }, "the trace magic");
    let n_channels = usize::from(c.u16());
    let dt_us = c.u32();
    let n_fx = c.u16();
    let effects = (0..n_fx)
        .map(|_| {
            let id = c.string();
            let key = c.string();
            (id, key, f32::from_bits(c.u32()))
        })
        .collect();
    let record = 8 + width * n_channels;
    let mut runs = Vec::new();
    loop {
        let at = c.pos;
        let tag = c.take(4).to_vec();
        if tag == protocol::DONE_MAGIC {
            let n = c.u32() as usize;
            assert_eq!(n, runs.len(), "trace: run count in the trailer");
            assert_eq!(c.pos, bytes.len(), "trace: bytes after the trailer");
            break;
        }
        assert_eq!(tag, protocol::RUN_MAGIC, "trace: expected a run at byte {at}");
        let name = c.take(8).to_vec();
        let name = String::from_utf8_lossy(&name).trim_end_matches('\0').to_string();
        let profile = Builtin::from_name(&name).unwrap_or_else(|| panic!("unknown {name}"));
        let rates = match c.u8() {
            0 => RateSet::Programmed,
            1 => RateSet::Identified,
            r => panic!("trace: bad rate set {r}"),
        };
        let n_steps = c.u32();
        let start = c.pos;
        c.take(record * n_steps as usize);
        let records = start..c.pos;
        c.magic(&protocol::END_MAGIC, "the end of a run");
        let hash = c.u64();
        runs.push(TraceRun { profile, rates, n_steps, records, hash });
    }
    Trace { n_channels, dt_us, effects, runs, bytes, width, fixed }
}

/// Step `k` of a run: `t_us` and the channel bits (4 bytes each, as a u64).
pub fn record(trace: &Trace, run: &TraceRun, k: usize) -> (u64, Vec<u64>) {
    let w = trace.width;
    let size = 8 + w * trace.n_channels;
    let r = &trace.bytes[run.records.start + k * size..][..size];
    let t = u64::from_le_bytes(r[..8].try_into().unwrap());
    let bits = r[8..]
        .chunks_exact(w)
        .map(|b| {
            let mut v = [0u8; 8];
            v[..w].copy_from_slice(b);
            u64::from_le_bytes(v)
        })
        .collect();
    (t, bits)
}

/// A twin's channel value as a trace carries it: f32 (M4F, M3 soft-float) or the
/// fixed-point `Fx` (M3 fixed), so one comparison and one hash serve both.
pub trait TraceValue: Copy {
    /// Bytes per value in a trace.
    const WIDTH: usize;
    /// The fixed-point twin's values.
    const FIXED: bool;
    /// The value's bits as the trace stores them (little-endian, zero-extended).
    fn raw(self) -> u64;
    /// Bits as read from a trace, for a message: the value and its hex.
    fn show(raw: u64) -> String;
}

impl TraceValue for f32 {
    const WIDTH: usize = 4;
    const FIXED: bool = false;
    fn raw(self) -> u64 {
        u64::from(self.to_bits())
    }
    fn show(raw: u64) -> String {
        format!("{:e} (0x{raw:08x})", f32::from_bits(raw as u32))
    }
}

impl TraceValue for model_core::Fx {
    const WIDTH: usize = 4;
    const FIXED: bool = true;
    fn raw(self) -> u64 {
        u64::from(self.to_bits() as u32)
    }
    fn show(raw: u64) -> String {
        format!("{} (0x{raw:08x})", model_core::Fx::from_bits(raw as u32 as i32).to_f32())
    }
}

/// FNV-1a 64 over the little-endian bits of every channel of every step (the firmware's
/// own hash), and the step count.
fn hash_steps<R: TraceValue>(outputs: impl IntoIterator<Item = Outputs<R>>) -> (u64, u32) {
    let mut h = protocol::Fnv1a64::default();
    let mut steps = 0;
    for o in outputs {
        for v in o.values {
            h.write(&v.raw().to_le_bytes()[..R::WIDTH]);
        }
        steps += 1;
    }
    (h.0, steps)
}

/// Compare one run bit for bit with the host's `host` outputs; the number of steps
/// compared. Panics at the first difference with step, time, channel and both values.
fn compare_outputs<R: TraceValue>(trace: &Trace, run: &TraceRun, label: &str, host: &[Outputs<R>]) -> usize {
    assert_eq!(trace.width, R::WIDTH, "{label}: a trace of {}-byte values", trace.width);
    assert_eq!(trace.fixed, R::FIXED, "{label}: a fixed-point trace compared with the f32 twin or back");
    assert_eq!(
        run.n_steps as usize,
        host.len(),
        "{label}: firmware ran {} steps, host {}",
        run.n_steps,
        host.len()
    );
    for (k, o) in host.iter().enumerate() {
        let (t_us, bits) = record(trace, run, k);
        assert_eq!(t_us, o.t_us, "{label}: step {k}: firmware t_us {t_us}, host {}", o.t_us);
        for (c, (fw, hv)) in bits.iter().zip(o.values.iter()).enumerate() {
            if *fw != hv.raw() {
                let ch = model_core::Channel::ALL[c];
                panic!(
                    "{label}: first difference at step {k} (t = {t_us} us), channel {} ({}):\n  \
                     firmware {}\n  host     {}",
                    ch.name(),
                    ch.unit(),
                    R::show(*fw),
                    R::show(hv.raw())
                );
            }
        }
    }
    assert_eq!(
        run.hash,
        hash_steps(host.iter().cloned()).0,
        "{label}: the firmware's own hash differs from the host's though every record matched"
    );
    host.len()
}

/// Compare one f32 run bit for bit with the host; the number of steps compared.
pub fn compare_run(trace: &Trace, run: &TraceRun, effects: Effects) -> usize {
    let label = format!("{} {}", run.profile.name(), rates_name(run.rates));
    let host: Vec<Outputs> = host_sim(run.profile, run.rates, effects).collect();
    compare_outputs(trace, run, &label, &host)
}

/// The host run of the fixed-point twin for one traced run (the M3 build's twin).
pub fn host_sim_fx(which: Builtin, rates: RateSet) -> Simulation<'static, model_core::Fx> {
    let profile = Profile::builtin(which, 1.0, 1.0).expect("built-in profile");
    Simulation::new_fx(&config(rates, Effects::NONE), profile, SUPPLY_V).expect("valid config")
}

/// FNV-1a 64 over the little-endian I17F15 bits of every channel of every step of the
/// host's fixed-point run; the step count.
pub fn host_hash_fx(which: Builtin, rates: RateSet) -> (u64, u32) {
    hash_steps(host_sim_fx(which, rates))
}

/// [`compare_run`] for a fixed-point trace: every channel's I17F15 bits at every step
/// equal the host's fixed-point twin's. The number of steps compared.
pub fn compare_run_fx(trace: &Trace, run: &TraceRun) -> usize {
    let label = format!("{} {} (fixed point)", run.profile.name(), rates_name(run.rates));
    let host: Vec<Outputs<model_core::Fx>> = host_sim_fx(run.profile, run.rates).collect();
    compare_outputs(trace, run, &label, &host)
}

/// Check the host's trace hashes (`hash` per built-in profile and rate set) against the
/// golden file `file` (under host-tests/, with `header` on top); `SIMROD_BLESS=1`
/// rewrites it instead. `test` is the command that blesses, for the messages.
pub fn check_golden(file: &str, header: &str, test: &str, hash: impl Fn(Builtin, RateSet) -> (u64, u32)) {
    use std::fmt::Write as _;
    let mut now = String::from(header);
    for rates in RATES {
        for which in Builtin::ALL {
            let (h, steps) = hash(which, rates);
            writeln!(
                now,
                "{} {} steps={steps} channels={} fnv1a64={h:#018x}",
                which.name(),
                rates_name(rates),
                model_core::N_CHANNELS
            )
            .ok();
        }
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let bless = format!("SIMROD_BLESS=1 cargo test -p host-tests --test {test} golden");
    if std::env::var_os("SIMROD_BLESS").is_some_and(|v| v == "1") {
        fs::create_dir_all(path.parent().expect("golden files live in a directory")).expect("golden dir");
        fs::write(&path, &now).expect("write the golden file");
        eprintln!("blessed {}", path.display());
        return;
    }
    let golden = fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e}. Create it with {bless}", path.display()));
    let data = |s: &str| -> Vec<String> {
        s.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()).map(str::to_string).collect()
    };
    let (want, got) = (data(&golden), data(&now));
    let diffs: Vec<String> = want
        .iter()
        .zip(&got)
        .filter(|(w, g)| w != g)
        .map(|(w, g)| format!("  golden: {w}\n  now:    {g}"))
        .collect();
    assert!(
        diffs.is_empty() && want.len() == got.len(),
        "the host traces no longer match {}:\n{}\n(golden has {} runs, now {}).\n\
         If the model change is deliberate, regenerate with\n  {bless}\n\
         and commit the file with the change; otherwise find what changed the numbers.",
        path.display(),
        diffs.join("\n"),
        want.len(),
        got.len()
    );
}
