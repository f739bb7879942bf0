//! The fold rule of the evaluation protocol (`docs/evaluation.md`): walks sorted by file name,
//! walk `i` in fold `i mod 5`.

/// Number of folds of the protocol.
pub const FOLDS: usize = 5;

/// The fold of each walk: walks sorted by file name, walk `i` in fold `i mod 5`. Returns, for
/// each input name (in input order), its fold.
///
/// ```
/// use wipdr_eval::folds::folds_by_name;
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
