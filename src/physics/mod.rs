//! The MPS solver core: particles, bonds, neighbour search, elastic operators, boundary
//! conditions, time integration. Knows nothing of scene files, FMI or output formats.
pub mod bonds;
pub mod boundary;
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

/// Brings rayon's parallel-iterator traits into scope when the `parallel` feature is on.
pub mod par {
    #[cfg(feature = "parallel")]
    pub use rayon::prelude::*;
}

/// Iterates mutably over a slice, in parallel with rayon when the `parallel` feature is on.
/// Every use gathers into its own element, so results do not depend on the thread count.
#[macro_export]
macro_rules! par_iter_mut {
    ($t:expr) => {{
        #[cfg(feature = "parallel")]
        let it = $t.par_iter_mut();
        #[cfg(not(feature = "parallel"))]
        let it = $t.iter_mut();
        it
    }};
}

pub use dim::{Dim, Mat, Space, Vect};
pub use params::{BondStrain, ContactOptions, ElasticModel, Material, MaterialLaw, SolverOptions};
pub use world::{BodyInit, InitialVelocity, SimError, World};
