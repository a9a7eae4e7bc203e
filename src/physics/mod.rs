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

pub use dim::{Dim, Mat, Space, Vect};
pub use params::{BondStrain, ContactOptions, ElasticModel, Material, MaterialLaw, SolverOptions};
pub use world::{duration_text, BodyInit, InitialVelocity, SimError, World};
