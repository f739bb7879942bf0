//! The dense message-passing iterations (responsibilities and availabilities over the full
//! similarity matrix, row blocks in parallel).

use super::*;

/// The message-passing loop. Returns the exemplar flags of the last iteration, the number of
/// iterations run, and whether the run converged.
pub(super) fn iterate<T: ApFloat>(
    s: &SimilarityMatrix<T>,
    config: &AffinityConfig,
) -> (Vec<bool>, usize, bool) {
    let n = s.n;
    let damping = T::from_f64(config.damping);
    let keep = T::from_f64(1.0 - config.damping);
    let conv = config.convergence_iter;
    let mut r = vec![T::ZERO; n * n];
    let mut a = vec![T::ZERO; n * n];
    let n_blocks = n.div_ceil(ROW_BLOCK);
    let mut partial = vec![T::ZERO; n_blocks * n];
    let mut col_sum = vec![T::ZERO; n];
    let mut is_exemplar = vec![false; n];
    // History of exemplar flags over the last `conv` iterations (ring buffer, per point count).
    let mut history = vec![false; n * conv];
    let mut window_count = vec![0usize; n];
    let block_len = ROW_BLOCK * n;

    // Iteration 0's responsibilities from a = 0.
    r.par_chunks_mut(block_len)
        .zip(s.data.par_chunks(block_len))
        .zip(partial.par_chunks_mut(n))
        .enumerate()
        .for_each(|(b, ((r_blk, s_blk), part))| {
            part.fill(T::ZERO);
            let a_zero = vec![T::ZERO; n];
            for (local, (r_row, s_row)) in r_blk.chunks_mut(n).zip(s_blk.chunks(n)).enumerate() {
                let i = b * ROW_BLOCK + local;
                update_responsibilities(r_row, &a_zero, s_row, part, i, damping, keep);
            }
        });

    let mut iterations = 0;
    let mut converged = false;
    for it in 0..config.max_iter {
        reduce_column_sums(&partial, &mut col_sum, n);
        let more = it + 1 < config.max_iter;
        let col_sum_ref = &col_sum;
        a.par_chunks_mut(block_len)
            .zip(r.par_chunks_mut(block_len))
            .zip(s.data.par_chunks(block_len))
            .zip(partial.par_chunks_mut(n))
            .zip(is_exemplar.par_chunks_mut(ROW_BLOCK))
            .enumerate()
            .for_each(|(b, ((((a_blk, r_blk), s_blk), part), flags))| {
                part.fill(T::ZERO);
                for (local, ((a_row, r_row), s_row)) in a_blk
                    .chunks_mut(n)
                    .zip(r_blk.chunks_mut(n))
                    .zip(s_blk.chunks(n))
                    .enumerate()
                {
                    let i = b * ROW_BLOCK + local;
                    update_availabilities(a_row, r_row, col_sum_ref, i, damping, keep);
                    flags[local] = a_row[i] + r_row[i] > T::ZERO;
                    if more {
                        update_responsibilities(r_row, a_row, s_row, part, i, damping, keep);
                    }
                }
            });
        iterations = it + 1;
        // Convergence bookkeeping (scikit-learn: e[:, it % conv] = E).
        let slot = it % conv;
        let mut k_count = 0usize;
        for i in 0..n {
            let old = history[i * conv + slot];
            let new = is_exemplar[i];
            if old != new {
                if new {
                    window_count[i] += 1;
                } else {
                    window_count[i] -= 1;
                }
            }
            history[i * conv + slot] = new;
            k_count += usize::from(new);
        }
        if it >= conv {
            let settled = window_count.iter().all(|&c| c == 0 || c == conv);
            if settled && k_count > 0 {
                converged = true;
                break;
            }
        }
    }
    (is_exemplar, iterations, converged)
}

pub(super) const LANES: usize = 8;

#[inline(always)]
pub(super) fn fmax<T: ApFloat>(a: T, b: T) -> T {
    if a > b { a } else { b }
}

#[inline(always)]
pub(super) fn fmin<T: ApFloat>(a: T, b: T) -> T {
    if a < b { a } else { b }
}

/// Largest value of `a + s`, the first index where it occurs, and the largest value over the
/// other indices (equal to the largest when it occurs twice), as NumPy's
/// `argmax` / `tmp[I] = -inf` / `max` compute them. Lane-parallel, branch-free inner loop.
#[inline]
pub(super) fn top_two<T: ApFloat>(a: &[T], s: &[T]) -> (T, usize, T) {
    let mut b1 = [T::NEG_INFINITY; LANES];
    let mut b2 = [T::NEG_INFINITY; LANES];
    let mut at = [usize::MAX; LANES];
    let ca = a.chunks_exact(LANES);
    let cs = s.chunks_exact(LANES);
    let tail_start = a.len() - ca.remainder().len();
    for (c, (xa, xs)) in ca.zip(cs).enumerate() {
        for l in 0..LANES {
            let v = xa[l] + xs[l];
            b2[l] = fmax(b2[l], fmin(b1[l], v));
            let better = v > b1[l];
            at[l] = if better { c * LANES + l } else { at[l] };
            b1[l] = if better { v } else { b1[l] };
        }
    }
    let mut best = T::NEG_INFINITY;
    let mut best_at = usize::MAX;
    let mut second = T::NEG_INFINITY;
    let mut offer = |v: T, k: usize| {
        if v > best || (v == best && k < best_at) {
            second = fmax(second, best);
            best = v;
            best_at = k;
        } else {
            second = fmax(second, v);
        }
    };
    for l in 0..LANES {
        if at[l] != usize::MAX {
            offer(b1[l], at[l]);
        }
    }
    for (k, (&av, &sv)) in a[tail_start..].iter().zip(&s[tail_start..]).enumerate() {
        offer(av + sv, tail_start + k);
    }
    for &v in &b2 {
        second = fmax(second, v);
    }
    (best, best_at.min(a.len().saturating_sub(1)), second)
}

/// Responsibility update (eq. 4) for row `i`:
/// `r = damping * r + (1 - damping) * (s - max_{k' != k}(a + s))`, then accumulates
/// `max(r, 0)` (the diagonal with its sign) into the block's column sums `part`.
#[inline]
pub(super) fn update_responsibilities<T: ApFloat>(
    r: &mut [T],
    a: &[T],
    s: &[T],
    part: &mut [T],
    i: usize,
    damping: T,
    keep: T,
) {
    let (best, best_at, second) = top_two(a, s);
    let at_best = r[best_at] * damping + (s[best_at] - second) * keep;
    for (rv, &sv) in r.iter_mut().zip(s) {
        *rv = *rv * damping + (sv - best) * keep;
    }
    r[best_at] = at_best;
    for (p, &rv) in part.iter_mut().zip(r.iter()) {
        *p = *p + fmax(rv, T::ZERO);
    }
    // The diagonal enters with its sign (scikit-learn: Rp's diagonal = R's diagonal).
    let rii = r[i];
    if rii <= T::ZERO {
        part[i] = part[i] + rii;
    }
}

pub(super) fn reduce_column_sums<T: ApFloat>(partial: &[T], col_sum: &mut [T], n: usize) {
    col_sum
        .par_chunks_mut(256)
        .enumerate()
        .for_each(|(c, out)| {
            let start = c * 256;
            for (off, v) in out.iter_mut().enumerate() {
                let k = start + off;
                let mut acc = T::ZERO;
                for blk in partial.chunks(n) {
                    acc = acc + blk[k];
                }
                *v = acc;
            }
        });
}

/// Availability update (eq. 5-6) for row `i` from the column sums of `max(r, 0)` (diagonal
/// with its sign): `-a_new(i,k) = max(0, rp(i,k) - colsum_k)` off the diagonal,
/// `-a_new(k,k) = rp(k,k) - colsum_k`; `a = damping * a - (1 - damping) * (-a_new)`.
pub(super) fn update_availabilities<T: ApFloat>(
    a: &mut [T],
    r: &[T],
    col_sum: &[T],
    i: usize,
    damping: T,
    keep: T,
) {
    let a_ii_old = a[i];
    let r_ii = r[i];
    for ((av, &rv), &cs) in a.iter_mut().zip(r).zip(col_sum) {
        let rp = if rv > T::ZERO { rv } else { T::ZERO };
        let neg = rp - cs;
        let neg = if neg > T::ZERO { neg } else { T::ZERO };
        *av = *av * damping - neg * keep;
    }
    let neg_diag = r_ii - col_sum[i];
    a[i] = a_ii_old * damping - neg_diag * keep;
}
