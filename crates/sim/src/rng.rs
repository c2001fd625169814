//! A tiny deterministic generator (SplitMix64): stable output on every platform and version,
//! which the "same seed, same bytes" guarantee needs.

#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    /// Approximately standard normal (sum of 4 uniforms, rescaled): cheap, bounded, and close
    /// enough for sensor noise.
    pub fn gaussian(&mut self) -> f64 {
        let s: f64 = (0..4).map(|_| self.uniform()).sum();
        (s - 2.0) * (3.0f64).sqrt()
    }
    /// Approximately standard normal from ONE 64-bit draw: the sum of four 16-bit uniforms
    /// (Irwin-Hall, n = 4), rescaled to unit variance. The mock renderer draws ~230k of these per
    /// frame, so it matters that this is one generator step.
    pub fn gaussian_fast(&mut self) -> f64 {
        let r = self.next_u64();
        let s = (r & 0xFFFF) + ((r >> 16) & 0xFFFF) + ((r >> 32) & 0xFFFF) + (r >> 48);
        // Mean of each 16-bit uniform: 32767.5; variance of the sum: 4 * (65536^2 - 1) / 12.
        (s as f64 - 131_070.0) * (3.0f64).sqrt() / 65_536.0
    }
}

/// Inverse of the standard normal CDF (Acklam's rational approximation, relative error below
/// 1.2e-9 on (0, 1)). Returns +-inf at 0 and 1, NaN outside.
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    if p.is_nan() || !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    if p == 0.0 {
        return f64::NEG_INFINITY;
    }
    if p == 1.0 {
        return f64::INFINITY;
    }
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    const LOW: f64 = 0.024_25;
    if p < LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Bits per noise sample and samples per 64-bit draw.
const TABLE_BITS: u32 = 12;
const TABLE_LEN: usize = 1 << TABLE_BITS;
const PER_DRAW: u32 = 64 / TABLE_BITS;

/// Normal quantiles at the 4096 mid-points (i + 0.5) / 4096, times sigma: a sample is one
/// 12-bit index, so one SplitMix64 draw gives five samples (the renderer's noise was one draw
/// per sample). The distribution is the normal one quantised to 4096 equally likely values,
/// with tails to +-3.7 sigma.
#[derive(Debug, Clone)]
pub struct GaussianTable {
    values: Box<[f32; TABLE_LEN]>,
}

impl GaussianTable {
    pub fn new(sigma: f64) -> Self {
        let mut values = Box::new([0f32; TABLE_LEN]);
        for (i, v) in values.iter_mut().enumerate() {
            let p = (i as f64 + 0.5) / TABLE_LEN as f64;
            *v = (sigma * normal_quantile(p)) as f32;
        }
        Self { values }
    }
    /// A stream of samples from `rng`.
    pub fn stream(&self, rng: SplitMix64) -> NoiseStream<'_> {
        NoiseStream {
            rng,
            bits: 0,
            left: 0,
            table: &self.values,
        }
    }
}

/// Samples of a [`GaussianTable`], five per generator step.
#[derive(Debug)]
pub struct NoiseStream<'a> {
    rng: SplitMix64,
    bits: u64,
    left: u32,
    table: &'a [f32; TABLE_LEN],
}

impl NoiseStream<'_> {
    #[inline]
    pub fn sample(&mut self) -> f32 {
        if self.left == 0 {
            self.bits = self.rng.next_u64();
            self.left = PER_DRAW;
        }
        let i = (self.bits as usize) & (TABLE_LEN - 1);
        self.bits >>= TABLE_BITS;
        self.left -= 1;
        self.table[i]
    }

    /// Fill `out` with the next samples: the same as calling [`Self::sample`] for each in
    /// order, five per generator step without the per-sample bookkeeping.
    pub fn fill(&mut self, out: &mut [f32]) {
        let head = (self.left as usize).min(out.len());
        let (first, rest) = out.split_at_mut(head);
        for d in first {
            *d = self.sample();
        }
        let mut chunks = rest.chunks_exact_mut(PER_DRAW as usize);
        for c in &mut chunks {
            let mut bits = self.rng.next_u64();
            for d in c {
                *d = self.table[(bits as usize) & (TABLE_LEN - 1)];
                bits >>= TABLE_BITS;
            }
        }
        for d in chunks.into_remainder() {
            *d = self.sample();
        }
    }
}

/// Round to the nearest integer in [0, 255] (ties to even; NaN gives 0): clamp with plain
/// comparisons (maxss/minss), then the 1.5 x 2^23 trick puts the rounded value in the low
/// mantissa bits.
#[inline]
pub fn quantise_f32(v: f32) -> u8 {
    let v = if v > 0.0 { v } else { 0.0 };
    let v = if v < 255.0 { v } else { 255.0 };
    (v + 12_582_912.0).to_bits() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantise_rounds_and_saturates() {
        assert_eq!(quantise_f32(-3.0), 0);
        assert_eq!(quantise_f32(f32::NAN), 0);
        assert_eq!(quantise_f32(300.0), 255);
        assert_eq!(quantise_f32(254.6), 255);
        assert_eq!(quantise_f32(17.4), 17);
        assert_eq!(quantise_f32(17.6), 18);
    }

    #[test]
    fn fill_matches_sample_by_sample() {
        let t = GaussianTable::new(1.0);
        let base: Vec<f32> = (0..97).map(|i| i as f32 * 2.5).collect();
        let mut a = t.stream(SplitMix64::new(4));
        let mut b = t.stream(SplitMix64::new(4));
        // Start mid-draw, then fill.
        let _ = (a.sample(), b.sample());
        let mut fa = vec![0f32; 97];
        a.fill(&mut fa);
        let fb: Vec<f32> = base.iter().map(|_| b.sample()).collect();
        assert_eq!(fa, fb);
        assert_eq!(a.sample(), b.sample());
    }

    #[test]
    fn table_noise_is_standard_normal() {
        assert!((normal_quantile(0.975) - 1.959_963_985).abs() < 1e-8);
        assert!((normal_quantile(0.001) + 3.090_232_306).abs() < 1e-8);
        let t = GaussianTable::new(2.0);
        let mut s = t.stream(SplitMix64::new(9));
        let n = 500_000;
        let xs: Vec<f64> = (0..n).map(|_| f64::from(s.sample())).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 4.0).abs() < 0.04, "{var}");
        let beyond = xs.iter().filter(|x| x.abs() > 2.0 * 1.96).count() as f64 / n as f64;
        assert!((beyond - 0.05).abs() < 0.003, "{beyond}");
    }

    #[test]
    fn gaussian_has_unit_variance() {
        let mut r = SplitMix64::new(42);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.gaussian()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.02, "{var}");
        let xs: Vec<f64> = (0..n).map(|_| r.gaussian_fast()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.02, "{var}");
    }
}
