//! The paper's cases, the benchmark and the accuracy studies: scene builders with their
//! references (closed forms, FEM results under reference/), reports and the linearised model.
//! Behind the `studies` cargo feature (default on); the FMU's binary leaves it out, and nothing
//! in the product depends on it.
pub mod bench;
pub mod bending;
pub mod case3;
pub mod cases;
pub mod family;
pub mod linear;
pub mod peers;
pub mod programs;
pub mod realtime;
pub mod report;
