//! The Sobol sampler ([`Sampler::Sobol`](super::kernels::Sampler::Sobol)) on
//! the CPU: its direction numbers, computed from primitive polynomials, and
//! the very numbers the kernels draw (`shaders/common/sampler.glsl`), bit
//! for bit, for tests and analyses.
//!
//! The method is Burley's ("Practical Hash-based Owen Scrambling", JCGT
//! 9(4), 2020), as Cycles' Sobol-Burley sampler uses it. A fixed-spp render
//! draws one sequence per pixel, seeded by a hash of (seed, pixel)
//! ([`SobolSampler::new`]). A progressive render draws it in two
//! independent halves ([`SobolSampler::in_halves`]): sample i of a pixel is
//! sample i / 2 of half i % 2, and each half of each pixel has a seed, a
//! hash of (seed, pixel, half). The even and the odd samples are then two
//! independent randomisations of the pixel's integral, which is what the
//! error estimate of the two half films needs ([`crate::render::film`]):
//! the two halves of one sequence are stratified against each other, and
//! their difference measures that stratification, not the error. The
//! halves cost some accuracy (n / 2 points of each of two sequences are
//! less evenly spread than n of one), so only renders that need the
//! estimate pay it. Each draw, a 2D pair or a 1D dimension named by its
//! first dimension, has a seed, a hash of (sequence seed, dimension), and:
//!
//! 1. shuffles the index within the sequence by a nested uniform scramble
//!    (reverse the bits, apply a Laine-Karras style hash permutation,
//!    reverse back), so that the draws of one path are decorrelated from
//!    each other;
//! 2. takes the Sobol point of the shuffled index: dimensions 0 and 1 for
//!    a pair, dimension 0 for a 1D draw;
//! 3. Owen-scrambles each coordinate with a seed of its own.
//!
//! A pair draw may be *partnered* with an earlier pair draw of the same
//! path: it then takes Sobol dimensions 2 and 3 of its partner's shuffled
//! index (step 2), and scrambles them with its own seeds, so that the two
//! pairs are one shuffled, scrambled 4D Sobol point, stratified jointly
//! rather than each alone. The path code partners the lens with the pixel
//! position, and each light sample with the BSDF direction that found the
//! point it lights (or, at the first hit of a camera without a lens, with
//! the pixel position): the error these pairs make together falls faster
//! than that of two pairs shuffled apart (docs/accuracy.md).
//!
//! Sobol dimensions 0 and 1 form a (0, 2)-sequence in base 2. The shuffle
//! maps each aligned block of 2^k indices onto an aligned block of 2^k
//! Sobol indices, and Owen scrambling keeps nets nets, so for every k the
//! first 2^k samples of each sequence of a pixel (and each later aligned block
//! of 2^k) put exactly one point in every elementary interval of area
//! 2^-k, for every draw that is not partnered: any spp and any prefix of a
//! progressive render is well spread. Sobol dimensions 2 and 3 are nets of
//! a quality t of at most 2 (up to 2^13 points, Joe and Kuo's choice
//! makes it small): 2^k points put 2^t in each elementary interval of area
//! 2^(t-k), and each number alone is still stratified at every power of
//! two; dimensions 0 to 3 together put 2^3 points in each 4D elementary
//! interval of volume 2^(3-k).

use crate::interface::{sobol_directions, SobolPolynomial, SOBOL_DIMENSIONS, SOBOL_POLYNOMIALS};

/// Direction numbers of one Sobol dimension: entry k is v_{k+1}, the
/// 32-bit fraction that bit k of the index adds (xor) to the point.
pub type Directions = [u32; 32];

/// A Sobol dimension's generator (Joe and Kuo's form); its one home is
/// the shader interface, which the kernels' direction numbers come from.
pub type Polynomial = SobolPolynomial;

/// The generators of the dimensions the sampler draws from, in order:
/// dimension 0 is the van der Corput sequence, dimension 1 the polynomial
/// x + 1, dimensions 2 and 3 those a partnered pair takes.
pub const POLYNOMIALS: [Polynomial; SOBOL_DIMENSIONS as usize] = SOBOL_POLYNOMIALS;

/// The direction numbers of a dimension from its polynomial
/// ([`sobol_directions`], which `build.rs` also gives the kernels).
pub fn directions(p: &Polynomial) -> Directions {
    sobol_directions(p)
}

/// Dimension `d` of Sobol point `index`, as a 32-bit fraction.
pub fn sobol(index: u32, d: &Directions) -> u32 {
    (0..32)
        .filter(|&bit| index >> bit & 1 != 0)
        .fold(0, |x, bit| x ^ d[bit])
}

/// The kernels' 32-bit hash (`pcg_hash` in `shaders/common/random.glsl`:
/// the PCG output permutation, Jarzynski and Olano 2020).
pub const fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// A bijection of 32-bit words in which each bit flips by a function of
/// the bits below it: a Laine-Karras style hash (Vegdahl's 2021 constants,
/// as pbrt-v4 and Cycles use).
pub const fn lk_permute(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3D20_ADEA);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6C56);
    x ^= x.wrapping_mul(0x53A2_2864);
    x
}

/// A nested uniform (Owen) scramble of a 32-bit fraction: each digit flips
/// by a hash of the digits above it. On a sample index it is the shuffle.
pub const fn owen_scramble(x: u32, seed: u32) -> u32 {
    lk_permute(x.reverse_bits(), seed).reverse_bits()
}

/// The top 24 bits of a 32-bit fraction as a float in [0, 1), exactly as
/// the kernels convert it.
pub fn fraction_to_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The seed of pixel `pixel` of a render seeded `seed`.
pub const fn pixel_seed(seed: u32, pixel: u32) -> u32 {
    pcg_hash(pixel ^ pcg_hash(seed ^ 0x5BD1_E995))
}

/// The seed of half `sample % 2` of pixel `pixel`: the seed of the
/// sequence that sample belongs to.
pub const fn half_seed(seed: u32, pixel: u32, sample: u32) -> u32 {
    pcg_hash(pixel_seed(seed, pixel).wrapping_add((sample & 1).wrapping_mul(0x6A09_E667)))
}

/// The seed of the draw whose first dimension is `dim`.
pub const fn draw_seed(pixel_seed: u32, dim: u32) -> u32 {
    pcg_hash(pixel_seed ^ pcg_hash(dim.wrapping_add(0x9E37_79B9)))
}

/// The sampler's numbers: the render's seed, whether it draws two
/// independent halves, and the direction numbers.
#[derive(Debug, Clone)]
pub struct SobolSampler {
    seed: u32,
    halves: bool,
    table: [Directions; SOBOL_DIMENSIONS as usize],
}

impl SobolSampler {
    /// The sampler of a fixed-spp render seeded `seed` (the scene's
    /// `render.seed`): one sequence per pixel.
    pub fn new(seed: u32) -> SobolSampler {
        SobolSampler {
            seed,
            halves: false,
            table: POLYNOMIALS.map(|p| directions(&p)),
        }
    }

    /// The sampler of a progressive render seeded `seed`: the even and the
    /// odd samples of each pixel are two independent sequences
    /// (`GpuFrame::halves`).
    pub fn in_halves(seed: u32) -> SobolSampler {
        SobolSampler {
            halves: true,
            ..SobolSampler::new(seed)
        }
    }

    /// The index of sample `sample` within its sequence, and that
    /// sequence's seed.
    fn sequence(&self, pixel: u32, sample: u32) -> (u32, u32) {
        if self.halves {
            (sample >> 1, half_seed(self.seed, pixel, sample))
        } else {
            (sample, pixel_seed(self.seed, pixel))
        }
    }

    /// The shuffled index and the draw's seed of sample `sample` of `pixel`.
    fn draw(&self, pixel: u32, sample: u32, dim: u32) -> (u32, u32) {
        let (index, sequence_seed) = self.sequence(pixel, sample);
        let draw = draw_seed(sequence_seed, dim);
        (owen_scramble(index, draw), draw)
    }

    /// The number `sample_1d` gives for dimension `dim` of sample `sample`
    /// of pixel `pixel` (`pixel` counts row-major from the top-left).
    pub fn sample_1d(&self, pixel: u32, sample: u32, dim: u32) -> f32 {
        let (index, draw) = self.draw(pixel, sample, dim);
        let x = owen_scramble(sobol(index, &self.table[0]), pcg_hash(draw.wrapping_add(1)));
        fraction_to_f32(x)
    }

    /// The pair `sample_2d` gives for dimensions `dim` and `dim + 1`.
    pub fn sample_2d(&self, pixel: u32, sample: u32, dim: u32) -> [f32; 2] {
        let (index, draw) = self.draw(pixel, sample, dim);
        self.scrambled_pair(index, draw, [0, 1])
    }

    /// The pair `sample_2d_partnered` gives for dimensions `dim` and
    /// `dim + 1`, partnered with the pair draw at `partner`: Sobol
    /// dimensions 2 and 3 of the partner's shuffled index, scrambled with
    /// this draw's seeds, so that the partner's pair and this one are one
    /// 4D Sobol point.
    pub fn sample_2d_partnered(&self, pixel: u32, sample: u32, dim: u32, partner: u32) -> [f32; 2] {
        let (index, sequence_seed) = self.sequence(pixel, sample);
        let shuffled = owen_scramble(index, draw_seed(sequence_seed, partner));
        self.scrambled_pair(shuffled, draw_seed(sequence_seed, dim), [2, 3])
    }

    /// Sobol dimensions `dims` of point `index`, each Owen-scrambled with a
    /// seed of the draw `draw`.
    fn scrambled_pair(&self, index: u32, draw: u32, dims: [usize; 2]) -> [f32; 2] {
        let x = owen_scramble(
            sobol(index, &self.table[dims[0]]),
            pcg_hash(draw.wrapping_add(1)),
        );
        let y = owen_scramble(
            sobol(index, &self.table[dims[1]]),
            pcg_hash(draw.wrapping_add(2)),
        );
        [fraction_to_f32(x), fraction_to_f32(y)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kernels compute dimensions 0 and 1 in closed form (`sobol0`,
    /// `sobol1` in `shaders/common/sampler.glsl`, mirrored here): they are
    /// the direction numbers' points, for indices of every size.
    #[test]
    fn closed_forms_of_the_kernels_match_the_direction_numbers() {
        fn sobol1(index: u32) -> u32 {
            let mut y = index;
            y ^= (y >> 1) & 0x5555_5555;
            y ^= (y >> 2) & 0x3333_3333;
            y ^= (y >> 4) & 0x0F0F_0F0F;
            y ^= (y >> 8) & 0x00FF_00FF;
            y ^= (y >> 16) & 0x0000_FFFF;
            y.reverse_bits()
        }
        let [d0, d1, _, _] = POLYNOMIALS.map(|p| directions(&p));
        let mut x = 1u32;
        for i in (0..1 << 16).chain([u32::MAX, 1 << 31, 0xDEAD_BEEF]) {
            x = pcg_hash(x);
            for index in [i, x] {
                assert_eq!(sobol(index, &d0), index.reverse_bits(), "{index:#x}");
                assert_eq!(sobol(index, &d1), sobol1(index), "{index:#x}");
            }
        }
    }

    /// Known values: dimension 0 is the bit reversal of the index, and
    /// dimension 1 (x + 1) gives the rows of Pascal's triangle mod 2.
    #[test]
    fn directions_are_the_known_ones() {
        let d0 = directions(&POLYNOMIALS[0]);
        let d1 = directions(&POLYNOMIALS[1]);
        for i in [0u32, 1, 2, 3, 12345, u32::MAX] {
            assert_eq!(sobol(i, &d0), i.reverse_bits());
        }
        assert_eq!(
            d1[..8],
            [
                0x8000_0000,
                0xC000_0000,
                0xA000_0000,
                0xF000_0000,
                0x8800_0000,
                0xCC00_0000,
                0xAA00_0000,
                0xFF00_0000
            ]
        );
        // A degree-3 polynomial, x^3 + x + 1 (Joe-Kuo's fourth dimension,
        // m = 1, 3, 1): m_4 = 4 a_2 m_2 ^ 8 m_1 ^ m_1 = 12 ^ 8 ^ 1 = 5
        let p = Polynomial {
            degree: 3,
            coefficients: 0b01,
            initial: &[1, 3, 1],
        };
        let d = directions(&p);
        let m: Vec<u32> = (0..5).map(|k| d[k] >> (31 - k)).collect();
        assert_eq!(m[..4], [1, 3, 1, 5]);
        assert!(m.iter().all(|v| v % 2 == 1));
    }

    /// The elementary interval of a point: 2^a columns by 2^(k-a) rows.
    fn cell(p: [u32; 2], a: u32, k: u32) -> u64 {
        let col = if a == 0 {
            0
        } else {
            u64::from(p[0] >> (32 - a))
        };
        let row = if a == k {
            0
        } else {
            u64::from(p[1] >> (32 - (k - a)))
        };
        (row << a) | col
    }

    /// Asserts that `points` (2^k of them) put one point in each elementary
    /// interval of every shape 2^a x 2^(k-a).
    fn assert_net(points: &[[u32; 2]], k: u32, what: &str) {
        assert_eq!(points.len(), 1 << k);
        for a in 0..=k {
            let mut seen = vec![false; 1 << k];
            for &p in points {
                let c = cell(p, a, k) as usize;
                assert!(!seen[c], "{what}: two points in cell {c} of shape {a}/{k}");
                seen[c] = true;
            }
        }
    }

    #[test]
    fn unscrambled_sobol_pair_is_a_0_2_sequence() {
        let d = POLYNOMIALS.map(|p| directions(&p));
        for k in 0..=12 {
            for block in [0u32, 1, 5] {
                let points: Vec<[u32; 2]> = (block << k..(block + 1) << k)
                    .map(|i| [sobol(i, &d[0]), sobol(i, &d[1])])
                    .collect();
                assert_net(&points, k, &format!("block {block} of 2^{k}"));
            }
        }
    }

    #[test]
    fn the_hash_permutation_flips_each_bit_by_the_bits_below() {
        // Bijective on the low k bits for every k: what makes the scramble
        // nested and uniform, and the shuffle keep aligned blocks
        for seed in [0u32, 1, 0xDEAD_BEEF, pcg_hash(7)] {
            for k in [1u32, 4, 10] {
                let mask = (1u32 << k) - 1;
                let mut seen = vec![false; 1 << k];
                for x in 0..1u32 << k {
                    let y = lk_permute(x, seed) & mask;
                    assert!(!seen[y as usize]);
                    seen[y as usize] = true;
                    // Bits above k do not change the low k bits
                    assert_eq!(lk_permute(x | 0xABC0_0000 & !mask, seed) & mask, y);
                }
            }
        }
    }

    /// The sequences a pixel's samples form: the whole pixel under
    /// [`SobolSampler::new`], each half (the even and the odd samples) under
    /// [`SobolSampler::in_halves`]. Each entry: the sampler, a pixel, and
    /// the sample numbers of index j of the sequence (stride, offset).
    fn sequences(seed: u32) -> Vec<(SobolSampler, u32, [u32; 2])> {
        let (one, halves) = (SobolSampler::new(seed), SobolSampler::in_halves(seed));
        vec![
            (one.clone(), 0, [1, 0]),
            (one, 4097, [1, 0]),
            (halves.clone(), 0, [2, 0]),
            (halves.clone(), 1, [2, 1]),
            (halves.clone(), 4097, [2, 0]),
            (halves, 4097, [2, 1]),
        ]
    }

    /// The shuffled, scrambled points of every draw, at the bits the
    /// kernels keep: in each sequence (a pixel's samples, or each of its
    /// halves), nets at every power of two, first blocks and later.
    #[test]
    fn every_draw_is_stratified_at_every_power_of_two() {
        let bits = |v: f32| (v * 16_777_216.0) as u32;
        for (s, pixel, [stride, offset]) in sequences(3) {
            for dim in [0u32, 2, 5, 7, 4 + 8 * 7] {
                for (k, block) in [(0u32, 0u32), (4, 0), (8, 0), (10, 0), (6, 3), (8, 1)] {
                    let samples = (block << k..(block + 1) << k).map(|j| stride * j + offset);
                    let pairs: Vec<[u32; 2]> = samples
                        .clone()
                        .map(|i| s.sample_2d(pixel, i, dim).map(|v| bits(v) << 8))
                        .collect();
                    assert_net(&pairs, k, &format!("pixel {pixel} dim {dim}"));
                    let mut ones: Vec<u32> = samples
                        .map(|i| bits(s.sample_1d(pixel, i, dim)) >> (24 - k.max(1)))
                        .collect();
                    ones.sort();
                    ones.dedup();
                    assert_eq!(
                        ones.len(),
                        1 << k,
                        "1D draw, pixel {pixel} dim {dim}, 2^{k}"
                    );
                }
            }
        }
    }

    /// Dimensions 2 and 3 are Joe and Kuo's (x^2 + x + 1, m = 1, 3; x^3 +
    /// x + 1, m = 1, 3, 1), as pbrt-v4's Sobol matrices list them.
    #[test]
    fn partner_dimensions_are_joe_and_kuos() {
        let d = POLYNOMIALS.map(|p| directions(&p));
        assert_eq!(
            d[2][..6],
            [
                0x8000_0000,
                0xC000_0000,
                0x6000_0000,
                0x9000_0000,
                0xE800_0000,
                0x5C00_0000
            ]
        );
        assert_eq!(
            d[3][..6],
            [
                0x8000_0000,
                0xC000_0000,
                0x2000_0000,
                0x5000_0000,
                0xF800_0000,
                0x7400_0000
            ]
        );
    }

    /// How many of `points` (4D, 32-bit fractions) fall in each elementary
    /// interval of shape `split` (2^split[i] parts along axis i).
    fn counts_4d(points: &[[u32; 4]], split: [u32; 4]) -> Vec<u32> {
        let bits: u32 = split.iter().sum();
        let mut count = vec![0u32; 1 << bits];
        for p in points {
            let cell = (0..4).fold(0usize, |c, i| {
                let part = if split[i] == 0 {
                    0
                } else {
                    p[i] >> (32 - split[i])
                };
                (c << split[i]) | part as usize
            });
            count[cell] += 1;
        }
        count
    }

    /// A partnered pair and its partner are one shuffled, scrambled 4D
    /// Sobol point: in each sequence of a pixel, 2^k samples put 2^3 points in
    /// every 4D elementary interval of volume 2^(3-k) (the quality of Sobol
    /// dimensions 0 to 3), and the partnered pair alone is a (2, k,
    /// 2)-net. Two pairs drawn alone are not stratified together.
    #[test]
    fn a_partnered_pair_and_its_partner_are_one_4d_net() {
        let bits = |v: f32| ((v * 16_777_216.0) as u32) << 8;
        let t = 3;
        let splits = |k: u32| {
            let n = k - t;
            let mut out = Vec::new();
            for a in 0..=n {
                for b in 0..=n - a {
                    for c in 0..=n - a - b {
                        out.push([a, b, c, n - a - b - c]);
                    }
                }
            }
            out
        };
        let mut alone_fails = 0;
        for (s, pixel, [stride, offset]) in sequences(5) {
            for (partner, dim) in [(0u32, 2u32), (0, 4), (6, 10), (12, 16)] {
                for (k, block) in [(4u32, 0u32), (6, 0), (8, 0), (10, 0), (6, 3)] {
                    let samples: Vec<u32> = (block << k..(block + 1) << k)
                        .map(|j| stride * j + offset)
                        .collect();
                    let point = |i: u32, partnered: bool| {
                        let [x, y] = s.sample_2d(pixel, i, partner);
                        let [z, w] = if partnered {
                            s.sample_2d_partnered(pixel, i, dim, partner)
                        } else {
                            s.sample_2d(pixel, i, dim)
                        };
                        [bits(x), bits(y), bits(z), bits(w)]
                    };
                    let joint: Vec<[u32; 4]> = samples.iter().map(|&i| point(i, true)).collect();
                    for split in splits(k) {
                        assert!(
                            counts_4d(&joint, split).iter().all(|&c| c == 1 << t),
                            "pixel {pixel} stride {stride} offset {offset}, draws {partner} and {dim}, 2^{k}: \
                             shape {split:?}"
                        );
                    }
                    let pair: Vec<[u32; 2]> = joint.iter().map(|p| [p[2], p[3]]).collect();
                    for a in 0..=k - 2 {
                        let mut count = vec![0u32; 1 << (k - 2)];
                        for &p in &pair {
                            count[cell(p, a, k - 2) as usize] += 1;
                        }
                        assert!(
                            count.iter().all(|&c| c == 4),
                            "partnered pair, 2^{k}, shape {a}"
                        );
                    }
                    let alone: Vec<[u32; 4]> = samples.iter().map(|&i| point(i, false)).collect();
                    alone_fails += splits(k)
                        .into_iter()
                        .filter(|&split| counts_4d(&alone, split).iter().any(|&c| c != 1 << t))
                        .count();
                }
            }
        }
        assert!(
            alone_fails > 0,
            "pairs drawn alone look jointly stratified: the check means nothing"
        );
    }

    #[test]
    fn draws_pixels_and_seeds_are_decorrelated() {
        let s = SobolSampler::new(0);
        let a: Vec<f32> = (0..64).map(|i| s.sample_1d(0, i, 4)).collect();
        for (pixel, dim, seed) in [(0u32, 5u32, 0u32), (1, 4, 0), (0, 4, 1)] {
            let t = SobolSampler::new(seed);
            let b: Vec<f32> = (0..64).map(|i| t.sample_1d(pixel, i, dim)).collect();
            assert_ne!(a, b);
            // Sample correlation of the two sequences stays small
            let mean = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / 64.0;
            let (ma, mb) = (mean(&a), mean(&b));
            let cov: f64 = a
                .iter()
                .zip(&b)
                .map(|(&x, &y)| (f64::from(x) - ma) * (f64::from(y) - mb))
                .sum::<f64>()
                / 64.0;
            let corr = cov / (1.0 / 12.0);
            assert!(
                corr.abs() < 0.5,
                "pixel {pixel} dim {dim} seed {seed}: {corr}"
            );
        }
        // Every number is in [0, 1)
        for i in 0..4096 {
            let [x, y] = s.sample_2d(i % 7, i, 3);
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
        }
    }
}
