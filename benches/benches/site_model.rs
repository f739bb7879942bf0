//! Site model files: size and load time (read, checks, matcher and plan indexes built) of a
//! model fit on all walks of each of the five ILC floors and of the 29 IPIN logfiles, when
//! they are under the data root (`$WIPDR_DATA`, else `../shared/data`), else of the committed
//! fixture floor. The fit's wall time and the file's size are printed once per model.
//!
//! `cargo bench -p wipdr-benches --bench site_model`

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use std::path::{Path, PathBuf};
use std::time::Instant;
use wipdr_core::Walk;
use wipdr_eval::pipeline::EvalConfig;
use wipdr_positioning::site_model::{SiteModel, TrainingData};

fn places() -> Vec<(String, PathBuf)> {
    let root = wipdr_io::data_root();
    let real: Vec<(String, PathBuf)> = ["site1/F1", "site1/F2", "site2/F1", "site2/F2", "site2/F3"]
        .iter()
        .map(|f| (format!("ilc {f}"), root.join("ilc20").join(f)))
        .chain([("ipin trials".to_string(), root.join("ipin2023/trials"))])
        .filter(|(_, p)| p.is_dir())
        .collect();
    if real.is_empty() {
        eprintln!(
            "site_model: no real data at {} (set WIPDR_DATA to the data root), using the fixtures",
            root.display()
        );
        let fixture = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/sim/F1"));
        return vec![("fixture F1".into(), fixture)];
    }
    real
}

fn fit(dir: &Path) -> SiteModel {
    let (data, _) = wipdr_io::any::read_any_dir(
        dir,
        // The workspace's parse cache (cargo runs benches in the package folder).
        &wipdr_io::cache::CacheSettings::in_dir(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../target/wipdr-cache"
        )),
        &Default::default(),
        &|| {},
    )
    .expect("the place reads");
    let floor = data.into_floor();
    let walks: Vec<&Walk> = floor.walks.iter().collect();
    let training = TrainingData {
        name: &floor.name,
        walks: &walks,
        survey: None,
        plan: Some(&floor.plan),
        geo_frame: floor.geo_frame,
    };
    SiteModel::fit(&training, &EvalConfig::default().site_config()).expect("fits")
}

fn site_model(c: &mut Criterion) {
    let mut g = c.benchmark_group("site_model_load");
    g.sample_size(10);
    for (name, dir) in places() {
        let started = Instant::now();
        let model = fit(&dir);
        let fit_s = started.elapsed().as_secs_f64();
        let bytes = model.to_bytes().expect("encodes");
        eprintln!(
            "site_model: {name}: fit {fit_s:.1} s, file {:.2} MB ({} points, {} APs)",
            bytes.len() as f64 / 1e6,
            model.radio_map().len(),
            model.radio_map().n_aps()
        );
        let path = std::env::temp_dir().join(format!(
            "wipdr-bench-{}-{}.wipdr",
            std::process::id(),
            name.replace(['/', ' '], "_")
        ));
        std::fs::write(&path, &bytes).expect("writes the model");
        g.bench_with_input(BenchmarkId::from_parameter(&name), &path, |b, path| {
            b.iter(|| SiteModel::load(path).expect("loads"))
        });
        let _ = std::fs::remove_file(&path);
    }
    g.finish();
}

criterion_group!(benches, site_model);
criterion_main!(benches);
