//! MPS (Moving Particle Semi-implicit) solver for linear elastodynamics of solids, after
//! Amaro Junior, Cheng & Tsukamoto, shipped as an FMI 2.0 co-simulation FMU.
//!
//! Layers, each depending only on those above it in this list: `physics` (the solver, generic
//! over the dimension), `scene` (serde scene files -> World), `sim` (either dimension behind one
//! type), then the command line and `fmi`.
pub mod analysis;
pub mod bench;
pub mod bending;
pub mod case3;
pub mod cases;
pub mod fmi;
pub mod linear;
pub mod output;
pub mod physics;
pub mod report;
pub mod runner;
pub mod scene;
pub mod sim;

pub use scene::Scene;
pub use sim::{SimState, Simulation};
