//! The pruned iterations: messages only over the kept (sparse) similarities of each row.

use super::*;

/// Per-row state of the pruned kernel.
pub(super) struct PrunedRow<T> {
    /// Off-diagonal similarities of the row, descending, with their columns (a prefix).
    sorted: Vec<(T, u32)>,
    /// Whether `sorted` holds the whole row.
    complete: bool,
    /// `mu_i`: damped history of the row's best `a + s`.
    mu: T,
    /// `c_i(k)`: damped arg-max corrections, sorted by column.
    c: Vec<(u32, T)>,
    /// `e_i(k) <= 0`: availability corrections where `r(i,k)` was ever positive, by column.
    e: Vec<(u32, T)>,
    /// This iteration's positive off-diagonal responsibilities `(k, r(i,k))`.
    positive: Vec<(u32, T)>,
    /// This iteration's `r(i,i)`.
    r_ii: T,
    /// `a(i,i)`.
    a_ii: T,
}

pub(super) fn lookup<T: ApFloat>(v: &[(u32, T)], k: u32) -> Option<T> {
    v.binary_search_by_key(&k, |e| e.0).ok().map(|p| v[p].1)
}

pub(super) fn add_at<T: ApFloat>(v: &mut Vec<(u32, T)>, k: u32, x: T) {
    match v.binary_search_by_key(&k, |e| e.0) {
        Ok(p) => v[p].1 = v[p].1 + x,
        Err(p) => v.insert(p, (k, x)),
    }
}

impl<T: ApFloat> PrunedRow<T> {
    /// Makes `sorted` at least `len` long (or complete).
    fn extend(&mut self, row: &[T], i: usize, len: usize) {
        let n_off = row.len() - 1;
        let len = len.min(n_off);
        if self.complete || self.sorted.len() >= len {
            return;
        }
        let mut all: Vec<(T, u32)> = row
            .iter()
            .enumerate()
            .filter(|&(k, _)| k != i)
            .map(|(k, &v)| (v, k as u32))
            .collect();
        let desc = |a: &(T, u32), b: &(T, u32)| {
            b.0.partial_cmp(&a.0)
                .unwrap_or(std::cmp::Ordering::Equal)
                .then(a.1.cmp(&b.1))
        };
        if len < all.len() {
            all.select_nth_unstable_by(len, desc);
            all.truncate(len);
        }
        all.sort_unstable_by(desc);
        self.complete = all.len() == n_off;
        self.sorted = all;
    }

    /// The `p`-th largest off-diagonal similarity, extending the prefix as needed.
    #[inline]
    fn at(&mut self, row: &[T], i: usize, p: usize) -> Option<(T, u32)> {
        if p >= self.sorted.len() {
            if self.complete {
                return None;
            }
            self.extend(row, i, (2 * self.sorted.len()).max(64));
        }
        self.sorted.get(p).copied()
    }
}

/// The pruned kernel ([`Kernel::Pruned`]). Memory: S plus O(N * visited prefix).
pub(super) fn iterate_pruned<T: ApFloat>(
    s: &SimilarityMatrix<T>,
    config: &AffinityConfig,
) -> (Vec<bool>, usize, bool) {
    let n = s.n;
    let d = T::from_f64(config.damping);
    let q = T::from_f64(1.0 - config.damping);
    let conv = config.convergence_iter;
    let mut rows: Vec<PrunedRow<T>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut r = PrunedRow {
                sorted: Vec::new(),
                complete: n == 1,
                mu: T::ZERO,
                c: Vec::new(),
                e: Vec::new(),
                positive: Vec::new(),
                r_ii: T::ZERO,
                a_ii: T::ZERO,
            };
            r.extend(s.row(i), i, 64);
            r
        })
        .collect();
    let mut beta = vec![T::ZERO; n];
    let mut col_sum = vec![T::ZERO; n];
    let mut alpha = T::ZERO;
    let mut is_exemplar = vec![false; n];
    let mut history = vec![false; n * conv];
    let mut window_count = vec![0usize; n];
    let mut iterations = 0;
    let mut converged = false;
    for it in 0..config.max_iter {
        alpha = alpha * d + q;
        let beta_ref = &beta;
        // Responsibilities (eq. 4) from the previous availabilities.
        rows.par_iter_mut().enumerate().for_each(|(i, st)| {
            let row = s.row(i);
            let mut best = row[i] + st.a_ii;
            let mut best_at = i as u32;
            let mut second = T::NEG_INFINITY;
            let mut p = 0;
            while let Some((sv, k)) = st.at(row, i, p) {
                if sv < second {
                    break;
                }
                let v = sv + beta_ref[k as usize] + lookup(&st.e, k).unwrap_or(T::ZERO);
                if v > best || (v == best && k < best_at) {
                    second = fmax(second, best);
                    best = v;
                    best_at = k;
                } else {
                    second = fmax(second, v);
                }
                p += 1;
            }
            st.mu = st.mu * d + q * best;
            for e in st.c.iter_mut() {
                e.1 = e.1 * d;
            }
            add_at(&mut st.c, best_at, q * (best - second));
            // Positive responsibilities: r(i,k) = alpha s - mu + c(k).
            st.positive.clear();
            let mut p = 0;
            while let Some((sv, k)) = st.at(row, i, p) {
                let r = alpha * sv - st.mu;
                if r <= T::ZERO {
                    break;
                }
                if lookup(&st.c, k).is_none() {
                    st.positive.push((k, r));
                }
                p += 1;
            }
            for &(k, cv) in &st.c {
                if k as usize != i {
                    let r = alpha * row[k as usize] - st.mu + cv;
                    if r > T::ZERO {
                        st.positive.push((k, r));
                    }
                }
            }
            st.r_ii = alpha * row[i] - st.mu + lookup(&st.c, i as u32).unwrap_or(T::ZERO);
        });
        // Column sums of max(r, 0) with the diagonal signed, rows in order.
        col_sum.fill(T::ZERO);
        for (i, st) in rows.iter().enumerate() {
            col_sum[i] = col_sum[i] + st.r_ii;
            for &(k, r) in &st.positive {
                col_sum[k as usize] = col_sum[k as usize] + r;
            }
        }
        // Availabilities (eq. 5-6).
        for (b, &cs) in beta.iter_mut().zip(&col_sum) {
            *b = *b * d + q * fmin(cs, T::ZERO);
        }
        let cs_ref = &col_sum;
        rows.par_iter_mut()
            .zip(is_exemplar.par_iter_mut())
            .enumerate()
            .for_each(|(i, (st, flag))| {
                st.a_ii = st.a_ii * d - q * (st.r_ii - cs_ref[i]);
                for e in st.e.iter_mut() {
                    e.1 = e.1 * d;
                }
                for pi in 0..st.positive.len() {
                    let (k, r) = st.positive[pi];
                    let cs = cs_ref[k as usize];
                    let delta = q * (fmin(cs - r, T::ZERO) - fmin(cs, T::ZERO));
                    add_at(&mut st.e, k, delta);
                }
                *flag = st.a_ii + st.r_ii > T::ZERO;
            });
        iterations = it + 1;
        let slot = it % conv;
        let mut k_count = 0usize;
        for i in 0..n {
            let new = is_exemplar[i];
            let old = std::mem::replace(&mut history[i * conv + slot], new);
            if old != new {
                if new {
                    window_count[i] += 1;
                } else {
                    window_count[i] -= 1;
                }
            }
            k_count += usize::from(new);
        }
        if it >= conv && k_count > 0 && window_count.iter().all(|&c| c == 0 || c == conv) {
            converged = true;
            break;
        }
    }
    (is_exemplar, iterations, converged)
}
