//! Fingerprint benchmark CSV reader (being built).
