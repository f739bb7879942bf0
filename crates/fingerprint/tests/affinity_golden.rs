//! Affinity propagation against scikit-learn 1.9.1 (`AffinityPropagation(affinity="precomputed")`).
//!
//! The golden files in `tests/golden/affinity/` come from `benches/peers/affinity_golden.py`;
//! each holds a similarity matrix, the settings, and scikit-learn's exemplars, labels,
//! iteration count and convergence flag. The Rust run uses the same preference rule, damping,
//! iteration limits and scikit-learn-compatible tie-breaking noise with the same seed.

use serde_json::Value;
use wipdr_fingerprint::affinity::{
    AffinityConfig, AffinityError, ConvergenceStatus, Kernel, Preference, SimilarityMatrix,
    TieBreakNoise, affinity_propagation,
};

fn load_matrix(case: &Value) -> SimilarityMatrix<f64> {
    if let Some(points) = case.get("points") {
        let pts: Vec<Vec<f64>> = points
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                p.as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect()
            })
            .collect();
        SimilarityMatrix::from_fn(pts.len(), |i, j| {
            -pts[i]
                .iter()
                .zip(&pts[j])
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
        })
    } else {
        let bits = case["bits"].as_array().unwrap();
        let data: Vec<f64> = bits
            .iter()
            .map(|b| f64::from_bits(u64::from_str_radix(b.as_str().unwrap(), 16).unwrap()))
            .collect();
        let n = (data.len() as f64).sqrt().round() as usize;
        SimilarityMatrix::new(n, data).unwrap()
    }
}

fn config_of(case: &Value, kernel: Kernel) -> AffinityConfig {
    let pref = &case["preference"];
    let preference = match pref["kind"].as_str().unwrap() {
        "global_median" => Preference::GlobalMedian,
        "row_median" => Preference::RowMedian,
        "value" => Preference::Value(pref["value"].as_f64().unwrap()),
        other => panic!("unknown preference kind {other}"),
    };
    AffinityConfig {
        damping: case["damping"].as_f64().unwrap(),
        max_iter: case["max_iter"].as_u64().unwrap() as usize,
        convergence_iter: case["convergence_iter"].as_u64().unwrap() as usize,
        preference,
        noise: TieBreakNoise::SklearnCompatible {
            seed: case["random_state"].as_u64().unwrap() as u32,
        },
        kernel,
    }
}

fn usizes(v: &Value) -> Vec<usize> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap() as usize)
        .collect()
}

#[test]
fn dense_kernel_matches_scikit_learn_on_every_golden_case() {
    check_all(Kernel::Dense);
}

#[test]
fn pruned_kernel_matches_scikit_learn_on_every_golden_case() {
    check_all(Kernel::Pruned);
}

fn check_all(kernel: Kernel) {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/affinity");
    let mut paths: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    paths.sort();
    assert!(paths.len() >= 7, "golden cases missing in {dir}");
    let mut seen_not_converged = false;
    let mut seen_no_exemplar = false;
    for path in paths {
        let case: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let name = case["name"].as_str().unwrap().to_owned();
        let s = load_matrix(&case);
        let cfg = config_of(&case, kernel);
        let exp = &case["expected"];
        let exp_exemplars = usizes(&exp["exemplars"]);
        let exp_iter = exp["n_iter"].as_u64().unwrap() as usize;
        let exp_converged = exp["converged"].as_bool().unwrap();
        match affinity_propagation(&s, &cfg) {
            Ok(out) => {
                assert_eq!(
                    out.exemplars, exp_exemplars,
                    "{name} ({kernel:?}): exemplars"
                );
                assert_eq!(
                    out.labels,
                    usizes(&exp["labels"]),
                    "{name} ({kernel:?}): labels"
                );
                assert_eq!(out.iterations, exp_iter, "{name} ({kernel:?}): iterations");
                assert_eq!(out.converged(), exp_converged, "{name}: convergence");
                if !exp_converged {
                    assert_eq!(out.status, ConvergenceStatus::NotConverged);
                    seen_not_converged = true;
                }
            }
            Err(AffinityError::NoExemplars { iterations }) => {
                assert!(
                    exp_exemplars.is_empty(),
                    "{name}: scikit-learn found exemplars"
                );
                assert!(!exp_converged);
                assert_eq!(iterations, exp_iter, "{name}: iterations");
                seen_no_exemplar = true;
            }
            Err(e) => panic!("{name}: {e}"),
        }
    }
    assert!(seen_not_converged && seen_no_exemplar);
}

#[test]
fn f32_storage_agrees_with_f64_on_well_separated_data() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/affinity");
    let case: Value = serde_json::from_str(
        &std::fs::read_to_string(format!("{dir}/blobs5d_n100_row_median.json")).unwrap(),
    )
    .unwrap();
    let s64 = load_matrix(&case);
    let s32 = SimilarityMatrix::<f32>::new(
        s64.len(),
        s64.as_slice().iter().map(|&v| v as f32).collect(),
    )
    .unwrap();
    let cfg = config_of(&case, Kernel::Dense);
    let a = affinity_propagation(&s64, &cfg).unwrap();
    let b = affinity_propagation(&s32, &cfg).unwrap();
    assert_eq!(a.exemplars, b.exemplars);
    assert_eq!(a.labels, b.labels);
}
