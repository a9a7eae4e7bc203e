//! The machine's floor for the force loops (issue 25): peak multiply-add rate of this build
//! (f64 and f32, 1 and 2 threads; independent accumulators, so no latency bound), memory
//! bandwidth (a STREAM triad a = b + s c over arrays far larger than the caches, 1 and 2
//! threads), and from them the least time per bond of a pass with a given count of flops and
//! bytes. `cargo run --release -- study floor [seconds per measurement]`.
//!
//! The binary is built for the baseline x86-64 instruction set (SSE2: 2 f64 or 4 f32 lanes, no
//! FMA instruction), like the FMU's; the figures are what this build's loops can reach.
use crate::physics::ElasticModel;
use crate::sim::Simulation;
use crate::studies::peers;
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;

/// Accumulators per kernel: enough independent chains to hide the add latency.
const CHAINS: usize = 32;

macro_rules! madd_kernel {
    ($name:ident, $t:ty) => {
        /// `iters` rounds of acc = acc * a + b over CHAINS accumulators: 2 CHAINS flops each.
        fn $name(iters: u64, a: $t, b: $t) -> $t {
            let mut acc = [0.0 as $t; CHAINS];
            for (k, x) in acc.iter_mut().enumerate() {
                *x = k as $t * 1e-3;
            }
            for _ in 0..iters {
                for x in acc.iter_mut() {
                    *x = *x * a + b;
                }
            }
            acc.iter().sum()
        }
    };
}
madd_kernel!(madd_f64, f64);
madd_kernel!(madd_f32, f32);

/// The f64 kernel with fused multiply-adds, compiled as the default operator's force passes are
/// (AVX-512, AVX2 + FMA, baseline; the best this CPU has is chosen at run time). LLVM keeps its
/// chains scalar (`vfmadd213sd`: the vectoriser does not pack independent chains of one
/// operation), so it measures the FMA units' issue rate per lane; times the lanes of the widest
/// vectors ([`vector_lanes`]) it is the peak of the passes' vector code.
#[multiversion::multiversion(
    targets(
        "x86_64+avx512f+avx512vl+avx512dq+avx512bw+avx2+fma",
        "x86_64+avx2+fma"
    ),
    dispatcher = "direct"
)]
fn fma_f64(iters: u64, a: f64, b: f64) -> f64 {
    let mut acc = [0.0f64; CHAINS];
    for (k, x) in acc.iter_mut().enumerate() {
        *x = k as f64 * 1e-3;
    }
    for _ in 0..iters {
        for x in acc.iter_mut() {
            *x = x.mul_add(a, b);
        }
    }
    acc.iter().sum()
}

/// f64 lanes of the widest vectors the default operator's passes run with on this CPU.
fn vector_lanes() -> f64 {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return 8.0;
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return 4.0;
        }
    }
    2.0
}

/// Which multiply-add kernel a rate measures.
#[derive(Clone, Copy)]
enum Kernel {
    BaselineF64,
    BaselineF32,
    FmaF64,
}

/// Flops per second of the multiply-add kernel on `threads` threads at once.
fn madd_rate(kernel: Kernel, threads: usize, seconds: f64) -> f64 {
    let run = |iters: u64| -> f64 {
        let t0 = Instant::now();
        let work = |_k: usize| {
            let (a, b) = (black_box(0.999_9), black_box(1e-4));
            match kernel {
                Kernel::BaselineF32 => black_box(madd_f32(iters, a as f32, b as f32)) as f64,
                Kernel::BaselineF64 => black_box(madd_f64(iters, a, b)),
                Kernel::FmaF64 => black_box(fma_f64(iters, a, b)),
            }
        };
        #[cfg(feature = "parallel")]
        let s: f64 = (0..threads).into_par_iter().map(work).sum();
        #[cfg(not(feature = "parallel"))]
        let s: f64 = (0..threads).map(work).sum();
        black_box(s);
        t0.elapsed().as_secs_f64()
    };
    let mut iters = 1u64 << 16;
    while run(iters) < 0.05 {
        iters *= 2;
    }
    let iters = ((iters as f64) * seconds / run(iters).max(1e-9)) as u64;
    let t = run(iters.max(1));
    2.0 * CHAINS as f64 * iters as f64 * threads as f64 / t
}

/// Bytes per second of the triad a = b + s c (24 bytes per element: two reads, one write)
/// over arrays of 2^24 f64 (128 MB each) on `threads` threads.
fn triad_rate(threads: usize, seconds: f64) -> f64 {
    let n = 1usize << 24;
    let b = vec![1.0f64; n];
    let c = vec![2.0f64; n];
    let mut a = vec![0.0f64; n];
    let s = black_box(0.5);
    let mut best = f64::INFINITY;
    let t_end = Instant::now();
    while t_end.elapsed().as_secs_f64() < seconds || best == f64::INFINITY {
        let t0 = Instant::now();
        let chunk = n.div_ceil(threads);
        #[cfg(feature = "parallel")]
        a.par_chunks_mut(chunk)
            .zip(b.par_chunks(chunk).zip(c.par_chunks(chunk)))
            .for_each(|(a, (b, c))| {
                for ((a, b), c) in a.iter_mut().zip(b).zip(c) {
                    *a = b + s * c;
                }
            });
        #[cfg(not(feature = "parallel"))]
        for ((a, b), c) in a.iter_mut().zip(&b).zip(&c) {
            let _ = chunk;
            *a = b + s * c;
        }
        black_box(&a);
        best = best.min(t0.elapsed().as_secs_f64());
    }
    24.0 * n as f64 / best
}

/// Flops and bytes per directed bond of each pass of the force loops, counted from the code
/// (3D, re = 2.1 dp, 32 bonds a particle): (operator, pass, flops, bytes streamed per bond).
/// A multiply-add counts 2; a square root or division 1 (each takes the time of several).
/// Bytes: what the pass reads and writes per bond from arrays larger than the caches (the
/// neighbour's state is assumed cached: neighbours are near in memory on a lattice).
pub const PASS_COUNTS: &[(&str, &str, f64, f64)] = &[
    // F_i += (r om) r0^T: r = r0 + du (3 add), r om (3 mul), outer product (9 madd);
    // bytes: nbr 4 + r0 24 + w0 8.
    (
        "corrected",
        "1: deformation gradient",
        3.0 + 3.0 + 3.0 + 18.0 + 1.0,
        36.0,
    ),
    // ((B_i + B_j) r0 + (r0 + du) s kv) om: 9 add, 9 madd, 3+3 add/mul, 3 mul, 3 add;
    // bytes: nbr 4 + r0 24 + w0 8 (B_j cached).
    (
        "corrected",
        "2: forces",
        9.0 + 18.0 + 6.0 + 3.0 + 3.0 + 3.0 + 1.0,
        36.0,
    ),
    // du (3), H += du g^T (9 madd), G^(a) += du h_a^T (27 madd); weight check;
    // residual: G r0 r0 (27 madd + 3 mul), H r0 (9 madd), res (6); direction: r (3), |r| (5 + sqrt),
    // n (3 div); res.n (5), conj (6+1), direct (6+3); rho r0^T (9 mul), A -= (9), B^(a) -= (27 madd);
    // bytes: nbr 4 + w0 8 + out 24 (write) = 36. The weights g and h, the snapped r0, 1/|r0|
    // and the bond's fit flag (14 values per bond) come from the particle's interned set
    // (physics::stencils: a few hundred sets per body, cache-resident), by groups of bonds
    // (second_order::lanes). Before the interning they were 96 B per bond from memory, read
    // twice: 157 + 96 B; before the groups (issue 25) r0 and the flag were read per bond: 61 B.
    (
        "second_order",
        "1: fits, stress, residuals, dE/d du",
        3.0 + 18.0 + 54.0 + 54.0 + 3.0 + 18.0 + 6.0 + 3.0 + 6.0 + 3.0 + 5.0 + 7.0 + 9.0 + 9.0 + 9.0 + 54.0
            // out: A g (9 madd), B^(a) h_a (27 madd), add (3)
            + 18.0 + 54.0 + 3.0,
        36.0,
    ),
    // f_i = own_i - sum_b dbond_mirror(b) (own_i summed in pass 1): 3; bytes: mirror position
    // 4 + dbond (random) 24.
    ("second_order", "2: gather", 3.0, 28.0),
];

pub fn main(args: Vec<String>) {
    let seconds: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1.0);
    println!("## The machine's floor (`mps study floor`)\n");
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into());
    println!(
        "CPU: {cpu}; build: baseline x86-64 (SSE2, no FMA instruction) for the corrected \
         operator's passes; the default operator's passes are compiled for AVX-512 and AVX2 + \
         FMA too, and run the widest this CPU has.\n"
    );
    println!("| measurement | 1 thread | 2 threads |\n|---|---|---|");
    let f64_1 = madd_rate(Kernel::BaselineF64, 1, seconds);
    let f64_2 = madd_rate(Kernel::BaselineF64, 2, seconds);
    let f32_1 = madd_rate(Kernel::BaselineF32, 1, seconds);
    let f32_2 = madd_rate(Kernel::BaselineF32, 2, seconds);
    let fma_s1 = madd_rate(Kernel::FmaF64, 1, seconds);
    let fma_s2 = madd_rate(Kernel::FmaF64, 2, seconds);
    let lanes = vector_lanes();
    let (fma_1, fma_2) = (fma_s1 * lanes, fma_s2 * lanes);
    let vector_row =
        format!("fused multiply-add, f64, scalar x {lanes:.0} lanes (GFlop/s, the vector peak)");
    let rows = [
        ("multiply-add, f64, baseline (GFlop/s)", f64_1, f64_2),
        ("multiply-add, f32, baseline (GFlop/s)", f32_1, f32_2),
        ("fused multiply-add, f64, scalar (GFlop/s)", fma_s1, fma_s2),
        (vector_row.as_str(), fma_1, fma_2),
    ];
    for (name, one, two) in rows {
        println!("| {name} | {:.2} | {:.2} |", one / 1e9, two / 1e9);
    }
    let bw1 = triad_rate(1, seconds);
    let bw2 = triad_rate(2, seconds);
    println!(
        "| triad a = b + s c (GB/s) | {:.2} | {:.2} |",
        bw1 / 1e9,
        bw2 / 1e9
    );
    // Each pass's least time per bond on `threads` threads: its flops at the rate of the code
    // it runs as (the default operator's vector FMA, the corrected operator's baseline), or its
    // bytes at the triad's bandwidth, whichever is longer.
    let floor_ns = |op: &str, flops: f64, bytes: f64, one: bool| -> (f64, f64) {
        let rate = match (op == "second_order", one) {
            (true, true) => fma_1,
            (true, false) => fma_2,
            (false, true) => f64_1,
            (false, false) => f64_2,
        };
        let bw = if one { bw1 } else { bw2 };
        (flops / rate * 1e9, bytes / bw * 1e9)
    };
    println!("\nLeast time per bond of each pass on 2 threads (flops at the rate of the code the pass runs as, bytes at the triad's bandwidth; the larger is the floor), for 32 bonds a particle as us per particle-step:\n");
    println!("| operator | pass | flops/bond | bytes/bond | compute floor (ns/bond) | memory floor (ns/bond) | floor, us per particle-step |\n|---|---|---|---|---|---|---|");
    for (op, pass, flops, bytes) in PASS_COUNTS {
        let (c, m) = floor_ns(op, *flops, *bytes, false);
        println!(
            "| {op} | {pass} | {flops:.0} | {bytes:.0} | {c:.3} | {m:.3} | {:.3} |",
            32.0 * c.max(m) / 1e3
        );
    }
    // Against what the loops do: one thread, the 3D lattice the counts are for (the peers'
    // cube, `mps bench --peers`, at 20^3 so that the default operator's set-up stays short),
    // whole steps (both passes, integration and supports), per directed bond.
    println!("\nMeasured against the floor, one thread, whole steps per directed bond (the peers' 3D cube at {MEASURED_N}^3 particles, dp 0.025 m, fixed dt 1e-5 s: the best of 3 runs of {MEASURED_STEPS} steps; the floor is the sum of the operator's passes above, so integration and supports are in the measured figure only):\n");
    println!("| operator | floor (ns per directed bond) | measured (ns per directed bond) | measured / floor |\n|---|---|---|---|");
    for (name, model) in [
        ("corrected", ElasticModel::Corrected),
        ("second_order", ElasticModel::SecondOrder),
    ] {
        let floor: f64 = PASS_COUNTS
            .iter()
            .filter(|(op, ..)| *op == name)
            .map(|(op, _, flops, bytes)| {
                let (c, m) = floor_ns(op, *flops, *bytes, true);
                c.max(m)
            })
            .sum();
        match measured_ns_per_bond(model) {
            Ok(measured) => println!(
                "| {name} | {floor:.2} | {measured:.2} | {:.2} |",
                measured / floor
            ),
            Err(e) => println!("| {name} | {floor:.2} | the run failed: {e} | |"),
        }
    }
}

/// Side of the cube the loops are measured on, and the steps timed per run.
const MEASURED_N: usize = 20;
const MEASURED_STEPS: u64 = 100;

/// Wall time per directed bond of whole steps on one thread: the peers' cube (3D, re 2.1 dp, the
/// bottom layer held), best of 3 runs of MEASURED_STEPS steps after one untimed step.
fn measured_ns_per_bond(model: ElasticModel) -> Result<f64, String> {
    const DT: f64 = 1e-5;
    let scene = peers::cube_scene(MEASURED_N, 0.025, model, DT);
    peers::with_threads(1, || {
        let mut sim = Simulation::new(&scene).map_err(|e| e.to_string())?;
        let directed = 2.0 * sim.bonds() as f64;
        let mut best = f64::INFINITY;
        let mut t = DT;
        sim.advance_to(t).map_err(|e| e.to_string())?;
        for _ in 0..3 {
            let (s0, t0) = (sim.steps(), Instant::now());
            t += MEASURED_STEPS as f64 * DT;
            sim.advance_to(t).map_err(|e| e.to_string())?;
            let per_step = t0.elapsed().as_secs_f64() / (sim.steps() - s0) as f64;
            best = best.min(per_step);
        }
        Ok(best / directed * 1e9)
    })?
}
