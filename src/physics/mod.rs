//! The MPS solver core: particles, bonds, neighbour search, elastic operators, boundary
//! conditions, time integration. Knows nothing of scene files, FMI or output formats.
pub mod bonds;
pub mod boundary;
pub mod cell_term;
pub mod contact;
pub mod dim;
pub mod elastic;
pub mod fracture;
pub mod ghosts;
pub mod grid;
pub mod integrate;
pub mod law;
pub mod params;
pub mod particles;
pub mod sbp;
pub mod second_order;
pub mod shape;
pub mod stencil_build;
pub mod stencils;
pub mod strain_screen;
pub mod world;

pub mod par;

/// Iterates mutably over a slice in parallel ([`par::ParMut`]: on the installed executor, else
/// rayon with the `parallel` feature, else serially). Every use gathers into its own element,
/// so results do not depend on the thread count.
#[macro_export]
macro_rules! par_iter_mut {
    ($t:expr) => {
        $crate::physics::par::ParMut(&mut $t[..])
    };
}

/// Compiles a force pass for AVX-512 and for AVX2 + FMA besides the baseline x86-64 and chooses
/// the widest the CPU has at run time (the `multiversion` crate; the FMU's binary stays
/// portable). A pass with no fused operations gives the same bits in every version. The fuzz
/// targets (`cfg(fuzzing)`, set by cargo-fuzz) compile the baseline only: they test the logic,
/// and the instrumented copies cost their build most of its time.
macro_rules! cpu_versions {
    ($f:item) => {
        #[cfg_attr(
            not(fuzzing),
            multiversion::multiversion(
                targets(
                    "x86_64+avx512f+avx512vl+avx512dq+avx512bw+avx2+fma",
                    "x86_64+avx2+fma"
                ),
                dispatcher = "direct"
            )
        )]
        $f
    };
}
pub(crate) use cpu_versions;

pub use dim::{Dim, Mat, Space, Vect};
pub use params::{BondStrain, ContactOptions, ElasticModel, Material, MaterialLaw, SolverOptions};
pub use world::{duration_text, BodyInit, InitialVelocity, SimError, World};
