//! The machine's floor for the force loops (issue 25): peak multiply-add rate of this build
//! (f64 and f32, 1 and 2 threads; independent accumulators, so no latency bound), memory
//! bandwidth (a STREAM triad a = b + s c over arrays far larger than the caches, 1 and 2
//! threads), and from them the least time per bond of a pass with a given count of flops and
//! bytes. `cargo run --release -- study floor [seconds per measurement]`.
//!
//! The binary is built for the baseline x86-64 instruction set (SSE2: 2 f64 or 4 f32 lanes, no
//! FMA instruction), like the FMU's; the figures are what this build's loops can reach.
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

/// Flops per second of the multiply-add kernel on `threads` threads at once.
fn madd_rate(single: bool, threads: usize, seconds: f64) -> f64 {
    let run = |iters: u64| -> f64 {
        let t0 = Instant::now();
        let work = |_k: usize| {
            if single {
                black_box(madd_f32(iters, black_box(0.999_9), black_box(1e-4))) as f64
            } else {
                black_box(madd_f64(iters, black_box(0.999_9), black_box(1e-4)))
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
    println!("CPU: {cpu}; build: baseline x86-64 (SSE2, no FMA instruction).\n");
    println!("| measurement | 1 thread | 2 threads |\n|---|---|---|");
    let f64_1 = madd_rate(false, 1, seconds);
    let f64_2 = madd_rate(false, 2, seconds);
    let f32_1 = madd_rate(true, 1, seconds);
    let f32_2 = madd_rate(true, 2, seconds);
    println!(
        "| multiply-add, f64 (GFlop/s) | {:.2} | {:.2} |",
        f64_1 / 1e9,
        f64_2 / 1e9
    );
    println!(
        "| multiply-add, f32 (GFlop/s) | {:.2} | {:.2} |",
        f32_1 / 1e9,
        f32_2 / 1e9
    );
    let bw1 = triad_rate(1, seconds);
    let bw2 = triad_rate(2, seconds);
    println!(
        "| triad a = b + s c (GB/s) | {:.2} | {:.2} |",
        bw1 / 1e9,
        bw2 / 1e9
    );
    println!("\nLeast time per bond of each pass on 2 threads (flops / the f64 rate, bytes / the bandwidth; the larger is the floor), for 32 bonds a particle as us per particle-step:\n");
    println!("| operator | pass | flops/bond | bytes/bond | compute floor (ns/bond) | memory floor (ns/bond) | floor, us per particle-step |\n|---|---|---|---|---|---|---|");
    for (op, pass, flops, bytes) in PASS_COUNTS {
        let c = flops / f64_2 * 1e9;
        let m = bytes / bw2 * 1e9;
        println!(
            "| {op} | {pass} | {flops:.0} | {bytes:.0} | {c:.3} | {m:.3} | {:.3} |",
            32.0 * c.max(m) / 1e3
        );
    }
}
