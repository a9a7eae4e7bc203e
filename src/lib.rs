//! MPS (Moving Particle Semi-implicit) solver for linear elastodynamics of solids, after
//! Amaro Junior, Cheng & Tsukamoto, shipped as an FMI 2.0 co-simulation FMU.
//!
//! The product, layers each depending only on those above it in this list: [`physics`] (the
//! solver, generic over the dimension; knows nothing of files or FMI), [`scene`] (serde scene
//! files -> World), [`sim`] (either dimension behind one type), [`runner`] (a scene run to its
//! end: probe series, energies, frequency), [`output`] (VTU/PVD and PNG snapshots), then the
//! command line (`src/bin/mps/`) and [`fmi`] (the FMU's C ABI).
//!
//! [`studies`] (cargo feature `studies`, on by default; the FMU's binary is built without it)
//! holds the paper's cases with their references, the benchmark and the accuracy studies. The
//! product never depends on it.
pub mod fmi;
#[cfg(feature = "output")]
pub mod output;
pub mod physics;
pub mod runner;
pub mod scene;
pub mod sim;
#[cfg(feature = "studies")]
pub mod studies;

pub use scene::Scene;
pub use sim::{SimState, Simulation};
