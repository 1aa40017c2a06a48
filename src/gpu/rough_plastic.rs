//! The rough coating of a rough plastic, integrated once per material on
//! the CPU, as Mitsuba 3's `roughplastic` precomputes it
//! (`parameters_changed` in its `src/bsdfs/roughplastic.cpp`):
//!
//! - the coating's **transmittance** T(μ) for light arriving from outside
//!   at cos θ = μ: the fraction refracted into the coating through the
//!   microfacets, ∫ (1 − F(wi·m)) G1(wt, m) D_wi(m) dm over the normals m
//!   visible from wi (density D_wi, Heitz and d'Eon 2014), wt the
//!   direction refracted through m and G1 its masking; tabulated at
//!   [`ROUGH_TRANSMITTANCE_RES`] cosines evenly spaced over [0, 1] (the
//!   first at 1e-6), which the kernels interpolate linearly;
//! - the **internal reflectance**: the fraction of diffuse light from the
//!   base that the coating reflects back down, 2 ∫ R(μ) μ dμ with R the
//!   rough reflectance of index ratio 1 / eta (F G1 of the mirrored
//!   direction, over the visible normals), taken as Mitsuba takes it: twice
//!   the mean of R(μ) μ over the same cosines. That rule stands about 1.5%
//!   below the integral (its weights sum to 64/63 and its ends count
//!   whole); lancer keeps it, so that its plastic is Mitsuba's.
//!
//! Both integrals run over the visible normals' sampling space [0, 1]² by
//! Gauss-Legendre quadrature, in f64 (Mitsuba: f32), with the visible
//! normals drawn exactly (GGX: Heitz 2018; Beckmann: the slope CDF
//! inverted by bracketed Newton steps) and Smith's exact masking (the
//! kernels' terms); the rule's nodes are 32 a side where the Fresnel term
//! is smooth and 128 where total internal reflection cuts it, as Mitsuba's.
//! `tests/it/materials.rs` checks the figures against an independent slope
//! quadrature and against Mitsuba's own.

use std::f64::consts::PI;

use crate::interface::ROUGH_TRANSMITTANCE_RES;
use crate::scene::Microfacet;

/// A rough coating's figures for the kernels.
#[derive(Debug, Clone, PartialEq)]
pub struct RoughCoating {
    /// T(μ) at μ = max(1e-6, i / (RES − 1)).
    pub transmittance: Vec<f32>,
    /// The diffuse reflectance inside the coating (Mitsuba's rule).
    pub internal_reflectance: f32,
}

/// Computes the coating's figures for microfacets of `distribution` and
/// roughness `alpha` (> 0) over index ratio `eta` (inside over outside,
/// > 0 and not 1).
pub fn rough_coating(distribution: Microfacet, alpha: f32, eta: f32) -> RoughCoating {
    use rayon::prelude::*;
    let d = Distribution {
        ggx: distribution == Microfacet::Ggx,
        alpha: f64::from(alpha),
    };
    let eta = f64::from(eta);
    let n = ROUGH_TRANSMITTANCE_RES as usize;
    let cosines: Vec<f64> = (0..n)
        .map(|i| (i as f64 / (n - 1) as f64).max(1e-6))
        .collect();
    let rows: Vec<(f64, f64)> = cosines
        .par_iter()
        .map(|&mu| {
            (
                d.directional(mu, eta, Lobe::Transmission, nodes(eta)),
                d.directional(mu, 1.0 / eta, Lobe::Reflection, nodes(1.0 / eta)),
            )
        })
        .collect();
    let internal = 2.0
        * rows
            .iter()
            .zip(&cosines)
            .map(|(r, &mu)| r.1 * mu)
            .sum::<f64>()
        / n as f64;
    RoughCoating {
        transmittance: rows.iter().map(|r| r.0 as f32).collect(),
        internal_reflectance: internal as f32,
    }
}

/// Gauss-Legendre nodes a side for index ratio `eta`: total internal
/// reflection cuts the Fresnel term where eta < 1, which needs more.
fn nodes(eta: f64) -> usize {
    if eta > 1.0 {
        32
    } else {
        128
    }
}

/// Which way the light leaves the coating's microfacets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lobe {
    /// Mirrored about the microfacet, weighed by F.
    Reflection,
    /// Refracted through it, weighed by 1 − F.
    Transmission,
}

/// An isotropic microfacet distribution in f64.
#[derive(Debug, Clone, Copy)]
struct Distribution {
    ggx: bool,
    alpha: f64,
}

/// Dot product of two 3-vectors.
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The unit vector along `v`.
fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = dot(v, v).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

impl Distribution {
    /// Smith's masking of direction `v` by microfacets of normal `m`: 0
    /// where `v` sees the back of the facet.
    fn g1(&self, v: [f64; 3], m: [f64; 3]) -> f64 {
        if dot(v, m) * v[2] <= 0.0 {
            return 0.0;
        }
        let xy2 = v[0] * v[0] + v[1] * v[1];
        if xy2 == 0.0 {
            return 1.0;
        }
        let tan2 = xy2 / (v[2] * v[2]);
        let lambda = if self.ggx {
            0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
        } else {
            let a = 1.0 / (self.alpha * tan2.sqrt());
            0.5 * ((-a * a).exp() / (a * PI.sqrt()) - statrs::function::erf::erfc(a))
        };
        1.0 / (1.0 + lambda.max(0.0))
    }

    /// The slope along the view's azimuth of a normal of the unit-roughness
    /// Beckmann distribution visible from a view at cos θ = `cos_t` (θ > 0),
    /// at quantile `u` of its distribution.
    fn visible_slope_x(&self, cos_t: f64, u: f64) -> f64 {
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let tan_t = sin_t / cos_t;
        let cot_t = cos_t / sin_t;
        // x has density ∝ (cot − x) exp(−x²) for x < cot; its CDF, scaled,
        // is 1 + erf(x) + tan exp(−x²) / √π, increasing on (−∞, cot)
        use statrs::function::erf::erf;
        let c = tan_t / PI.sqrt();
        let cdf = |x: f64| 1.0 + erf(x) + c * (-x * x).exp();
        let target = u * cdf(cot_t);
        let (mut lo, mut hi) = (-30.0f64, cot_t.min(30.0));
        let mut x = 0.5 * (lo + hi);
        for _ in 0..200 {
            let g = cdf(x) - target;
            if g > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            let slope = 2.0 / PI.sqrt() * (-x * x).exp() * (1.0 - x * tan_t);
            let next = x - g / slope;
            let next = if slope > 0.0 && next > lo && next < hi {
                next
            } else {
                0.5 * (lo + hi)
            };
            if (next - x).abs() <= 1e-15 * x.abs().max(1.0) || hi - lo <= 1e-15 {
                return next;
            }
            x = next;
        }
        x
    }

    /// The normals visible from `v` (in the xz-plane, v.z > 0), at
    /// (u1, u2) of their sampling space: for Beckmann, the slope along
    /// the view's azimuth at quantile u1 (`slope_x`, precomputed) and the
    /// one across it at quantile u2.
    fn visible_normal(&self, v: [f64; 3], slope_x: f64, u1: f64, u2: f64) -> [f64; 3] {
        let a = self.alpha;
        let vs = normalize([a * v[0], a * v[1], v[2]]);
        if self.ggx {
            // Heitz 2018: a uniform point of the disc, squeezed onto the
            // visible half, lifted onto the hemisphere about the view
            let len2 = vs[0] * vs[0] + vs[1] * vs[1];
            let t1 = if len2 > 0.0 {
                let l = len2.sqrt();
                [-vs[1] / l, vs[0] / l, 0.0]
            } else {
                [1.0, 0.0, 0.0]
            };
            let t2 = [
                vs[1] * t1[2] - vs[2] * t1[1],
                vs[2] * t1[0] - vs[0] * t1[2],
                vs[0] * t1[1] - vs[1] * t1[0],
            ];
            let r = u1.sqrt();
            let phi = 2.0 * PI * u2;
            let p1 = r * phi.cos();
            let h = 0.5 * (1.0 + vs[2]);
            let p2 = (1.0 - h) * (1.0 - p1 * p1).max(0.0).sqrt() + h * r * phi.sin();
            let p3 = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
            let n: Vec<f64> = (0..3)
                .map(|k| p1 * t1[k] + p2 * t2[k] + p3 * vs[k])
                .collect();
            return normalize([a * n[0], a * n[1], n[2].max(0.0)]);
        }
        // Beckmann: the slope across the view is a plain Gaussian
        let y = statrs::function::erf::erf_inv(2.0 * u2 - 1.0);
        let len = (vs[0] * vs[0] + vs[1] * vs[1]).sqrt();
        let (c, s) = if len > 0.0 {
            (vs[0] / len, vs[1] / len)
        } else {
            (1.0, 0.0)
        };
        let (sx, sy) = (c * slope_x - s * y, s * slope_x + c * y);
        normalize([-a * sx, -a * sy, 1.0])
    }

    /// The slope quantile the Beckmann mapping needs for node `u1` of a
    /// view at cos θ = `cos_t` (normal incidence: a plain Gaussian).
    fn slope_x(&self, cos_t: f64, u1: f64) -> f64 {
        if self.ggx {
            return 0.0;
        }
        let vs_z = cos_t / (self.alpha * self.alpha * (1.0 - cos_t * cos_t) + cos_t * cos_t).sqrt();
        if vs_z >= 1.0 - 1e-12 {
            return statrs::function::erf::erf_inv(2.0 * u1 - 1.0);
        }
        self.visible_slope_x(vs_z, u1)
    }

    /// The rough coating's reflectance or transmittance for light from
    /// cos θ = `mu` across index ratio `eta` (eta_t / eta_i): the Fresnel
    /// part of `lobe` times the masking of the leaving direction, averaged
    /// over the visible normals by the Gauss-Legendre rule of `nodes` a side.
    fn directional(&self, mu: f64, eta: f64, lobe: Lobe, nodes: usize) -> f64 {
        let wi = [(1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu];
        let (x, w) = gauss_legendre(nodes);
        let mut sum = 0.0;
        for (xj, wj) in x.iter().zip(&w) {
            let u1 = 0.5 * (xj + 1.0);
            let slope_x = self.slope_x(mu, u1);
            for (xk, wk) in x.iter().zip(&w) {
                let u2 = 0.5 * (xk + 1.0);
                let m = self.visible_normal(wi, slope_x, u1, u2);
                let cos_i = dot(wi, m);
                if cos_i <= 0.0 {
                    continue;
                }
                let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
                let (f, cos_t) = if sin2_t >= 1.0 {
                    (1.0, 0.0)
                } else {
                    let ct = (1.0 - sin2_t).sqrt();
                    let rs = (cos_i - eta * ct) / (cos_i + eta * ct);
                    let rp = (eta * cos_i - ct) / (eta * cos_i + ct);
                    (0.5 * (rs * rs + rp * rp), ct)
                };
                let value = match lobe {
                    Lobe::Reflection => {
                        let r = [
                            2.0 * cos_i * m[0] - wi[0],
                            2.0 * cos_i * m[1] - wi[1],
                            2.0 * cos_i * m[2] - wi[2],
                        ];
                        if r[2] > 0.0 {
                            f * self.g1(r, m)
                        } else {
                            0.0
                        }
                    }
                    Lobe::Transmission => {
                        let k = cos_i / eta - cos_t;
                        let t = [
                            -wi[0] / eta + k * m[0],
                            -wi[1] / eta + k * m[1],
                            -wi[2] / eta + k * m[2],
                        ];
                        if t[2] < 0.0 && f < 1.0 {
                            (1.0 - f) * self.g1(t, m)
                        } else {
                            0.0
                        }
                    }
                };
                sum += value * wj * wk;
            }
        }
        0.25 * sum
    }
}

/// The nodes and weights of the `n`-point Gauss-Legendre rule on [−1, 1],
/// by Newton's method on the Legendre polynomial from the usual cosine
/// guesses.
fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(z) and its derivative by the three-term recurrence
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-15 {
                break;
            }
        }
        x[i] = -z;
        x[n - 1 - i] = z;
        let wi = 2.0 / ((1.0 - z * z) * dp * dp);
        w[i] = wi;
        w[n - 1 - i] = wi;
    }
    (x, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in [1usize, 2, 5, 32, 128] {
            let (x, w) = gauss_legendre(n);
            // Exact up to degree 2n - 1: ∫ x^k over [-1, 1]
            for k in 0..(2 * n).min(40) {
                let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let want = if k % 2 == 1 {
                    0.0
                } else {
                    2.0 / (k as f64 + 1.0)
                };
                assert!((got - want).abs() < 1e-12, "n {n}, x^{k}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn visible_normals_are_distributed_as_their_density() {
        // Seen from the normal, the visible normals have density D(m) m.z,
        // so the mean of (v·m)⁺ / m.z is ∫ D(m) (v·m)⁺ dm, the projected
        // area v.z (1 + Λ(v)) = v.z / G1(v) for any direction v; away from
        // the normal every sampled normal faces the view. (v·m)⁺ / m.z is
        // unbounded where m.z -> 0, in GGX's long tails, where the rule
        // converges slowly: hence 5e-3
        for ggx in [true, false] {
            for alpha in [0.1, 0.3, 1.0] {
                let d = Distribution { ggx, alpha };
                let (x, w) = gauss_legendre(256);
                for cos_v in [1.0f64, 0.7, 0.3, 0.05] {
                    let v = [(1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v];
                    let mut mean = 0.0;
                    for (xj, wj) in x.iter().zip(&w) {
                        let u1 = 0.5 * (xj + 1.0);
                        let sx = d.slope_x(1.0, u1);
                        for (xk, wk) in x.iter().zip(&w) {
                            let m = d.visible_normal([0.0, 0.0, 1.0], sx, u1, 0.5 * (xk + 1.0));
                            mean += 0.25 * wj * wk * dot(v, m).max(0.0) / m[2];
                        }
                    }
                    let want = cos_v / d.g1(v, [0.0, 0.0, 1.0]);
                    assert!(
                        (mean / want - 1.0).abs() < 5e-3,
                        "ggx {ggx}, alpha {alpha}, cos_v {cos_v}: {mean} vs {want}"
                    );
                }
                for mu in [0.7, 0.3, 1e-3] {
                    let wi = [(1.0f64 - mu * mu).sqrt(), 0.0, mu];
                    for (xj, _) in x.iter().zip(&w) {
                        let u1 = 0.5 * (xj + 1.0);
                        let sx = d.slope_x(mu, u1);
                        for (xk, _) in x.iter().zip(&w) {
                            let m = d.visible_normal(wi, sx, u1, 0.5 * (xk + 1.0));
                            assert!(
                                dot(wi, m) > 0.0 && m[2] > 0.0,
                                "{m:?} faces away from {wi:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_rule_has_converged() {
        // Mitsuba's node counts against four times as many a side: the
        // transmittance to 5e-4, the reflectance (cut by total internal
        // reflection) to 5e-3
        for ggx in [true, false] {
            for alpha in [0.01, 0.3, 1.0] {
                let d = Distribution { ggx, alpha };
                for mu in [1.0, 0.5, 0.05, 1e-6] {
                    let t = d.directional(mu, 1.5, Lobe::Transmission, nodes(1.5));
                    let t4 = d.directional(mu, 1.5, Lobe::Transmission, 4 * nodes(1.5));
                    assert!(
                        (t - t4).abs() < 5e-4,
                        "ggx {ggx}, alpha {alpha}, mu {mu}: T {t} vs {t4}"
                    );
                    let r = d.directional(mu, 1.0 / 1.5, Lobe::Reflection, nodes(1.0 / 1.5));
                    let r4 = d.directional(mu, 1.0 / 1.5, Lobe::Reflection, 4 * nodes(1.0 / 1.5));
                    assert!(
                        (r - r4).abs() < 5e-3,
                        "ggx {ggx}, alpha {alpha}, mu {mu}: R {r} vs {r4}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_smooth_coating_is_fresnel() {
        // alpha -> 0: the transmittance is 1 - F(mu) wherever alpha tan θ
        // stays small (at grazing incidence no roughness is small)
        for distribution in [Microfacet::Ggx, Microfacet::Beckmann] {
            let c = rough_coating(distribution, 1e-4, 1.5);
            for (i, t) in c.transmittance.iter().enumerate().skip(3) {
                let mu = i as f64 / 63.0;
                let sin2_t = (1.0 - mu * mu) / 2.25;
                let ct = (1.0 - sin2_t).sqrt();
                let rs = (mu - 1.5 * ct) / (mu + 1.5 * ct);
                let rp = (1.5 * mu - ct) / (1.5 * mu + ct);
                let f = 0.5 * (rs * rs + rp * rp);
                assert!(
                    (f64::from(*t) - (1.0 - f)).abs() < 2e-3,
                    "{distribution:?} mu {mu}: {t} vs {}",
                    1.0 - f
                );
            }
        }
    }
}
