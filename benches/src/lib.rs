//! Criterion benchmarks of wipdr live in `benches/benches/`; this library is empty.
