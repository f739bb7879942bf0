//! scikit-learn's tie-breaking noise: numpy's `RandomState` (MT19937) reproduced.

use super::*;

/// NumPy's MT19937 `RandomState` with the legacy polar Gaussian, for
/// [`TieBreakNoise::SklearnCompatible`].
pub struct NumpyRandomState {
    mt: [u32; 624],
    pos: usize,
    cached_gauss: Option<f64>,
}

impl NumpyRandomState {
    /// `np.random.RandomState(seed)`.
    pub fn new(seed: u32) -> Self {
        let mut mt = [0u32; 624];
        mt[0] = seed;
        for i in 1..624 {
            mt[i] = 1_812_433_253u32
                .wrapping_mul(mt[i - 1] ^ (mt[i - 1] >> 30))
                .wrapping_add(i as u32);
        }
        Self {
            mt,
            pos: 624,
            cached_gauss: None,
        }
    }

    fn next_u32(&mut self) -> u32 {
        const UPPER: u32 = 0x8000_0000;
        const LOWER: u32 = 0x7fff_ffff;
        const MATRIX_A: u32 = 0x9908_b0df;
        if self.pos >= 624 {
            for k in 0..624 {
                let y = (self.mt[k] & UPPER) | (self.mt[(k + 1) % 624] & LOWER);
                let mag = if y & 1 == 1 { MATRIX_A } else { 0 };
                self.mt[k] = self.mt[(k + 397) % 624] ^ (y >> 1) ^ mag;
            }
            self.pos = 0;
        }
        let mut y = self.mt[self.pos];
        self.pos += 1;
        y ^= y >> 11;
        y ^= (y << 7) & 0x9d2c_5680;
        y ^= (y << 15) & 0xefc6_0000;
        y ^= y >> 18;
        y
    }

    /// `random_sample()`: a double in `[0, 1)` from 53 random bits.
    pub fn next_double(&mut self) -> f64 {
        let a = f64::from(self.next_u32() >> 5);
        let b = f64::from(self.next_u32() >> 6);
        (a * 67_108_864.0 + b) / 9_007_199_254_740_992.0
    }

    /// `standard_normal()` (NumPy's `legacy_gauss`, Marsaglia polar method with a cache).
    pub fn standard_normal(&mut self) -> f64 {
        if let Some(g) = self.cached_gauss.take() {
            return g;
        }
        loop {
            let x1 = 2.0 * self.next_double() - 1.0;
            let x2 = 2.0 * self.next_double() - 1.0;
            let r2 = x1 * x1 + x2 * x2;
            if r2 < 1.0 && r2 != 0.0 {
                let f = (-2.0 * r2.ln() / r2).sqrt();
                self.cached_gauss = Some(f * x1);
                return f * x2;
            }
        }
    }
}

pub(super) fn add_sklearn_noise<T: ApFloat>(data: &mut [T], seed: u32) {
    let mut rng = NumpyRandomState::new(seed);
    let eps = f64::EPSILON;
    let tiny100 = f64::MIN_POSITIVE * 100.0;
    for v in data.iter_mut() {
        let s = v.to_f64();
        let z = rng.standard_normal();
        *v = T::from_f64(s + (eps * s + tiny100) * z);
    }
}
