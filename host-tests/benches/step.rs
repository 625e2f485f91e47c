//! `cargo bench -p host-tests --bench step [-- --quick]`: host cost of the twin, one
//! `Model::step` and whole TP07 runs at 1 ms and 100 µs (ns per step, steps per
//! second, real-time factor). A plain harness (no criterion): medians of wall-clock
//! repetitions on one thread and an undisturbed estimate, see `host_tests::hostbench`. `cargo xtask bench-rt`
//! prints the same cases next to the target's numbers.

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let cases = host_tests::hostbench::run(quick);
    print!("{}", host_tests::hostbench::table(&cases));
    let aim = host_tests::rt::AIM_HOST_STEPS_PER_S;
    if let Some(step) = cases.first() {
        // Undisturbed: other processes only add time (the median shows the load).
        let best = step.steps_per_s_min();
        println!(
            "aim >= {:.0} M steps/s on one core (Model::step, undisturbed): {} ({:.2} M steps/s)",
            aim / 1e6,
            if best >= aim { "met" } else { "missed" },
            best / 1e6
        );
    }
}
