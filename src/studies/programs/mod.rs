//! One-off studies and diagnostics behind `mps study NAME [ARGS...]`: each answered a question of
//! the accuracy work (docs/model.md, BENCHMARKS.md cite them) and is kept so that its figures can
//! be reproduced. Each reads its arguments like a program (`args[0]` is its name).
pub mod bending;
pub mod case1_edge;
pub mod clamp;
pub mod closure;
pub mod consistency;
pub mod cutface;
pub mod elastica;
pub mod family;
pub mod floor;
pub mod fold;
pub mod fracture;
pub mod fracture_energy_dt;
pub mod ghost;
pub mod stiffest;
pub mod throughput;
pub mod torsion;

/// The studies by name, with their one-line descriptions (for `mps study --list`).
pub const PROGRAMS: &[(&str, &str)] = &[
    ("bending", "linearised f1 and static tip of the GMS plate and the slender cantilever by operator and resolution"),
    ("case1_edge", "case 1's lateral displacement near the free end against the closed form (linearised)"),
    ("clamp", "a clamped axial bar under its weight (exact quadratic field): computed against exact displacement"),
    ("closure", "the summation-by-parts closure's build: CG iterations, residuals and time per axis (`-- cube N`)"),
    ("consistency", "case 1's exact field against the discrete equilibrium: residual forces by layer"),
    ("cutface", "the GMS plate written as a box shape with its faces cutting cells: residuals of a quadratic stress (`-- 8 0 0.5`), free-free f1 (`-- free`), wall layers (`-- walls`), another Poisson ratio (`-- nu 0`)"),
    ("elastica", "large deflection of the slender cantilever against the elastica and the finite-strain FEM"),
    ("family", "issue 24's family written as a user would (clamps without mirror, stepped, L-bracket, hole): linearised f1 and static deflection against the FEM (`-- 4 8`, THREE_D=1 adds 3D)"),
    ("floor", "the machine's floor: multiply-add peak, triad bandwidth, and the least time per bond of each force pass"),
    ("fold", "the folding small2d strip that blew up at safety 0.8: deformation gradients and tangent spectrum"),
    ("fracture", "case 3's largest bond strain over time for the corrected and second-order operators"),
    ("fracture_energy_dt", "whether breaks create energy at time steps below the automatic one"),
    ("ghost", "mirror faces against the grip on the axial bar, plate and cantilever"),
    ("stiffest", "where the stiffest mode of case 1, case 2 or the cantilever sits: the place that sets the stable step (`-- case1 second_order 400`)"),
    ("throughput", "single-thread force-loop throughput of each operator on case 2 (pair-updates/s)"),
    ("torsion", "first torsion frequency of the slender cantilever near incompressibility"),
];

/// Runs the study `name` with `args` (`args[0]` is the program name). Err: no such study.
pub fn run(name: &str, args: Vec<String>) -> Result<(), String> {
    match name {
        "bending" => {
            bending::main(args);
        }
        "case1_edge" => {
            case1_edge::main(args);
        }
        "clamp" => {
            clamp::main(args);
        }
        "closure" => {
            closure::main(args);
        }
        "consistency" => {
            consistency::main(args);
        }
        "cutface" => {
            cutface::main(args);
        }
        "elastica" => {
            elastica::main(args);
        }
        "family" => {
            family::main(args);
        }
        "floor" => {
            floor::main(args);
        }
        "fold" => {
            fold::main(args);
        }
        "fracture" => {
            fracture::main(args);
        }
        "fracture_energy_dt" => {
            fracture_energy_dt::main(args);
        }
        "ghost" => {
            ghost::main(args);
        }
        "stiffest" => {
            stiffest::main(args);
        }
        "throughput" => {
            throughput::main(args);
        }
        "torsion" => {
            torsion::main(args);
        }
        _ => {
            return Err(format!(
                "no study named {name:?}; `mps study --list` lists them"
            ))
        }
    }
    Ok(())
}
