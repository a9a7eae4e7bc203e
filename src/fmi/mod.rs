//! FMI 2.0 Co-Simulation layer: a scene becomes an FMU whose variables come from one table.
//!
//! - [`variables`]: the variable table derived from a scene (drives get/set and the XML);
//! - [`model_description`]: modelDescription.xml (quick-xml) and the GUID;
//! - [`instance`]: the safe instance (call-order state machine, doStep, FMU state, threads);
//! - [`ffi`]: the exported `fmi2*` C functions, the only unsafe code of the crate;
//! - [`pack`]: builds `NAME.fmu` from a scene and the built library;
//! - [`source_id`]: the identity of the sources the library was built from (checked by pack).
//!
//! The layer never touches the solver's fields: it goes through [`crate::sim::Simulation`].
pub mod ffi;
pub mod instance;
pub mod model_description;
pub mod pack;
pub mod source_id;
pub mod variables;
