//! Memory of the set-up stages (issue 25, BENCHMARKS.md "Issue 25: memory"): a counting global
//! allocator measures free cubes at re = 2.1 dp, two of the default operator (closure
//! included) and one of `corrected`; per set-up stage the peak within it and what is in use at
//! its end, then the peak of 3 steps with the strain-energy query of the outputs, in bytes per
//! particle; and, from the default operator's two cubes, the cost per particle at large sizes
//! (the difference of their figures over the difference of their particle counts) and the
//! fixed part (the closure's reduced box). The figures do not depend on the machine's load.
//!
//! ```text
//! cargo bench --bench memory -- [N1 N2]     # the default operator's cubes, default 30 40
//! ```
//! The memory tests (tests/limits_memory.rs) check the bounds on the same measurements.
#[path = "../tests/common/memory_counting.rs"]
mod counting;
use counting::{block_with, measure_stages, report, Counting};
use mps_solid::scene::memory;

#[global_allocator]
static GLOBAL: Counting = Counting;

fn main() {
    // `cargo bench` passes `--bench` to a harness-less bench: only numbers are sizes.
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let (n1, n2) = match sizes[..] {
        [a, b, ..] if a < b => (a, b),
        _ => (30, 40),
    };
    let mut rows = Vec::new();
    for (model, n) in [
        ("second_order", n1),
        ("second_order", n2),
        ("corrected", n2),
    ] {
        let s = block_with(3, n, 2.1, model);
        let np = n * n * n;
        let m = measure_stages(&s, 3);
        report(&format!("{model} {n}^3"), np, &m);
        let e = memory::estimate(&s);
        println!(
            "{model} {n}^3: the memory guard's estimate {:.0} B/particle, {:.2} times the peak",
            e.bytes as f64 / np as f64,
            e.bytes as f64 / m.peak() as f64
        );
        rows.push((np, m));
    }
    let (a, b) = (&rows[0], &rows[1]);
    let mut lines: Vec<(String, usize, usize)> =
        a.1.stages
            .iter()
            .zip(&b.1.stages)
            .map(|(x, y)| (format!("{} peak", x.0.name()), x.1, y.1))
            .collect();
    lines.push(("built world".into(), a.1.built, b.1.built));
    lines.push(("steps peak".into(), a.1.steps_peak, b.1.steps_peak));
    lines.push(("peak overall".into(), a.1.peak(), b.1.peak()));
    for (what, fa, fb) in lines {
        let slope = (fb as f64 - fa as f64) / (b.0 - a.0) as f64;
        println!(
            "second_order {what}: {slope:.0} B/particle at large sizes, fixed {:.1} MB",
            (fa as f64 - slope * a.0 as f64) / 1e6
        );
    }
}
