//! The integration tests as one binary (one link of the library instead of one per file):
//! each module is one invariant or one surface. Tests that need a process of their own
//! (a counting global allocator, dlopen/dlclose cycles, thread counts of the FMU) stay
//! separate: tests/limits_memory.rs, tests/unload.rs, tests/fmi_host.rs.
mod bending_accuracy;
mod c_abi;
mod case3_short;
mod clamp_faces;
mod cli_errors;
mod cli_outputs;
mod cli_reliability;
#[path = "../common/mod.rs"]
mod common;
mod contact_collision;
mod elastica;
mod energy_drift;
mod energy_fracture;
mod fmi_model_description;
mod fmi_time;
mod fracture_bar;
mod fracture_screen;
mod header_fresh;
mod initial_velocity;
mod invariance;
mod layout;
mod leak_check;
mod limits_work;
mod material_law;
mod output_snapshots;
mod pack_checks;
mod paper_cases;
mod physics_invariants;
mod scene_schema;
mod scene_validation;
mod shapes;
mod stability_step;
mod stencil_classes;
mod torsion;
