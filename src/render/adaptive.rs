//! Adaptive sampling: each pixel gets the samples its own noise needs.
//!
//! Every pixel first gets [`ADAPTIVE_MIN_SPP`] samples. Then, round by
//! round, the film is read back and each pixel's per-sample relative
//! variance is estimated: v_p, the mean over RGB of the sample variance
//! divided by (mean² + 0.01), the same weighting as the relMSE. The image's
//! relMSE with n_p samples of pixel p is then about (k / P) Σ v_p / n_p,
//! where k, the ratio of the two half films' error estimate to the
//! sample-variance one over the whole image, accounts for the sampler
//! (1 for independent samples, below 1 for the Sobol sampler's). The
//! allocation that reaches a relMSE E with the fewest samples in all
//! minimises Σ n_p under that constraint: n_p ∝ sqrt(v_p) (a Lagrange
//! multiplier), scaled so that the predicted relMSE is E. With a time limit
//! the scale is instead the one whose samples fit the seconds left, at the
//! time per sample measured so far.
//!
//! Three rules keep a pixel's own samples from biasing it:
//! - a pixel's count is shaped by the mean v of its eight neighbours, not
//!   by its own samples. A rule that reads the pixel's own samples biases
//!   it: a pixel whose first samples missed a caustic looks quiet and
//!   stops, one whose samples hit it renders on and is averaged down. With
//!   its own v in the shape (the larger of it and the 3 x 3 mean), the mean
//!   of 16 adaptive renders of the glass caustic came out 1.06% darker
//!   than Mitsuba's reference and failed the z-test; with the neighbours
//!   alone it passes (`tests/it/adaptive.rs`). Neighbours also keep the
//!   pixels around a noisy one active, as Cycles does. The cost is small:
//!   from 4096-spp variances, the ideal allocation (n ∝ sqrt(v)) lowers
//!   the error at equal samples 1.53x on the glass caustic, the
//!   neighbours' mean 1.40x;
//! - no pixel stops before [`ADAPTIVE_MIN_SPP`] samples, and a pixel at
//!   most doubles its samples in a round, so that an estimate from few
//!   samples never commits many more;
//! - the render stops on the whole image's error, as `--target-error`
//!   does: the two half films' predicted relMSE, summed over every pixel
//!   with its own count, not the per-pixel figures.
//!
//! In a round, each pixel short of its share gets a power of two of
//! samples more (the one nearest what it lacks, at most as many as it has),
//! so that the pixels fall into few groups of equal increments, whatever
//! samples each holds; each group renders through
//! [`Renderer::render_pixels`], whose waves hold only those pixels, each
//! going on from its own count. A pixel that has its samples launches no
//! path. (Groups of equal sample ranges instead, on a ladder of counts,
//! made about five times the waves, and their fixed costs were 10 to 25%
//! of an adaptive render's time on lavapipe.) Sample i of pixel p is the
//! same path as in a uniform render: an adaptive image differs from a
//! uniform one only in how many of those samples each pixel averages.
//!
//! The last rounds of a render are small: once the model's error meets the
//! target and the film's does not, the model's aim falls by 5% or more a
//! round, and few pixels lack a quarter of their samples (the small bright
//! light at 2e-5: 19 of its 29 rounds, for its last 8% of error). Lowering
//! the aim by a fifth whenever a round would add under a sixteenth of the
//! samples rendered made fewer rounds and waves (46 to 33 on the glass
//! caustic) but overshot the target (true relMSE 0.89e-3 rather than
//! 1.04e-3 at 1e-3), so the render stopped later (1.41x sooner than
//! uniform rather than 1.65x, five seeds), at the same efficiency; it was
//! dropped.
//!
//! A stopping rule that looks at a pixel's own samples can bias it (a pixel
//! whose samples happen to agree stops early); `tests/it/adaptive.rs` checks the
//! mean of many adaptive renders against the reference, pixel by pixel.

use std::collections::BTreeMap;

use anyhow::{ensure, Result};

use crate::render::budget::MIN_SPP_FOR_PREDICTION;
use crate::render::{OnWave, RenderOutput, Renderer};
use crate::util::metrics::predicted_rel_mse;

/// Samples every pixel gets before its noise is estimated.
pub const ADAPTIVE_MIN_SPP: u32 = MIN_SPP_FOR_PREDICTION;

/// Least share of its samples a pixel must lack to get more in a round.
pub const MIN_STEP: f64 = 0.25;

/// A round's group of pixels with one increment renders only when it holds
/// at least 1 / this of the round's samples; the others wait for a later
/// round (a group of a few pixels costs a wave's fixed time: on lavapipe
/// the Cornell box at 64 x 64 made 38 waves, many of under 50 paths).
pub const MIN_GROUP_SHARE: u64 = 16;

/// The denominator's offset of the relMSE: error / (mean² + this).
const REL_OFFSET: f64 = 0.01;

/// What an adaptive render aims at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// Stop once the predicted relMSE of the image is at most this.
    Error(f64),
    /// Stop once this many seconds of rendering are spent.
    Time(f64),
    /// Stop once the pixels hold this many samples on average (`converge`
    /// compares adaptive and uniform renders at equal mean spp).
    MeanSpp(f64),
}

impl Goal {
    /// Checks the goal's value, naming it in the message.
    pub fn validate(&self) -> Result<()> {
        let (name, v) = match *self {
            Goal::Error(e) => ("Goal::Error (a relMSE)", e),
            Goal::Time(s) => ("Goal::Time (seconds)", s),
            Goal::MeanSpp(n) => ("Goal::MeanSpp (samples per pixel)", n),
        };
        ensure!(v.is_finite() && v > 0.0, "{name} must be above 0, got {v}");
        Ok(())
    }
}

/// Each pixel's noise, as the allocation needs it.
#[derive(Debug, Clone, PartialEq)]
pub struct Noise {
    /// Per-sample relative variance of each pixel (mean over RGB of the
    /// sample variance / (mean² + 0.01)).
    pub per_sample: Vec<f64>,
    /// The mean `per_sample` of each pixel's neighbours (not its own):
    /// what shapes the allocation.
    pub shape: Vec<f64>,
    /// The two half films' predicted relMSE over the sample-variance one,
    /// over the whole image: how much better than independent samples the
    /// sampler does (1 when nothing is known).
    pub calibration: f64,
}

impl Noise {
    /// The noise of a resolved film of a `width` x `height` image whose
    /// pixels hold `counts` samples.
    pub fn of(out: &RenderOutput, counts: &[u32]) -> Noise {
        let (w, h) = (out.width as usize, out.height as usize);
        let mut per_sample = Vec::with_capacity(w * h);
        let (mut honest, mut variance) = (0.0, 0.0);
        for (p, &n) in counts.iter().enumerate() {
            let mut v = 0.0;
            for c in 3 * p..3 * p + 3 {
                let m = f64::from(out.mean[c]);
                let weight = 1.0 / (m * m + REL_OFFSET);
                let var_of_mean = f64::from(out.var_of_mean[c]).max(0.0);
                v += var_of_mean * f64::from(n) * weight / 3.0;
                variance += var_of_mean * weight;
                honest += f64::from(out.error_estimate[c]).max(0.0) * weight;
            }
            per_sample.push(v);
        }
        let calibration = if variance > 0.0 && honest > 0.0 {
            (honest / variance).clamp(1e-3, 4.0)
        } else {
            1.0
        };
        let shape = neighbours_mean(&per_sample, w, h);
        Noise {
            per_sample,
            shape,
            calibration,
        }
    }

    /// The relMSE the image is predicted to have with `counts` samples per pixel.
    pub fn predicted(&self, counts: &[f64]) -> f64 {
        let sum: f64 = self
            .per_sample
            .iter()
            .zip(counts)
            .map(|(v, n)| v / n.max(1.0))
            .sum();
        self.calibration * sum / self.per_sample.len().max(1) as f64
    }

    /// Samples each pixel should hold at `scale`: scale x sqrt(shape),
    /// within `min..=max`.
    pub fn allocation(&self, scale: f64, min: u32, max: u32) -> Vec<f64> {
        self.shape
            .iter()
            .map(|s| (scale * s.sqrt()).clamp(f64::from(min), f64::from(max)))
            .collect()
    }

    /// The allocation whose predicted relMSE is `target`, within
    /// `min..=max` samples per pixel.
    pub fn for_error(&self, target: f64, min: u32, max: u32) -> Vec<f64> {
        self.solve(min, max, |n| self.predicted(n) <= target)
    }

    /// The allocation of `mean_spp` samples per pixel on average, within
    /// `min..=max`.
    pub fn for_mean_spp(&self, mean_spp: f64, min: u32, max: u32) -> Vec<f64> {
        let pixels = self.shape.len().max(1) as f64;
        self.solve(min, max, |n| n.iter().sum::<f64>() / pixels >= mean_spp)
    }

    /// The allocation at the smallest scale for which `enough` holds (found
    /// by bisection of the scale's logarithm; `enough` must grow with the
    /// scale), or the most samples everywhere when none does.
    fn solve(&self, min: u32, max: u32, enough: impl Fn(&[f64]) -> bool) -> Vec<f64> {
        let at = |log_scale: f64| self.allocation(log_scale.exp(), min, max);
        let (mut lo, mut hi) = (-60.0f64, 60.0f64);
        if !enough(&at(hi)) {
            return vec![f64::from(max); self.shape.len()];
        }
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if enough(&at(mid)) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        at(hi)
    }
}

/// The mean value of each pixel's eight neighbours (those within the
/// image), without the pixel itself; a 1 x 1 image keeps its value.
pub fn neighbours_mean(values: &[f64], width: usize, height: usize) -> Vec<f64> {
    let mut out = vec![0.0f64; values.len()];
    for y in 0..height {
        for x in 0..width {
            let (mut sum, mut n) = (0.0f64, 0.0f64);
            for ny in y.saturating_sub(1)..(y + 2).min(height) {
                for nx in x.saturating_sub(1)..(x + 2).min(width) {
                    if (nx, ny) != (x, y) {
                        sum += values[ny * width + nx];
                        n += 1.0;
                    }
                }
            }
            out[y * width + x] = if n > 0.0 {
                sum / n
            } else {
                values[y * width + x]
            };
        }
    }
    out
}

/// One round's work: for each increment of samples, the pixels
/// (ascending) that get it.
pub type Round = BTreeMap<u32, Vec<u32>>;

/// The round that brings each pixel short of its `target` by at least a
/// [`MIN_STEP`] of what it `counts` towards it: a power of two of samples
/// more, the one nearest (in ratio) what it lacks, at most what it holds
/// already (at least 2), and never past `max`. A pixel that lacks less
/// stays, and so do the pixels of an increment that holds under
/// 1/[`MIN_GROUP_SHARE`] of the round's samples: each wave costs a fixed
/// time, and rounds of a few samples of a few pixels cost more than their
/// samples are worth.
pub fn plan_round(counts: &[u32], target: &[f64], max: u32) -> Round {
    let mut round = Round::new();
    for (p, (&n, &want)) in counts.iter().zip(target).enumerate() {
        let room = max.saturating_sub(n);
        if want - f64::from(n) < (MIN_STEP * f64::from(n)).max(1.0) || room == 0 {
            continue;
        }
        let lacks = (want - f64::from(n)).max(1.0);
        let nearest = 2f64.powf(lacks.log2().round()).min(f64::from(n.max(2)));
        let more = (nearest as u32).max(2).min(room);
        round.entry(more).or_default().push(p as u32);
    }
    // Defer the groups too small to be worth their waves' fixed cost; the
    // largest always stays, so a round with work renders some
    let total = round_samples(&round);
    round.retain(|&more, pixels| u64::from(more) * pixels.len() as u64 * MIN_GROUP_SHARE >= total);
    round
}

/// Halves every increment of `round` (those of 1 or 2 samples stay):
/// the round a time limit can still afford.
pub fn halved(round: &Round) -> Round {
    let mut out = Round::new();
    for (&more, pixels) in round {
        let half = if more > 2 { more / 2 } else { more };
        out.entry(half).or_default().extend_from_slice(pixels);
    }
    for pixels in out.values_mut() {
        pixels.sort_unstable();
    }
    out
}

/// Samples a round adds, over all its pixels.
pub fn round_samples(round: &Round) -> u64 {
    round
        .iter()
        .map(|(&more, pixels)| u64::from(more) * pixels.len() as u64)
        .sum()
}

/// Renders adaptively from an empty film until `goal` is met or every
/// pixel holds `max_spp` samples, and reads the film back. The renderer
/// must be built with `RenderOptions::adaptive`.
pub fn render_adaptive(
    renderer: &mut Renderer,
    goal: Goal,
    max_spp: u32,
    progress: OnWave<'_>,
) -> Result<RenderOutput> {
    renderer.restart()?;
    advance(renderer, goal, max_spp, progress)
}

/// Continues an adaptive render until `goal` is met (or every pixel holds
/// `max_spp` samples), and reads the film back; an empty film starts with
/// [`ADAPTIVE_MIN_SPP`] samples of every pixel. Goals can follow one
/// another on one film (`converge` climbs mean spp 16, 32, 64, ...).
pub fn advance(
    renderer: &mut Renderer,
    goal: Goal,
    max_spp: u32,
    progress: OnWave<'_>,
) -> Result<RenderOutput> {
    goal.validate()?;
    ensure!(
        max_spp >= 1,
        "adaptive::advance(max_spp) must be at least 1"
    );
    let pixels = renderer.pixel_count() as usize;
    let min = ADAPTIVE_MIN_SPP.min(max_spp);
    let counts = renderer.pixel_spp();
    let short: Vec<u32> = (0..pixels as u32)
        .filter(|&p| counts[p as usize] < min)
        .collect();
    if !short.is_empty() {
        ensure!(
            short.iter().all(|&p| counts[p as usize] == 0),
            "adaptive::advance continues a film whose pixels hold {min} samples or more, or none"
        );
        renderer.render_pixels(&short, min, progress)?;
    }
    // Lowered when the model's error falls short of the film's own estimate
    let mut model_target = match goal {
        Goal::Error(e) => e,
        _ => f64::NAN,
    };
    loop {
        let counts = renderer.pixel_spp();
        let out = renderer.output()?;
        let total: u64 = counts.iter().map(|&n| u64::from(n)).sum();
        let seconds = renderer.render_seconds();
        let predicted = predicted_rel_mse(&out.error_estimate, &out.mean);
        let done = match goal {
            Goal::Error(e) => predicted <= e,
            Goal::Time(limit) => seconds >= limit,
            Goal::MeanSpp(n) => total as f64 >= n * pixels as f64,
        };
        if done {
            return Ok(out);
        }
        let noise = Noise::of(&out, &counts);
        let target = match goal {
            Goal::Error(_) => noise.for_error(model_target, min, max_spp),
            Goal::MeanSpp(n) => noise.for_mean_spp(n, min, max_spp),
            Goal::Time(limit) => {
                let per_sample = seconds / total.max(1) as f64;
                let affordable = total as f64 + (limit - seconds) / per_sample.max(1e-12);
                noise.for_mean_spp(affordable / pixels as f64, min, max_spp)
            }
        };
        let mut round = plan_round(&counts, &target, max_spp);
        if let Goal::Time(limit) = goal {
            // Smaller steps when the round would not fit, and stop when
            // even the smallest does not
            let per_sample = seconds / total.max(1) as f64;
            let fits = |r: &Round| seconds + round_samples(r) as f64 * per_sample <= limit;
            while !fits(&round) && round.keys().any(|&more| more > 2) {
                round = halved(&round);
            }
            if !fits(&round) {
                return Ok(out);
            }
        }
        if round.is_empty() {
            let capped = counts.iter().all(|&n| n >= max_spp);
            match goal {
                // The model's error meets the target and the film's does
                // not: aim the model lower
                Goal::Error(e) if !capped => {
                    model_target *= (e / predicted).clamp(0.5, 0.95);
                    continue;
                }
                _ => return Ok(out),
            }
        }
        for (more, list) in round {
            renderer.render_pixels(&list, more, progress)?;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_is_shaped_by_its_eight_neighbours_not_by_itself() {
        let mut v = vec![0.0; 5 * 4];
        v[5 + 1] = 8.0;
        let m = neighbours_mean(&v, 5, 4);
        let lit: Vec<usize> = (0..20).filter(|&i| m[i] > 0.0).collect();
        assert_eq!(
            lit,
            [0, 1, 2, 5, 7, 10, 11, 12],
            "its neighbours, not itself"
        );
        // Inside, an eighth of it; at the corner, a third (three neighbours)
        assert_eq!((m[7], m[12], m[0]), (1.0, 1.0, 8.0 / 3.0));
        assert_eq!(neighbours_mean(&[5.0], 1, 1), [5.0]);
    }

    /// Noise of pixels with per-sample relative variances `v` (shape = v).
    fn noise(v: &[f64]) -> Noise {
        Noise {
            per_sample: v.to_vec(),
            shape: v.to_vec(),
            calibration: 1.0,
        }
    }

    #[test]
    fn the_allocation_grows_as_the_root_of_the_variance_and_meets_its_target() {
        let n = noise(&[1.0, 4.0, 16.0, 0.0]);
        let a = n.for_error(0.01, 16, 1 << 20);
        // n ∝ sqrt(v) where the minimum does not bind
        assert!((a[1] / a[0] - 2.0).abs() < 1e-6, "{a:?}");
        assert!((a[2] / a[1] - 2.0).abs() < 1e-6, "{a:?}");
        assert_eq!(a[3], 16.0, "a noiseless pixel keeps the minimum");
        assert!((n.predicted(&a) - 0.01).abs() < 1e-9, "{}", n.predicted(&a));
        // The fewest samples for the error: any other split of the same
        // total with the same shape predicts more error
        let total: f64 = a.iter().sum();
        let even = vec![total / 4.0; 4];
        assert!(n.predicted(&even) > 0.01);
        // A mean spp is met exactly where the bounds allow
        let m = n.for_mean_spp(100.0, 16, 1 << 20);
        assert!((m.iter().sum::<f64>() / 4.0 - 100.0).abs() < 1e-6);
        // An unreachable goal gives the most samples everywhere
        assert_eq!(n.for_error(1e-30, 16, 64), [64.0; 4]);
    }

    #[test]
    fn a_round_adds_a_power_of_two_to_pixels_short_of_their_target() {
        let counts = [16, 16, 16, 26, 128, 100, 16, 16];
        let target = [16.0, 17.0, 1000.0, 33.0, 1000.0, 1000.0, 40.0, 21.0];
        // With 64 pixels more that lack 24, the groups of 4, 8 and 28
        // samples (each under 1/16 of the round's 1096) wait for a later
        // round
        let mut many = counts.to_vec();
        many.extend([16; 64]);
        let mut wants = target.to_vec();
        wants.extend([40.0; 64]);
        let big = plan_round(&many, &wants, 128);
        assert_eq!(big.keys().copied().collect::<Vec<_>>(), [16]);
        assert_eq!(big[&16].len(), 66);
        let round = plan_round(&counts, &target, 128);
        let groups: Vec<_> = round.clone().into_iter().collect();
        // 1 lacking of 16: less than a quarter, none; 984 lacking: at most
        // doubled (16); 7 lacking of 26: 8; at the cap: none; 28 of room:
        // 28; 24 lacking: 16 (of 16 and 32, the nearer in ratio); 5 of 16:
        // 4, but 4 samples are under 1/16 of the round's 72, and wait
        assert_eq!(groups, [(8, vec![3]), (16, vec![2, 6]), (28, vec![5])]);
        assert_eq!(round_samples(&round), 8 + 32 + 28);
        let half = halved(&round);
        assert_eq!(
            half.into_iter().collect::<Vec<_>>(),
            [(4, vec![3]), (8, vec![2, 6]), (14, vec![5])]
        );
    }
}
