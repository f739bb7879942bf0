//! The fold rules of the evaluation protocol (`docs/evaluation.md`): walks sorted by file
//! name, walk `i` in fold `i mod 5`; or, where walks repeat routes (IPIN `TrialNN`, every
//! walk's [`wipdr_core::WalkMeta::route`] given), leave-one-route-out: one fold per route,
//! all repetitions of a route together.

use wipdr_core::Walk;

/// Number of folds of the protocol.
pub const FOLDS: usize = 5;

/// The fold of each walk: walks sorted by file name, walk `i` in fold `i mod 5`. Returns, for
/// each input name (in input order), its fold.
///
/// ```
/// use wipdr_eval::fold_rules::folds_by_name;
/// let f = folds_by_name(&["c", "a", "b", "f", "e", "d"]);
/// assert_eq!(f, vec![2, 0, 1, 0, 4, 3]);
/// ```
pub fn folds_by_name<S: AsRef<str>>(names: &[S]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..names.len()).collect();
    order.sort_by(|&a, &b| names[a].as_ref().cmp(names[b].as_ref()));
    let mut fold = vec![0; names.len()];
    for (rank, &i) in order.iter().enumerate() {
        fold[i] = rank % FOLDS;
    }
    fold
}

/// The folds of a floor's walks: `(fold of each walk, number of folds)`. Leave-one-route-out
/// when every walk has a route (folds in route-name order), else [`folds_by_name`] with
/// [`FOLDS`] folds.
///
/// ```
/// use wipdr_core::Walk;
/// use wipdr_eval::fold_rules::folds_of_walks;
/// let walk = |id: &str, route: Option<&str>| {
///     let mut w = Walk::default();
///     w.meta.id = id.into();
///     w.meta.route = route.map(String::from);
///     w
/// };
/// let routes = [walk("a1", Some("Trial03")), walk("b1", Some("Trial01")), walk("b2", Some("Trial01"))];
/// assert_eq!(folds_of_walks(&routes), (vec![1, 0, 0], 2));
/// let plain = [walk("x", None), walk("y", Some("Trial01"))];
/// assert_eq!(folds_of_walks(&plain).1, 5);
/// ```
pub fn folds_of_walks(walks: &[Walk]) -> (Vec<usize>, usize) {
    folds_of_walk_refs(&walks.iter().collect::<Vec<_>>())
}

/// [`folds_of_walks`] over borrowed walks.
pub fn folds_of_walk_refs(walks: &[&Walk]) -> (Vec<usize>, usize) {
    let routes: Option<Vec<&str>> = walks.iter().map(|w| w.meta.route.as_deref()).collect();
    match routes {
        Some(routes) if !routes.is_empty() => {
            let mut names: Vec<&str> = routes.clone();
            names.sort_unstable();
            names.dedup();
            let folds = routes
                .iter()
                .map(|r| names.binary_search(r).unwrap_or(0))
                .collect();
            (folds, names.len())
        }
        _ => {
            let ids: Vec<&str> = walks.iter().map(|w| w.meta.id.as_str()).collect();
            (folds_by_name(&ids), FOLDS)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_fold_gets_a_walk_in_name_order() {
        let names: Vec<String> = (0..12).rev().map(|i| format!("w{i:02}")).collect();
        let f = folds_by_name(&names);
        // names[11] = "w00" is first in name order.
        assert_eq!(f[11], 0);
        assert_eq!(f[0], 11 % FOLDS);
        for k in 0..FOLDS {
            assert!(f.contains(&k));
        }
    }
}
