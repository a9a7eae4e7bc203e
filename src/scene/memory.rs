//! Memory a scene needs and memory the machine has: the estimate is checked before the world is
//! allocated, so that a scene too big for the machine is an error naming the particle count and
//! the estimate instead of an abort (or the OOM killer) in the middle of the build.
use super::limits::num;
use super::{err, Scene, SceneError};
use crate::physics::ElasticModel;

/// Bytes per particle besides its bonds (2D, 3D) and per stored (directed) bond of the operators
/// with first-order fits (corrected, paper): the peak of `Simulation::new` measured with a
/// counting allocator (tests/limits_memory.rs; `CALIBRATE=1` prints the figures) is exactly
/// linear in the bonds per particle: about 440 + 36 nb bytes in 2D, 825 + 44 nb in 3D (nbr 4,
/// r0 8 D, w0 8 and the force passes' 1 / |r0|^2 8 bytes per bond), at re = 1.5, 2.1 and 3 dp
/// and 8,000 to 250,000 particles (853 B per particle in 2D and 2177 B in 3D at re = 2.1 dp). The constants add about 15 % for what grows
/// during a run (contact pair lists, the fracture screen's records and cells: with eps_max set,
/// a 30^3 `corrected` cube's peak over three steps is 2,173 B per particle against 2,535
/// estimated, a 20^3 `second_order` cube's 3,956 against 4,890,
/// tests/limits_memory.rs::the_estimate_bounds_a_fracture_scene_with_its_strain_screen) and the
/// allocator.
const BASE_BYTES: [u64; 2] = [512, 960];
const BOND_BYTES: [u64; 2] = [40, 48];
/// The same for `second_order`, which stores per bond the position of its reverse bond's output
/// and per particle its fits' flags, span and the indices of its interned weight and geometry
/// sets (src/physics/stencils.rs), and keeps per bond the conjugates of its force pass (padded
/// to whole groups of bonds: src/physics/second_order/lanes.rs). Its peak is the first stable-step
/// measurement (the power iteration's force pass beside the world) for a body larger than the
/// closure's reduced box, the closure below otherwise. Measured after issue 25
/// (`cargo bench --bench memory` per stage, tests/limits_memory.rs with `CALIBRATE=...` for the
/// totals): 3D at re = 2.1 dp, stable step 2,642 B per particle at large sizes (30^3 and 40^3
/// cubes) plus 6.6 MB, peaks of 2,796 and 2,746 B per particle at 35^3 and 40^3; 2D peaks of
/// 757, 949-953 and 1,656 B per particle at re = 1.5, 2.1 and 3 dp (8, 12 and 28 bonds),
/// i.e. 49 B per bond. Fitted as an upper bound with about 5 % to spare. With the force loop's
/// groups of bonds (padding, the geometry sets), 2,894 B per particle at 35^3 (was 2,844) and
/// 2D peaks of 790, 988 and 1,717 B per particle. Before issue 25's
/// memory work: 3,783 B per particle in 3D at large sizes, 7,000-7,550 before the interning.
const SECOND_ORDER_BASE_BYTES: [u64; 2] = [400, 800];
const SECOND_ORDER_BOND_BYTES: [u64; 2] = [49, 66];
/// The summation-by-parts closure of a second_order body (src/physics/sbp/) builds the operator
/// once more on a reduced box of at most 15 layers a side (17 before 2026-12-06) during the build, with its
/// conjugate-gradient systems: `CLOSURE_BOX_BYTES` per particle of the reduced box (min of the
/// body's particles and 15^D), on top of `CLOSURE_SHARE` of the per-particle cost of the whole
/// world for what the body holds by then (bonds, fits). Measured in 3D at re = 2.1 dp: 1,700 B
/// per particle plus 39.6 MB (8.06 kB per box particle) from the 25^3 and 30^3 cubes, whose
/// peak was the closure; since its solve keeps its monomials per lattice stencil and its tied
/// corrections per class (2026-12-07, fifteenth session) the peaks of the 15^3, 20^3 and 25^3
/// cubes are 26.65, 31.65 and 50.45 MB (66.2 MB at 25^3 before), bounded with 7.0 kB per box
/// particle (30.8, 39.1 and 52.9 MB); at 30^3 the stable step's is the peak. 2D: the figure
/// measured before issue 25 (31 kB per box particle), an upper bound not measured again (the
/// 2D box has at most 289 particles).
const CLOSURE_LAYERS: f64 = 15.0;
const CLOSURE_BOX_BYTES: [f64; 2] = [31_000.0, 7_000.0];
const CLOSURE_SHARE: f64 = 0.62;
/// Fixed cost of a world whatever its size (bytes).
const FIXED_BYTES: u64 = 1 << 20;

/// What a scene needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryEstimate {
    /// Particles the boxes can hold (an upper bound: overlapping boxes drop some).
    pub particles: u64,
    /// Bonds per interior particle: lattice neighbours within re = re_factor dp.
    pub bonds_per_particle: u64,
    /// Bytes per particle, bonds included.
    pub bytes_per_particle: u64,
    /// Total (bytes).
    pub bytes: u64,
}

/// Memory the process may still use, and where the figure comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct Available {
    pub bytes: u64,
    pub source: String,
}

/// At most the bonds of an interior particle (12 in 2D and 32 in 3D for re = 2.1 dp; see
/// `physics::bonds::max_lattice_neighbours`).
pub fn lattice_neighbours(dimension: usize, re_factor: f64) -> u64 {
    crate::physics::bonds::max_lattice_neighbours(dimension, 1.0, re_factor.clamp(0.0, 16.0)) as u64
}

/// The memory a scene needs once built (an upper bound of the peak of the build).
pub fn estimate(scene: &Scene) -> MemoryEstimate {
    let d = if scene.dimension == 3 { 1 } else { 0 };
    let particles = scene.particle_bound();
    let nb = lattice_neighbours(scene.dimension, scene.solver.re_factor);
    let (per, world) = if scene.solver.model == ElasticModel::SecondOrder {
        let per = SECOND_ORDER_BASE_BYTES[d] + nb * SECOND_ORDER_BOND_BYTES[d];
        let closure: f64 = scene
            .bodies
            .iter()
            .map(|b| {
                scene
                    .body_particle_bound(b)
                    .min(CLOSURE_LAYERS.powi(scene.dimension as i32))
            })
            .sum();
        // The larger of the two peaks: the stable step's and the closure's.
        let stable = particles * per as f64;
        let closing = particles * per as f64 * CLOSURE_SHARE + closure * CLOSURE_BOX_BYTES[d];
        (per, stable.max(closing))
    } else {
        let per = BASE_BYTES[d] + nb * BOND_BYTES[d];
        (per, particles * per as f64)
    };
    let bytes = (world + FIXED_BYTES as f64).min(u64::MAX as f64) as u64;
    MemoryEstimate {
        particles: particles.min(u64::MAX as f64) as u64,
        bonds_per_particle: nb,
        bytes_per_particle: per,
        bytes,
    }
}

/// "1.5 GB" (decimal units).
pub fn bytes_text(b: u64) -> String {
    let b = b as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else {
        format!("{:.0} kB", (b / 1e3).ceil())
    }
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

/// The value of `key:` in a /proc file whose lines read "Key:   1234 kB" (bytes).
fn kb_field(text: &str, key: &str) -> Option<u64> {
    text.lines().find_map(|l| {
        let rest = l.strip_prefix(key)?.strip_prefix(':')?;
        let v: u64 = rest.split_whitespace().next()?.parse().ok()?;
        Some(v.saturating_mul(1024))
    })
}

/// The memory the process may still use: the least of MemAvailable, the headroom under the
/// cgroup's memory limit (v2 memory.max or v1 memory.limit_in_bytes) and the headroom under the
/// address-space limit (ulimit -v). None when nothing can be read (not Linux).
pub fn available() -> Option<Available> {
    let mut best: Option<Available> = None;
    let mut consider = |bytes: u64, source: String| {
        if best.as_ref().is_none_or(|b| bytes < b.bytes) {
            best = Some(Available { bytes, source });
        }
    };
    if let Some(v) = read("/proc/meminfo").and_then(|t| kb_field(&t, "MemAvailable")) {
        consider(v, "MemAvailable in /proc/meminfo".into());
    }
    // cgroup v2: the process's own group (from /proc/self/cgroup), then the namespace root.
    let own = read("/proc/self/cgroup").and_then(|t| {
        t.lines()
            .find_map(|l| l.strip_prefix("0::").map(|p| p.trim().to_string()))
    });
    let mut dirs = Vec::new();
    if let Some(p) = own.filter(|p| p != "/") {
        dirs.push(format!("/sys/fs/cgroup{p}"));
    }
    dirs.push("/sys/fs/cgroup".into());
    for dir in dirs {
        let max = read(&format!("{dir}/memory.max"));
        if let Some(limit) = max.and_then(|t| t.trim().parse::<u64>().ok()) {
            let used = read(&format!("{dir}/memory.current"))
                .and_then(|t| t.trim().parse::<u64>().ok())
                .unwrap_or(0);
            consider(
                limit.saturating_sub(used),
                format!("cgroup limit {dir}/memory.max = {}", bytes_text(limit)),
            );
        }
    }
    // cgroup v1.
    if let Some(limit) = read("/sys/fs/cgroup/memory/memory.limit_in_bytes")
        .and_then(|t| t.trim().parse::<u64>().ok())
        .filter(|&l| l < (1 << 60))
    {
        let used = read("/sys/fs/cgroup/memory/memory.usage_in_bytes")
            .and_then(|t| t.trim().parse::<u64>().ok())
            .unwrap_or(0);
        consider(
            limit.saturating_sub(used),
            format!("cgroup limit memory.limit_in_bytes = {}", bytes_text(limit)),
        );
    }
    // Address space (ulimit -v): the soft limit less what is mapped now.
    if let Some(limit) = read("/proc/self/limits").and_then(|t| {
        t.lines()
            .find(|l| l.starts_with("Max address space"))
            .and_then(|l| l["Max address space".len()..].split_whitespace().next())
            .and_then(|v| v.parse::<u64>().ok())
    }) {
        let mapped = read("/proc/self/status")
            .and_then(|t| kb_field(&t, "VmSize"))
            .unwrap_or(0);
        consider(
            limit.saturating_sub(mapped),
            format!("address-space limit (ulimit -v) {}", bytes_text(limit)),
        );
    }
    best
}

/// Refuses a scene whose estimate exceeds `available` (no check when it is unknown).
pub fn check_against(scene: &Scene, available: Option<&Available>) -> Result<(), SceneError> {
    let e = estimate(scene);
    match available {
        Some(a) if e.bytes > a.bytes => Err(err(
            "bodies",
            format!(
                "the scene has up to {} particles, which need about {} (estimate: {} bytes per \
                 particle with {} bonds each), more than the {} of memory available ({}); use a \
                 larger particle_spacing or fewer boxes",
                e.particles,
                bytes_text(e.bytes),
                e.bytes_per_particle,
                e.bonds_per_particle,
                bytes_text(a.bytes),
                a.source
            ),
        )),
        _ => Ok(()),
    }
}

/// Refuses a scene that does not fit in the memory this process may still use.
pub fn check(scene: &Scene) -> Result<(), SceneError> {
    check_against(scene, available().as_ref())
}

/// The particle count in a message: "N particles (about X)".
pub(crate) fn particles_text(scene: &Scene) -> String {
    let e = estimate(scene);
    format!(
        "{} particles (about {} of memory)",
        num(e.particles as f64),
        bytes_text(e.bytes)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_of_the_lattice() {
        assert_eq!(lattice_neighbours(2, 2.1), 12);
        assert_eq!(lattice_neighbours(3, 2.1), 32);
        // pairs at exactly re count (an upper bound: round-off may bond them)
        assert_eq!(lattice_neighbours(2, 1.0), 4);
        assert_eq!(lattice_neighbours(3, 1.5), 18);
    }

    #[test]
    fn proc_fields() {
        let t = "MemTotal:       24000000 kB\nMemAvailable:    1000 kB\n";
        assert_eq!(kb_field(t, "MemAvailable"), Some(1024000));
        assert_eq!(kb_field(t, "Mem"), None);
    }

    #[test]
    fn this_machine_reports_memory() {
        let a = available().expect("Linux has /proc/meminfo");
        assert!(a.bytes > 0, "{a:?}");
    }
}
