//! The identity of the sources a library was built from: `MPS_SOLID_SOURCE_ID`, an exported
//! symbol of the FMU's library holding "mps-solid <version> <checksum of src/ except src/bin>"
//! (build.rs). `mps pack` reads it from the library file, without loading it, and packs only a
//! library built from its own sources, whose variable table is the one its modelDescription.xml
//! describes.

/// The source id of this build: "mps-solid <version> <16 hex digits>".
pub const SOURCE_ID: &str = concat!(
    "mps-solid ",
    env!("CARGO_PKG_VERSION"),
    " ",
    env!("MPS_SOURCE_ID")
);

/// Length of the exported symbol's data: the id, NUL-padded.
const LEN: usize = 64;

const fn padded(s: &str) -> [u8; LEN] {
    let b = s.as_bytes();
    assert!(b.len() < LEN, "source id too long");
    let mut out = [0u8; LEN];
    let mut i = 0;
    while i < b.len() {
        out[i] = b[i];
        i += 1;
    }
    out
}

/// The source id as exported data of the shared library (NUL-padded), read by `mps pack`
/// ([`crate::fmi::pack::library_source_id`]).
#[no_mangle]
pub static MPS_SOLID_SOURCE_ID: [u8; LEN] = padded(SOURCE_ID);
