//! Synthetic images for the tests of [`super::ztest`], [`super::metrics`]
//! and [`super::compare`]: a ground truth with structure in both
//! directions, noisy estimates of it with known variance, and its mirror
//! image.

/// SplitMix64 with Box–Muller normals: enough for synthetic noise.
pub(super) struct Rng(pub(super) u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in (0, 1].
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }
    pub(super) fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

pub(super) const W: usize = 64;
pub(super) const H: usize = 48;

/// An asymmetric ground truth: a horizontal ramp, a bright block on the
/// left, and a channel-dependent tint.
pub(super) fn truth() -> Vec<f32> {
    let mut img = Vec::with_capacity(W * H * 3);
    for y in 0..H {
        for x in 0..W {
            let ramp = 0.1 + 0.8 * x as f32 / (W - 1) as f32;
            let block = if x < W / 4 && y > H / 3 { 0.5 } else { 0.0 };
            for c in 0..3 {
                img.push(ramp + block + 0.05 * c as f32 + 0.02 * (y % 5) as f32);
            }
        }
    }
    img
}

/// A noisy estimate of `truth`: per value, noise with standard deviation
/// `rel_sigma * value`; returns (mean, variance of mean).
pub(super) fn noisy(truth: &[f32], rel_sigma: f64, rng: &mut Rng) -> (Vec<f32>, Vec<f32>) {
    let mut mean = Vec::with_capacity(truth.len());
    let mut var = Vec::with_capacity(truth.len());
    for &t in truth {
        let s = rel_sigma * f64::from(t);
        mean.push((f64::from(t) + s * rng.normal()) as f32);
        var.push((s * s) as f32);
    }
    (mean, var)
}

/// `img` (a `W` x `H` image) mirrored left to right.
pub(super) fn mirror(img: &[f32]) -> Vec<f32> {
    let mut out = vec![0.0; img.len()];
    for y in 0..H {
        for x in 0..W {
            for c in 0..3 {
                out[(y * W + x) * 3 + c] = img[(y * W + (W - 1 - x)) * 3 + c];
            }
        }
    }
    out
}
