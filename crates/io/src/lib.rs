//! # wipdr-io — readers and writers (placeholder being built)

pub mod fingerprint_csv;
