//! "No hidden std, alloc or panic" in what runs on the target.
//!
//! - model-core's normal dependency tree for the target enables no `std`/`alloc`
//!   feature anywhere, and it builds for `thumbv7em-none-eabihf`, which has no `std`.
//! - The firmware links without a global allocator (so no crate in it uses `alloc`)
//!   and its ELFs hold no allocator symbol.
//! - The step links no panic path: from the firmware's `simrod_step` and
//!   `simrod_profile_at` (see `firmware/src/step.rs`), every direct call and tail call
//!   is followed through the release ELF (Thumb-2 BL/B.W decoding over the symbol
//!   table), and no reachable function may be a panic entry (`core::panicking::*`,
//!   `*_fail`, `unwrap_failed`, the panic handler...). Indirect branches would hide
//!   callees, so any reachable one fails the check too. A canary with an unchecked
//!   index (`simrod_canary_index` in the trace binary) proves the check finds panics.

mod firmware_support;

use std::collections::{BTreeMap, VecDeque};
use std::fs;
use std::path::Path;
use std::process::Command;

use firmware_support as fw;
use object::{Object, ObjectSection, ObjectSymbol, SectionKind, SymbolKind};

#[test]
fn model_core_dependency_tree_is_no_std_no_alloc() {
    fw::require_tools();
    let out = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
        .current_dir(fw::root())
        .args(["tree", "-p", "model-core", "-e", "normal,features", "--prefix", "none"])
        .args(["--target", fw::TARGET])
        .output()
        .expect("run cargo tree");
    assert!(out.status.success(), "cargo tree failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let tree = String::from_utf8_lossy(&out.stdout);
    let offending: Vec<&str> =
        tree.lines().filter(|l| l.contains("feature \"std\"") || l.contains("feature \"alloc\"")).collect();
    assert!(
        offending.is_empty(),
        "model-core's dependency tree for {} enables std/alloc:\n{}\nwhole tree:\n{tree}",
        fw::TARGET,
        offending.join("\n")
    );
    let mut crates: Vec<&str> = tree
        .lines()
        .filter(|l| !l.contains(" feature \""))
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    crates.sort_unstable();
    crates.dedup();
    assert!(crates.contains(&"model-core"), "cargo tree output:\n{tree}");
    eprintln!("model-core's tree for {}: {}", fw::TARGET, crates.join(", "));

    // The target has no std at all: this build succeeds only if nothing needs it.
    let out = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
        .current_dir(fw::root())
        .args(["build", "-p", "model-core", "--release", "--target", fw::TARGET])
        .arg("--target-dir")
        .arg(fw::firmware_target_dir("build"))
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .output()
        .expect("run cargo build");
    assert!(
        out.status.success(),
        "model-core does not build for {} (no std there):\n{}",
        fw::TARGET,
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A function of the ELF.
#[derive(Debug, Clone)]
struct Func {
    name: String,
    addr: u64,
    size: u64,
}

struct Elf {
    funcs: Vec<Func>,
    /// Executable bytes by section: (address, bytes).
    text: Vec<(u64, Vec<u8>)>,
    /// Data regions inside code (literal pools, jump tables): from `$d` to the next
    /// mapping symbol.
    data: Vec<(u64, u64)>,
    names: Vec<String>,
}

fn load(path: &Path) -> Elf {
    let bytes = fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let file = object::File::parse(&*bytes).expect("parse the ELF");
    let mut funcs = Vec::new();
    let mut maps: Vec<(u64, bool)> = Vec::new();
    let mut names = Vec::new();
    for s in file.symbols() {
        let Ok(raw) = s.name() else { continue };
        if raw.starts_with("$d") || raw.starts_with("$t") || raw.starts_with("$a") {
            maps.push((s.address(), raw.starts_with("$d")));
            continue;
        }
        let name = format!("{:#}", rustc_demangle::demangle(raw));
        names.push(name.clone());
        if s.kind() == SymbolKind::Text && s.size() > 0 {
            funcs.push(Func { name, addr: s.address() & !1, size: s.size() });
        }
    }
    funcs.sort_by_key(|f| f.addr);
    funcs.dedup_by_key(|f| f.addr);
    maps.sort_unstable();
    let text: Vec<(u64, Vec<u8>)> = file
        .sections()
        .filter(|s| s.kind() == SectionKind::Text)
        .map(|s| (s.address(), s.data().expect("section data").to_vec()))
        .collect();
    let end_of_text = text.iter().map(|(a, b)| a + b.len() as u64).max().unwrap_or(0);
    let data = maps
        .iter()
        .enumerate()
        .filter(|(_, (_, is_data))| *is_data)
        .map(|(i, (a, _))| (*a, maps.get(i + 1).map_or(end_of_text, |m| m.0)))
        .collect();
    Elf { funcs, text, data, names }
}

impl Elf {
    fn half(&self, addr: u64) -> Option<u16> {
        self.text.iter().find_map(|(base, b)| {
            let off = addr.checked_sub(*base)? as usize;
            let s = b.get(off..off + 2)?;
            Some(u16::from_le_bytes([s[0], s[1]]))
        })
    }

    fn func_at(&self, addr: u64) -> Option<usize> {
        let i = self.funcs.partition_point(|f| f.addr <= addr).checked_sub(1)?;
        let f = &self.funcs[i];
        (addr < f.addr + f.size).then_some(i)
    }

    fn func_named(&self, name: &str) -> usize {
        self.funcs
            .iter()
            .position(|f| f.name == name)
            .unwrap_or_else(|| panic!("no function `{name}` in the ELF"))
    }

    fn data_end(&self, addr: u64) -> Option<u64> {
        self.data.iter().find(|(a, b)| (*a..*b).contains(&addr)).map(|r| r.1)
    }
}

/// Branches out of a function: direct ones (address, target), and indirect ones
/// (address, what).
type Branches = (Vec<(u64, u64)>, Vec<(u64, String)>);

fn branches(elf: &Elf, f: &Func) -> Branches {
    let sext = |v: u32, bits: u32| -> i64 { ((v << (32 - bits)) as i32 >> (32 - bits)) as i64 };
    let (mut direct, mut indirect) = (Vec::new(), Vec::new());
    let end = f.addr + f.size;
    let mut pc = f.addr;
    while pc + 2 <= end {
        if let Some(skip_to) = elf.data_end(pc) {
            pc = skip_to.max(pc + 2);
            continue;
        }
        let Some(h1) = elf.half(pc) else { break };
        let target = |off: i64| (pc, (pc as i64 + 4 + off) as u64);
        if matches!(h1 >> 11, 0b11101..=0b11111) {
            let Some(h2) = elf.half(pc + 2) else { break };
            let (h1w, h2w) = (u32::from(h1), u32::from(h2));
            if h1 & 0xF800 == 0xF000 && h2 & 0x8000 == 0x8000 {
                let s = (h1w >> 10) & 1;
                let (j1, j2) = ((h2w >> 13) & 1, (h2w >> 11) & 1);
                let imm10 = h1w & 0x3FF;
                let imm11 = h2w & 0x7FF;
                if h2 & 0x5000 == 0x5000 || h2 & 0x5000 == 0x1000 {
                    // BL (T1) / B.W (T4): S:I1:I2:imm10:imm11:0, I = NOT(J xor S).
                    let (i1, i2) = (1 ^ (j1 ^ s), 1 ^ (j2 ^ s));
                    let v = (s << 24) | (i1 << 23) | (i2 << 22) | (imm10 << 12) | (imm11 << 1);
                    direct.push(target(sext(v, 25)));
                } else if h2 & 0x5000 == 0x0000 && (h1w >> 6) & 0xE != 0xE {
                    // B<c>.W (T3): S:J2:J1:imm6:imm11:0.
                    let imm6 = h1w & 0x3F;
                    let v = (s << 20) | (j2 << 19) | (j1 << 18) | (imm6 << 12) | (imm11 << 1);
                    direct.push(target(sext(v, 21)));
                } else if h2 & 0x5000 == 0x4000 {
                    indirect.push((pc, "BLX to ARM state".to_string()));
                }
            } else if h2 >> 12 == 0xF && (h1 & 0xFFF0 == 0xF8D0 || h1 == 0xF85F) {
                indirect.push((pc, "LDR pc".to_string()));
            }
            pc += 4;
        } else {
            if h1 & 0xF800 == 0xE000 {
                direct.push(target(sext(u32::from(h1 & 0x7FF) << 1, 12))); // B (T2)
            } else if h1 & 0xF000 == 0xD000 && (h1 >> 8) & 0xE != 0xE {
                direct.push(target(sext(u32::from(h1 & 0xFF) << 1, 9))); // B<c> (T1)
            } else if h1 & 0xF500 == 0xB100 {
                let off = (((h1 >> 9) & 1) << 6) | (((h1 >> 3) & 0x1F) << 1); // CB(N)Z
                direct.push(target(i64::from(off)));
            } else if h1 & 0xFF87 == 0x4780 {
                indirect.push((pc, format!("BLX r{}", (h1 >> 3) & 0xF)));
            } else if h1 & 0xFF87 == 0x4700 && (h1 >> 3) & 0xF != 14 {
                indirect.push((pc, format!("BX r{}", (h1 >> 3) & 0xF)));
            } else if h1 & 0xFF87 == 0x4687 {
                indirect.push((pc, "MOV pc".to_string()));
            }
            pc += 2;
        }
    }
    (direct, indirect)
}

/// Does this function mean "the program panics"?
fn is_panic_path(name: &str) -> bool {
    name.contains("panic")
        || name.contains("unwrap_failed")
        || name.contains("expect_failed")
        || name.contains("begin_unwind")
        || name.ends_with("_fail")
        || name.contains("assert_failed")
        || name.contains("unreachable")
        || name == "HardFault"
        || name == "firmware::exit"
        || name == "rust_begin_unwind"
}

/// Everything reachable from `root`; a call chain to the first panic path, if any.
struct Reach {
    funcs: Vec<usize>,
    panic_chain: Option<Vec<String>>,
    indirect: Vec<String>,
    unresolved: Vec<String>,
}

fn reach(elf: &Elf, root: &str) -> Reach {
    let r = elf.func_named(root);
    // Function -> (caller, address of the branch in the caller).
    let mut parent: BTreeMap<usize, (usize, u64)> = BTreeMap::new();
    let mut queue = VecDeque::from([r]);
    let mut seen = vec![r];
    let (mut indirect, mut unresolved) = (Vec::new(), Vec::new());
    let chain = |parent: &BTreeMap<usize, (usize, u64)>, mut i: usize| {
        let mut c = vec![elf.funcs[i].name.clone()];
        while let Some((p, at)) = parent.get(&i) {
            i = *p;
            c.push(format!("{} (branch at {at:#x})", elf.funcs[i].name));
        }
        c.reverse();
        c
    };
    let mut panic_chain = None;
    while let Some(i) = queue.pop_front() {
        let f = &elf.funcs[i];
        if is_panic_path(&f.name) {
            panic_chain.get_or_insert_with(|| chain(&parent, i));
            continue;
        }
        let (direct, ind) = branches(elf, f);
        for (pc, what) in ind {
            indirect.push(format!("{what} at {pc:#x} in {}", f.name));
        }
        for (at, t) in direct {
            match elf.func_at(t) {
                Some(j) if j == i => {}
                Some(j) => {
                    if !seen.contains(&j) {
                        seen.push(j);
                        parent.insert(j, (i, at));
                        queue.push_back(j);
                    }
                }
                None => unresolved.push(format!("{t:#x} from {}", f.name)),
            }
        }
    }
    Reach { funcs: seen, panic_chain, indirect, unresolved }
}

/// The entry points that must reach no panic: the twin's step, the profile lookup, and
/// (in the XiL binary, which must have it) the closed loop's step.
const ROOTS: [&str; 3] = ["simrod_step", "simrod_profile_at", "simrod_xil_step"];

#[test]
fn step_links_no_panic_path_and_no_allocator() {
    check_elfs(&fw::M4F, "plain");
}

/// The same check on the Cortex-M3's fixed-point build (its step: the fixed-point twin,
/// `fixed`'s operations and the 64-bit helpers of compiler-builtins).
#[test]
fn m3_fixed_point_step_links_no_panic_path_and_no_allocator() {
    check_elfs(&fw::M3_FIXED, "m3-fixed");
}

fn check_elfs(mcu: &fw::Mcu, variant: &str) {
    let dir = fw::build_firmware_on(mcu, variant, None);
    // Positive control: the check must see the canary's bounds check.
    let elf = load(&dir.join("simrod-trace"));
    let r = reach(&elf, "simrod_canary_index");
    let chain = r.panic_chain.expect(
        "the ELF check missed the panic of simrod_canary_index's unchecked index: \
         it would miss one in the step too",
    );
    assert!(chain.last().is_some_and(|n| n.contains("panic_bounds_check")), "{chain:?}");
    eprintln!("canary found: {}", chain.join(" -> "));
    for bin in mcu.binaries() {
        let elf = load(&dir.join(bin));
        let alloc: Vec<&String> = elf
            .names
            .iter()
            .filter(|n| {
                n.starts_with("__rust_alloc")
                    || n.starts_with("__rg_")
                    || n.starts_with("__rdl_")
                    || n.starts_with("alloc::")
                    || n.starts_with("<alloc::")
            })
            .collect();
        assert!(alloc.is_empty(), "{bin}: allocator symbols {alloc:?}");
        assert!(
            *bin != "simrod-xil" || elf.names.iter().any(|n| n == "simrod_xil_step"),
            "simrod-xil has no simrod_xil_step to check"
        );
        for root in
            ROOTS.iter().copied().filter(|r| *r != "simrod_xil_step" || elf.names.iter().any(|n| n == r))
        {
            let r = reach(&elf, root);
            let list: Vec<String> = r
                .funcs
                .iter()
                .map(|i| format!("{} ({} B)", elf.funcs[*i].name, elf.funcs[*i].size))
                .collect();
            if let Some(c) = &r.panic_chain {
                panic!(
                    "{bin}: `{root}` can reach a panic: {}\n(an unwrap, an unchecked \
                     index, a clamp with unproven bounds...? the step must not stop the bench.)\n\
                     Source lines: llvm-addr2line -i -f -C -e {} <branch address>",
                    c.join(" -> "),
                    dir.join(bin).display()
                );
            }
            assert!(
                r.indirect.is_empty(),
                "{bin}: `{root}` reaches indirect branches the check cannot follow:\n{}",
                r.indirect.join("\n")
            );
            assert!(
                r.unresolved.is_empty(),
                "{bin}: `{root}` branches outside any function:\n{}",
                r.unresolved.join("\n")
            );
            eprintln!("{bin}: {root} reaches {} functions, no panic: {}", list.len(), list.join(", "));
        }
    }
}
