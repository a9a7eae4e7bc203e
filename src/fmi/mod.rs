//! FMI 2.0 co-simulation layer (work in progress).
