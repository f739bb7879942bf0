//! Reading a sample batch of `wipdr serve`'s API: one second of a phone (200 accelerometer
//! samples and a scan of two APs) as JSON into `PlainSample`s, with the hand-written reading
//! of `wipdr_io::sample_stream` (`sample_stream/de.rs`).
//!
//! `cargo bench -p wipdr-benches --bench plain_json`

use criterion::{Criterion, criterion_group, criterion_main};
use wipdr_io::sample_stream::PlainSample;

fn batch() -> String {
    let mut items: Vec<String> = (0..200)
        .map(|i| {
            format!(
                r#"{{"t_ms":{i},"sensor":"accelerometer","x":0.123456,"y":-0.3456,"z":9.7912345}}"#
            )
        })
        .collect();
    items.push(
        r#"{"t_ms":5,"sensor":"wifi","aps":[{"bssid":"aa:bb:cc:dd:ee:01","rssi_dbm":-61,"last_seen_ms":3},{"bssid":"aa:bb:cc:dd:ee:02","rssi_dbm":-71,"last_seen_ms":3}]}"#
            .into(),
    );
    format!("[{}]", items.join(","))
}

fn bench(c: &mut Criterion) {
    let body = batch();
    c.bench_function("plain_json/one_second_batch", |b| {
        b.iter(|| {
            let v: Vec<PlainSample> =
                serde_json::from_str(std::hint::black_box(&body)).expect("a valid batch");
            v
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
