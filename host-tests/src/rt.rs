//! Real-time cost and footprint of the firmware, measured on QEMU: building it, running
//! its cost binary (`simrod-cost`) and bench loop (`firmware`), and reading what they
//! report. Shared by the budget test (`tests/firmware_budget.rs`) and
//! `cargo xtask bench-rt`.
//!
//! **Instructions, not cycles.** QEMU counts instructions exactly (`-icount`) but does
//! not model the Cortex-M4F's pipeline, flash wait states or the FPU's 14-cycle divide.
//! Cost here is instructions; on a real part cycles are typically 1.2–1.5× that (the
//! `rtt` firmware build times steps with the DWT cycle counter there).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use model_core::{
    Builtin, Config, CouplingStiffness, Effects, Params, Profile, RateSet, Simulation, SpeedTarget,
};

#[path = "../../firmware/src/protocol.rs"]
#[allow(dead_code)] // the serial decoder is the firmware's business
pub mod protocol;

/// The firmware's target.
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// The binaries of the firmware crate.
pub const BINARIES: [&str; 4] = ["firmware", "simrod-trace", "simrod-cost", "simrod-xil"];

/// One firmware build: the core, its Rust target and QEMU board, and the twin's scalar.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mcu {
    /// For reports.
    pub name: &'static str,
    pub target: &'static str,
    /// QEMU `-machine` and `-cpu`.
    pub machine: &'static str,
    pub cpu: &'static str,
    /// The fixed-point twin (`firmware` feature `fixed`), else f32.
    pub fixed: bool,
}

/// The Cortex-M4F with its FPU, the f32 twin (QEMU mps2-an386).
pub const M4F: Mcu = Mcu {
    name: "Cortex-M4F, f32 (FPU)",
    target: TARGET,
    machine: "mps2-an386",
    cpu: "cortex-m4",
    fixed: false,
};
/// The FPU-less Cortex-M3, the fixed-point twin (QEMU mps2-an385).
pub const M3_FIXED: Mcu = Mcu {
    name: "Cortex-M3, fixed point",
    target: "thumbv7m-none-eabi",
    machine: "mps2-an385",
    cpu: "cortex-m3",
    fixed: true,
};
/// The Cortex-M3 running the f32 twin in soft-float: the fixed point's comparison.
pub const M3_SOFT: Mcu = Mcu { name: "Cortex-M3, f32 soft-float", fixed: false, ..M3_FIXED };

impl Mcu {
    /// The firmware binaries this build has (`simrod-xil`, the f32 xDT's loop, only on
    /// the M4F).
    pub fn binaries(&self) -> &'static [&'static str] {
        if *self == M4F {
            &BINARIES
        } else {
            &BINARIES[..3]
        }
    }
}
/// The profiles `simrod-cost` runs, in its order.
pub const COST_PROFILES: [Builtin; 3] = [Builtin::TP07, Builtin::TP11, Builtin::TP14];

/// CI budget: worst instructions per `simrod_step` call on the Cortex-M4F.
pub const BUDGET_STEP_INSNS: u32 = 5_000;
/// CI budget: flash (vector table, code, read-only data, initial values of `.data`).
pub const BUDGET_FLASH: u64 = 64 * 1024;
/// CI budget: RAM (`.data`, `.bss` and the stack high-water mark).
pub const BUDGET_RAM: u64 = 16 * 1024;
/// CI budget: worst instructions per `simrod_step` call of the fixed-point twin on the
/// Cortex-M3 (generous: about 2x the worst measured, 8,997 on TP07; see
/// `tests/firmware_budget.rs`).
pub const BUDGET_M3_STEP_INSNS: u32 = 18_000;
/// CI guard: the fixed-point step at least this many times cheaper than the f32 twin in
/// soft-float on the same core (mean over a profile; the aim, measured 4.6).
pub const MIN_M3_SOFT_OVER_FIXED: f64 = 3.0;
/// CI budget: the M3 fixed-point bench firmware's flash (its arithmetic, 32- and 64-bit,
/// is inlined into the step; measured 83 KB).
pub const BUDGET_M3_FLASH: u64 = 192 * 1024;
/// CI budget: the M3 fixed-point bench firmware's RAM (static + stack high-water). Its
/// peak is `Model::new_fx`: the model's 64-bit parts and the discretization's f64
/// temporaries in soft f64; the part declared (`firmware/m3/memory.x`) has 128 KiB.
pub const BUDGET_M3_RAM: u64 = 24 * 1024;
/// Aim (reported, not enforced): worst instructions per step.
pub const AIM_STEP_INSNS: u32 = 3_000;
/// Aim: RAM including the stack.
pub const AIM_RAM: u64 = 8 * 1024;
/// Aim: host steps per second on one core.
pub const AIM_HOST_STEPS_PER_S: f64 = 5e6;

/// icount shift of the cost runs: 128 ns of virtual time per instruction, so the
/// 25 MHz SysTick moves 3.2 counts per instruction and every interval converts to an
/// exact instruction count (the calibration proves it).
pub const COST_SHIFT: u32 = 7;
/// icount shift of the real-time loop runs: 8 ns per instruction, a core of 125 M
/// instructions/s, what a 168 MHz Cortex-M4F does at 1.34 cycles per instruction.
pub const LOOP_SHIFT: u32 = 3;
/// Virtual instructions per microsecond at [`LOOP_SHIFT`].
pub const LOOP_INSNS_PER_US: u32 = 1000 >> LOOP_SHIFT;
/// Supply voltage of the firmware's runs (`firmware::SUPPLY_V`).
pub const SUPPLY_V: f32 = 24.0;
/// The firmware's step (`firmware::STEP_US`).
pub const STEP_US: u32 = 1000;

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("host-tests sits in the workspace").to_path_buf()
}

/// `target/firmware-tests/<sub>`: the firmware tests' build directory and variants.
pub fn firmware_target_dir(sub: &str) -> PathBuf {
    let base = match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) if Path::new(&d).is_absolute() => PathBuf::from(d),
        Some(d) => root().join(d),
        None => root().join("target"),
    };
    base.join("firmware-tests").join(sub)
}

/// Build the firmware's binaries (release) with the effects file `effects` compiled in
/// (or none) and the crate features `features`, in the shared build directory
/// `target/firmware-tests/build`, and copy the ELFs to `target/firmware-tests/<variant>`.
/// A nested `cargo build`: the `cargo test` running the tests holds the lock of the
/// workspace's own build directory.
pub fn build_firmware(variant: &str, effects: Option<&Path>, features: &[&str]) -> Result<PathBuf, String> {
    build_firmware_on(&M4F, variant, effects, features)
}

/// [`build_firmware`] for the core `mcu` (its target, its binaries, feature `fixed` for
/// the fixed-point twin).
pub fn build_firmware_on(
    mcu: &Mcu,
    variant: &str,
    effects: Option<&Path>,
    features: &[&str],
) -> Result<PathBuf, String> {
    let target_dir = firmware_target_dir("build");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(root()).args(["build", "-p", "firmware", "--release", "--target", mcu.target]);
    for bin in mcu.binaries() {
        cmd.args(["--bin", bin]);
    }
    let mut features = features.to_vec();
    if mcu.fixed {
        features.push("fixed");
    }
    cmd.arg("--target-dir")
        .arg(&target_dir)
        // Only what .cargo/config.toml and the manifests say may shape the build.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .env_remove("SIMROD_PROFILE")
        .env_remove("SIMROD_RATES")
        .env_remove("SIMROD_MEMORY_X");
    if !features.is_empty() {
        cmd.arg("--features").arg(features.join(","));
    }
    match effects {
        Some(p) => cmd.env("SIMROD_EFFECTS", p),
        None => cmd.env_remove("SIMROD_EFFECTS"),
    };
    let out = cmd.output().map_err(|e| format!("cannot run cargo: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "building the firmware ({variant}) failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let built = target_dir.join(mcu.target).join("release");
    let dir = firmware_target_dir(variant);
    fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for bin in mcu.binaries() {
        fs::copy(built.join(bin), dir.join(bin))
            .map_err(|e| format!("copy {bin} to {}: {e}", dir.display()))?;
    }
    Ok(dir)
}

/// Boot `elf` on QEMU's mps2-an386 in a fresh `cwd` with `extra` QEMU arguments and
/// `args` on the semihosting command line; wait for a successful exit. The defmt log
/// goes to `cwd/defmt.bin`, QEMU's stderr to `cwd/qemu.stderr`.
pub fn run_qemu(
    elf: &Path,
    cwd: &Path,
    extra: &[&str],
    args: &[&str],
    timeout: Duration,
) -> Result<(), String> {
    run_qemu_on(&M4F, elf, cwd, extra, args, timeout)
}

/// [`run_qemu`] on the board of `mcu`.
pub fn run_qemu_on(
    mcu: &Mcu,
    elf: &Path,
    cwd: &Path,
    extra: &[&str],
    args: &[&str],
    timeout: Duration,
) -> Result<(), String> {
    let _ = fs::remove_dir_all(cwd);
    fs::create_dir_all(cwd).map_err(|e| format!("{}: {e}", cwd.display()))?;
    let mut semi = String::from("enable=on,target=native,arg=firmware");
    for a in args {
        semi.push_str(",arg=");
        semi.push_str(a);
    }
    let file = |name: &str| fs::File::create(cwd.join(name)).map_err(|e| format!("{name}: {e}"));
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(["-machine", mcu.machine, "-cpu", mcu.cpu, "-display", "none", "-monitor", "none"])
        .args(["-semihosting-config", &semi]);
    if !extra.contains(&"-serial") {
        cmd.args(["-serial", "null"]);
    }
    cmd.args(extra)
        .arg("-kernel")
        .arg(elf)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(file("defmt.bin")?)
        .stderr(file("qemu.stderr")?);
    let t0 = Instant::now();
    let mut child = cmd.spawn().map_err(|e| format!("cannot start qemu-system-arm: {e}"))?;
    let status = loop {
        if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
            break s;
        }
        if t0.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("{} did not finish within {timeout:?} on QEMU", elf.display()));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    if !status.success() {
        let stderr = fs::read_to_string(cwd.join("qemu.stderr")).unwrap_or_default();
        return Err(format!(
            "{} failed on QEMU ({status}); defmt log in {} (decode with `defmt-print -e {}`); stderr:\n{stderr}",
            elf.display(),
            cwd.join("defmt.bin").display(),
            elf.display()
        ));
    }
    Ok(())
}

/// The host simulation's FNV-1a 64 over every channel of every step of a firmware
/// run (identified rate set, 1 ms, no effects, 24 V): what the firmware must match.
pub fn host_hash(which: Builtin) -> u64 {
    host_hash_on(&M4F, which)
}

/// [`host_hash`] of the twin `mcu` runs: f32 bits, or the fixed-point twin's I17F15
/// bits (4 bytes a value).
pub fn host_hash_on(mcu: &Mcu, which: Builtin) -> u64 {
    let cfg = Config {
        dt_us: STEP_US,
        params: Params::thesis(RateSet::Identified, CouplingStiffness::Identified),
        speed_target: SpeedTarget::Map,
        effects: Effects::NONE,
    };
    let profile = Profile::builtin(which, 1.0, 1.0).expect("built-in profile");
    let mut h = protocol::Fnv1a64::default();
    if mcu.fixed {
        for o in Simulation::new_fx(&cfg, profile, SUPPLY_V).expect("valid config") {
            for v in o.values {
                h.write(&v.to_bits().to_le_bytes());
            }
        }
    } else {
        for o in Simulation::new(&cfg, profile, SUPPLY_V).expect("valid config") {
            h.write_f32s(&o.values);
        }
    }
    h.0
}

/// min / median / 99th percentile / max / mean of a sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    pub n: usize,
    pub min: u32,
    pub median: u32,
    pub p99: u32,
    pub max: u32,
    pub mean: f64,
}

impl Summary {
    /// Of `values` (nearest-rank percentiles); `None` when empty.
    pub fn of(values: impl IntoIterator<Item = u32>) -> Option<Self> {
        let mut v: Vec<u32> = values.into_iter().collect();
        if v.is_empty() {
            return None;
        }
        v.sort_unstable();
        let n = v.len();
        let rank = |p: f64| v[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
        Some(Self {
            n,
            min: v[0],
            median: rank(0.5),
            p99: rank(0.99),
            max: v[n - 1],
            mean: v.iter().map(|&x| f64::from(x)).sum::<f64>() / n as f64,
        })
    }
}

/// One calibration region of the cost file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Calibration {
    /// `nop`s between the two timer reads.
    pub nops: u32,
    /// Instructions the firmware counted between them.
    pub insns: u32,
    /// Raw SysTick counts.
    pub counts: u32,
}

/// One step of a cost run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StepCost {
    /// Instructions of the `simrod_profile_at` call.
    pub profile_at: u32,
    /// Instructions of the `simrod_step` call (arguments, call, step, return).
    pub step: u32,
    /// Stack bytes the step used below its caller's stack pointer.
    pub stack: u32,
    /// Per block (build with feature `profile`): instructions, hooks included.
    pub blocks: Vec<u32>,
    /// Per block: number of intervals summed (each carries one hook overhead).
    pub marks: Vec<u32>,
}

/// One profile of a cost run.
#[derive(Debug, Clone)]
pub struct CostRun {
    pub profile: Builtin,
    pub identified: bool,
    pub steps: Vec<StepCost>,
    /// The firmware's FNV-1a 64 over its outputs' bits.
    pub hash: u64,
}

/// A parsed `simrod-cost.bin`.
#[derive(Debug, Clone)]
pub struct CostFile {
    pub ns_per_insn: u32,
    pub timer_hz: u32,
    pub n_blocks: usize,
    pub calibration: Vec<Calibration>,
    /// Instructions between the timer reads of two back-to-back probe calls.
    pub mark_overhead: u32,
    /// Bytes painted below the step.
    pub stack_window: u32,
    pub runs: Vec<CostRun>,
}

struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let s = self
            .b
            .get(self.pos..self.pos + n)
            .ok_or_else(|| format!("cost file truncated at byte {}", self.pos))?;
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn magic(&mut self, m: &[u8], what: &str) -> Result<(), String> {
        let at = self.pos;
        if self.take(m.len())? != m {
            return Err(format!("cost file: expected {what} at byte {at}"));
        }
        Ok(())
    }
}

/// Parse a cost file (format in `firmware/src/protocol.rs`).
pub fn parse_cost(bytes: &[u8]) -> Result<CostFile, String> {
    let mut c = Cursor { b: bytes, pos: 0 };
    c.magic(&protocol::COST_MAGIC, "the cost magic")?;
    let ns_per_insn = c.u32()?;
    let timer_hz = c.u32()?;
    let n_blocks = c.u32()? as usize;
    if n_blocks != 0 && n_blocks != protocol::COST_BLOCKS.len() {
        return Err(format!("cost file: {n_blocks} blocks, expected 0 or {}", protocol::COST_BLOCKS.len()));
    }
    let n_cal = c.u32()?;
    let mut calibration = Vec::new();
    for _ in 0..n_cal {
        calibration.push(Calibration { nops: c.u32()?, insns: c.u32()?, counts: c.u32()? });
    }
    let mark_overhead = c.u32()?;
    let stack_window = c.u32()?;
    let words = protocol::COST_FIXED_WORDS + 2 * n_blocks;
    let mut runs = Vec::new();
    loop {
        let at = c.pos;
        let tag = c.take(4)?.to_vec();
        if tag == protocol::DONE_MAGIC {
            let n = c.u32()? as usize;
            if n != runs.len() || c.pos != bytes.len() {
                return Err(format!("cost file: trailer says {n} runs, read {}", runs.len()));
            }
            break;
        }
        if tag != protocol::RUN_MAGIC {
            return Err(format!("cost file: expected a run at byte {at}"));
        }
        let name = String::from_utf8_lossy(c.take(8)?).trim_end_matches('\0').to_string();
        let profile =
            Builtin::from_name(&name).ok_or_else(|| format!("cost file: unknown profile {name}"))?;
        let identified = c.take(1)?[0] == 1;
        let n_steps = c.u32()? as usize;
        let mut steps = Vec::with_capacity(n_steps);
        for _ in 0..n_steps {
            let w: Vec<u32> = (0..words).map(|_| c.u32()).collect::<Result<_, _>>()?;
            let (fixed, rest) = w.split_at(protocol::COST_FIXED_WORDS);
            let (blocks, marks) = rest.split_at(n_blocks);
            steps.push(StepCost {
                profile_at: fixed[0],
                step: fixed[1],
                stack: fixed[2],
                blocks: blocks.to_vec(),
                marks: marks.to_vec(),
            });
        }
        c.magic(&protocol::END_MAGIC, "the end of a run")?;
        let hash = c.u64()?;
        runs.push(CostRun { profile, identified, steps, hash });
    }
    Ok(CostFile { ns_per_insn, timer_hz, n_blocks, calibration, mark_overhead, stack_window, runs })
}

impl CostFile {
    /// The calibration regions must count exactly their `nop`s: proof that the counts
    /// are instruction-exact under this shift.
    pub fn check_calibration(&self) -> Result<(), String> {
        if self.calibration.len() < 3 {
            return Err(format!("only {} calibration regions", self.calibration.len()));
        }
        match self.calibration.iter().find(|c| c.insns != c.nops) {
            Some(c) => Err(format!(
                "calibration: {} nops counted as {} instructions ({} timer counts at {} ns/instruction): \
                 counts are not instruction-exact",
                c.nops, c.insns, c.counts, self.ns_per_insn
            )),
            None => Ok(()),
        }
    }

    /// Per block over all runs: (name, instructions per step with the hooks' overhead
    /// removed, share of the step). Empty without block profile.
    pub fn block_shares(&self) -> Vec<(&'static str, f64, f64)> {
        if self.n_blocks == 0 {
            return Vec::new();
        }
        let steps: usize = self.runs.iter().map(|r| r.steps.len()).sum();
        let net: Vec<f64> = (0..self.n_blocks)
            .map(|b| {
                let sum: f64 = self
                    .runs
                    .iter()
                    .flat_map(|r| &r.steps)
                    .map(|s| f64::from(s.blocks[b]) - f64::from(s.marks[b]) * f64::from(self.mark_overhead))
                    .sum();
                (sum / steps.max(1) as f64).max(0.0)
            })
            .collect();
        let total: f64 = net.iter().sum();
        protocol::COST_BLOCKS
            .iter()
            .zip(net)
            .map(|(n, v)| (*n, v, if total > 0.0 { v / total } else { 0.0 }))
            .collect()
    }
}

/// Run `simrod-cost` (at [`COST_SHIFT`]) in `cwd`, parse its file, and check the
/// calibration and that every run computed the host's bits.
pub fn run_cost(elf: &Path, cwd: &Path) -> Result<CostFile, String> {
    run_cost_on(&M4F, elf, cwd)
}

/// [`run_cost`] on the board of `mcu`, against the host run of its twin.
pub fn run_cost_on(mcu: &Mcu, elf: &Path, cwd: &Path) -> Result<CostFile, String> {
    let shift = format!("shift={COST_SHIFT},sleep=off");
    let arg = format!("shift={COST_SHIFT}");
    // The M3's soft-float build runs several times the M4F's instructions.
    let timeout = Duration::from_secs(if *mcu == M4F { 600 } else { 1800 });
    run_qemu_on(mcu, elf, cwd, &["-icount", &shift], &[&arg], timeout)?;
    let path = cwd.join(protocol::COST_FILE);
    let bytes = fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let cost = parse_cost(&bytes)?;
    cost.check_calibration()?;
    let got: Vec<Builtin> = cost.runs.iter().map(|r| r.profile).collect();
    if got != COST_PROFILES {
        return Err(format!("cost runs {got:?}, expected {COST_PROFILES:?}"));
    }
    for r in &cost.runs {
        let want = host_hash_on(mcu, r.profile);
        if !r.identified || r.hash != want {
            return Err(format!(
                "{} (identified: {}): the firmware's outputs hash to {:#018x}, the host's to {want:#018x}",
                r.profile.name(),
                r.identified,
                r.hash
            ));
        }
    }
    Ok(cost)
}

/// Flash and static RAM of an ELF, by section.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Footprint {
    pub vector_table: u64,
    pub text: u64,
    pub rodata: u64,
    pub data: u64,
    pub bss: u64,
    pub uninit: u64,
}

impl Footprint {
    /// Flash: vector table, code, read-only data and `.data`'s initial values.
    pub fn flash(&self) -> u64 {
        self.vector_table + self.text + self.rodata + self.data
    }

    /// Static RAM: `.data`, `.bss`, `.uninit` (the stack comes on top).
    pub fn static_ram(&self) -> u64 {
        self.data + self.bss + self.uninit
    }
}

/// The section sizes of `elf`.
pub fn footprint(elf: &Path) -> Result<Footprint, String> {
    use object::{Object, ObjectSection};
    let bytes = fs::read(elf).map_err(|e| format!("{}: {e}", elf.display()))?;
    let file = object::File::parse(&*bytes).map_err(|e| format!("{}: {e}", elf.display()))?;
    let size = |name: &str| file.section_by_name(name).map_or(0, |s| s.size());
    let f = Footprint {
        vector_table: size(".vector_table"),
        text: size(".text"),
        rodata: size(".rodata"),
        data: size(".data"),
        bss: size(".bss"),
        uninit: size(".uninit"),
    };
    if f.vector_table == 0 || f.text == 0 {
        return Err(format!("{}: no .vector_table/.text: not the firmware ELF?", elf.display()));
    }
    Ok(f)
}

/// The statistics frame of a bench loop run, by field name (`protocol::STATS_FIELDS`).
#[derive(Debug, Clone)]
pub struct LoopStats(pub Vec<(&'static str, u32)>);

impl LoopStats {
    /// A field; panics on an unknown name (a programming error).
    pub fn get(&self, name: &str) -> u32 {
        self.0
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| *v)
            .unwrap_or_else(|| panic!("no stats field {name}"))
    }
}

impl std::fmt::Display for LoopStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self.0.iter().map(|(n, v)| format!("{n}={v}")).collect();
        f.write_str(&parts.join(" "))
    }
}

/// Run the bench loop (`firmware` ELF) on `profile` with a tick of `tick_us` under
/// `-icount shift=LOOP_SHIFT` in `cwd`; its statistics frame.
pub fn run_loop(elf: &Path, cwd: &Path, profile: Builtin, tick_us: u32) -> Result<LoopStats, String> {
    run_loop_on(&M4F, elf, cwd, profile, tick_us)
}

/// [`run_loop`] on the board of `mcu`.
pub fn run_loop_on(
    mcu: &Mcu,
    elf: &Path,
    cwd: &Path,
    profile: Builtin,
    tick_us: u32,
) -> Result<LoopStats, String> {
    let shift = format!("shift={LOOP_SHIFT},sleep=off");
    let args = [format!("profile={}", profile.name()), format!("tick_us={tick_us}")];
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let extra = ["-icount", &shift, "-serial", "file:uart.bin"];
    run_qemu_on(mcu, elf, cwd, &extra, &args, Duration::from_secs(600))?;
    let bytes = fs::read(cwd.join("uart.bin")).map_err(|e| format!("UART capture: {e}"))?;
    let stats = protocol::frames(&bytes)
        .filter(|(k, _)| *k == protocol::KIND_STATS)
        .last()
        .ok_or("no statistics frame on the UART")?
        .1;
    let v: Vec<(&'static str, u32)> = protocol::STATS_FIELDS
        .iter()
        .zip(stats.chunks_exact(4))
        .map(|(n, b)| (*n, u32::from_le_bytes(b.try_into().expect("4 bytes"))))
        .collect();
    if v.len() != protocol::STATS_FIELDS.len() {
        return Err(format!("statistics frame of {} bytes", stats.len()));
    }
    Ok(LoopStats(v))
}

/// The `n` largest symbols of an ELF that occupy flash (code and read-only data):
/// `(demangled name without hash, bytes)`, largest first.
pub fn largest_symbols(elf: &Path, n: usize) -> Result<Vec<(String, u64)>, String> {
    use object::{Object, ObjectSection, ObjectSymbol, SectionKind};
    let bytes = fs::read(elf).map_err(|e| format!("{}: {e}", elf.display()))?;
    let file = object::File::parse(&*bytes).map_err(|e| format!("{}: {e}", elf.display()))?;
    let mut v: Vec<(String, u64)> = file
        .symbols()
        .filter(|s| s.size() > 0)
        .filter(|s| {
            s.section_index()
                .and_then(|i| file.section_by_index(i).ok())
                .is_some_and(|sec| matches!(sec.kind(), SectionKind::Text | SectionKind::ReadOnlyData))
        })
        .filter_map(|s| Some((format!("{:#}", rustc_demangle::demangle(s.name().ok()?)), s.size())))
        .collect();
    v.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    v.dedup();
    v.truncate(n);
    Ok(v)
}
