//! Directional albedo of the phong and glossy materials of docs/scene-format.md,
//! by deterministic numerical integration in f64: the figures the white
//! furnace tests of `tests/it/materials.rs` compare renders against.
//!
//! Directional albedo: the fraction of light arriving from the view
//! direction (at angle acos(cos_o) from the normal) that a surface sends
//! back into the upper hemisphere, i.e. what a pixel shows in a furnace of
//! uniform radiance 1 when every path escapes after one bounce.
#![allow(dead_code)]

use std::f64::consts::PI;

/// Midpoints in t = cos^(n+1)(alpha) for [`phong_albedo`].
const PHONG_T_STEPS: usize = 8192;

/// Rings of the disc for [`glossy_albedo`].
const GLOSSY_RINGS: usize = 8192;

/// Mean over phi in [0, 2 pi) of max(0, a + b cos phi), b >= 0: exact.
fn mean_positive_part(a: f64, b: f64) -> f64 {
    if a >= b {
        a
    } else if a <= -b {
        0.0
    } else {
        let phi0 = (-a / b).acos();
        (a * phi0 + b * phi0.sin()) / PI
    }
}

/// Sine and cosine of the angle theta_o whose cosine is `cos_o`.
fn sin_cos(cos_o: f64) -> (f64, f64) {
    assert!(
        (0.0..=1.0).contains(&cos_o),
        "cos_o = {cos_o} outside [0, 1]"
    );
    ((1.0 - cos_o * cos_o).max(0.0).sqrt(), cos_o)
}

/// Specular part of the phong albedo for ks = 1:
/// ∫ (n+2)/(2π) cos^n(α) cos θ_i dω over the directions with cos θ_i > 0 and
/// cos α > 0.
///
/// With t = cos^(n+1)(α) uniform in [0, 1] and φ uniform in [0, 2π), the
/// integral is (n+2)/(n+1) · E[max(0, cos θ_i)], and cos θ_i =
/// cos α cos θ_o + sin α sin θ_o cos φ (the mirror direction makes the
/// angle θ_o with the normal). The φ average of the positive part is exact
/// ([`mean_positive_part`]); t = s² with s on a midpoint grid. The integrand is
/// smooth in t even for n = 1e7, which a grid over α would not resolve.
fn phong_specular_albedo(n: f64, cos_o: f64) -> f64 {
    let (sin_o, cos_o) = sin_cos(cos_o);
    let mut sum = 0.0;
    for k in 0..PHONG_T_STEPS {
        // t = s², s on the midpoint grid: smooths the t^(1/(n+1)) corner at 0
        let s = (k as f64 + 0.5) / PHONG_T_STEPS as f64;
        // cos α = t^(1/(n+1)); sin α from 1 - cos² α = -expm1(2 ln t / (n+1)),
        // which keeps its digits when α is tiny (huge n)
        let l = 2.0 * s.ln() / (n + 1.0);
        let cos_a = l.exp();
        let sin_a = (-(2.0 * l).exp_m1()).max(0.0).sqrt();
        sum += 2.0 * s * mean_positive_part(cos_a * cos_o, sin_a * sin_o);
    }
    (n + 2.0) / (n + 1.0) * sum / PHONG_T_STEPS as f64
}

/// Directional albedo of the normalised modified Phong of docs/scene-format.md
/// for one channel: `kd + ks * ∫ (n+2)/(2π) cos^n(α) cos θ_i dω` over the
/// upper hemisphere, α the angle between the mirror direction of wo and wi
/// (the lobe is 0 where cos α <= 0). `cos_o` is the cosine of the view
/// direction with the normal.
pub fn phong_albedo(kd: f64, ks: f64, n: f64, cos_o: f64) -> f64 {
    kd + ks * phong_specular_albedo(n, cos_o)
}

/// The same integral on a plain 2-D midpoint grid over (t, φ), as the brief
/// describes it: slower and less exact, kept to cross-check [`phong_albedo`].
pub fn phong_albedo_grid(kd: f64, ks: f64, n: f64, cos_o: f64, steps: usize) -> f64 {
    let (sin_o, cos_o) = sin_cos(cos_o);
    let mut sum = 0.0;
    for i in 0..steps {
        let t = (i as f64 + 0.5) / steps as f64;
        let l = t.ln() / (n + 1.0);
        let cos_a = l.exp();
        let sin_a = (-(2.0 * l).exp_m1()).max(0.0).sqrt();
        for j in 0..steps {
            let phi = 2.0 * PI * (j as f64 + 0.5) / steps as f64;
            sum += (cos_a * cos_o + sin_a * sin_o * phi.cos()).max(0.0);
        }
    }
    kd + ks * (n + 2.0) / (n + 1.0) * sum / (steps * steps) as f64
}

/// Directional albedo of the glossy material of docs/scene-format.md for one
/// channel: `refl` times the fraction of the disc of radius sin(cone),
/// perpendicular to the unit mirror direction r, whose points d give
/// D = r + d above the surface (D·n > 0).
///
/// With d = ρ (cos φ e1 + sin φ e2), e1 the unit projection of n on the
/// disc's plane, D·n = cos θ_o + ρ sin θ_o cos φ. Rings of equal area (a
/// midpoint grid in ρ²) with the exact fraction of φ on each.
pub fn glossy_albedo(refl: f64, cone_deg: f64, cos_o: f64) -> f64 {
    assert!(
        (0.0..90.0).contains(&cone_deg),
        "cone angle {cone_deg} outside [0, 90)"
    );
    let (sin_o, cos_o) = sin_cos(cos_o);
    let s = cone_deg.to_radians().sin();
    let mut sum = 0.0;
    for k in 0..GLOSSY_RINGS {
        let rho = s * ((k as f64 + 0.5) / GLOSSY_RINGS as f64).sqrt();
        let b = rho * sin_o;
        // Fraction of φ with cos θ_o + b cos φ > 0
        sum += if cos_o >= b {
            1.0
        } else {
            (-cos_o / b).acos() / PI
        };
    }
    refl * sum / GLOSSY_RINGS as f64
}

/// The same fraction in closed form: the disc less the circular segment
/// beyond the chord at distance cot θ_o from its centre.
pub fn glossy_albedo_closed_form(refl: f64, cone_deg: f64, cos_o: f64) -> f64 {
    let (sin_o, cos_o) = sin_cos(cos_o);
    let s = cone_deg.to_radians().sin();
    if s == 0.0 || cos_o >= s * sin_o {
        return refl;
    }
    // Work in units of the disc radius: chord at distance c
    let c = cos_o / (s * sin_o);
    let segment = c.acos() - c * (1.0 - c * c).sqrt();
    refl * (1.0 - segment / PI)
}

/// Steps in u = r / (1 + r) (r: the microfacet slope over alpha) for
/// [`microfacet_albedo`].
const SLOPE_STEPS: usize = 512;
/// Steps in the slope's azimuth for [`microfacet_albedo`].
const SLOPE_AZIMUTHS: usize = 192;

/// Directional albedo of an isotropic rough perfect reflector (conductor
/// of material `none`, Fresnel 1) of roughness `alpha`, GGX (`ggx` true)
/// or Beckmann: ∫ D(h) G1(o, h) G1(i, h) (o·h)⁺ / cos θ_o dω_h over the
/// microfacet normals h whose mirror direction i leaves above the surface,
/// with Smith's exact masking. The normals are written by their slopes
/// (p, q) = alpha r (cos φ, sin φ), dω_h = cos³ θ_h dp dq, on a midpoint
/// grid in u = r / (1 + r) and φ.
pub fn microfacet_albedo(ggx: bool, alpha: f64, cos_o: f64) -> f64 {
    microfacet_weight_moment(ggx, alpha, cos_o, 1)
}

/// The `power`-th moment of the sample weight G1(i, h) of visible-normal
/// sampling of that reflector (0 for a direction below the surface): the
/// integral of [`microfacet_albedo`] with G1(i, h) raised to `power`. The
/// first moment is the albedo; the second gives the exact variance of a
/// furnace pixel's samples.
pub fn microfacet_weight_moment(ggx: bool, alpha: f64, cos_o: f64, power: i32) -> f64 {
    let (sin_o, cos_o) = sin_cos(cos_o.max(1e-6));
    let o = [sin_o, 0.0, cos_o];
    let g1 = |v: [f64; 3], h: [f64; 3]| smith_g1(ggx, alpha, v, h);
    let mut sum = 0.0;
    for iu in 0..SLOPE_STEPS {
        let u = (iu as f64 + 0.5) / SLOPE_STEPS as f64;
        let r = u / (1.0 - u);
        let dr = 1.0 / ((1.0 - u) * (1.0 - u) * SLOPE_STEPS as f64);
        let t2 = alpha * alpha * r * r; // tan² θ_h
        let cos2 = 1.0 / (1.0 + t2);
        // D(h) cos³ θ_h: the density per unit slope area
        let d_slope = if ggx {
            1.0 / (PI * alpha * alpha * (1.0 + r * r).powi(2)) / cos2.sqrt()
        } else {
            (-r * r).exp() / (PI * alpha * alpha) / cos2.sqrt()
        };
        for ip in 0..SLOPE_AZIMUTHS {
            let phi = 2.0 * PI * (ip as f64 + 0.5) / SLOPE_AZIMUTHS as f64;
            let (p, q) = (alpha * r * phi.cos(), alpha * r * phi.sin());
            let len = (1.0 + p * p + q * q).sqrt();
            let h = [-p / len, -q / len, 1.0 / len];
            let oh = dot(o, h);
            if oh <= 0.0 {
                continue;
            }
            let i = [
                2.0 * oh * h[0] - o[0],
                2.0 * oh * h[1] - o[1],
                2.0 * oh * h[2] - o[2],
            ];
            if i[2] <= 0.0 {
                continue;
            }
            let area = alpha * alpha * r * dr * 2.0 * PI / SLOPE_AZIMUTHS as f64;
            sum += d_slope * g1(o, h) * g1(i, h).powi(power) * oh / cos_o * area;
        }
    }
    sum
}

/// The `power`-th moment of the sample weight of a rough dielectric (both
/// specular factors 1) of roughness `alpha` and index ratio `eta` (eta_t /
/// eta_i across the surface from the viewer's side), GGX or Beckmann, for
/// light leaving at `cos_o`: over the visible normals h, density D(h)
/// G1(o, h) (o·h)⁺ / cos θ_o, reflection with the Fresnel reflectance F of
/// o·h and weight G1(i, h) (0 below the surface), refraction with 1 - F and
/// weight G1(t, h) / eta² (0 above the surface; radiance is scaled by
/// 1 / eta² as it crosses, as in Mitsuba). The first moment is the
/// directional albedo in a white furnace where every path escapes after one
/// bounce, on either side; the same slope grid as [`microfacet_weight_moment`].
pub fn rough_dielectric_weight_moment(
    ggx: bool,
    alpha: f64,
    eta: f64,
    cos_o: f64,
    power: i32,
) -> f64 {
    let (sin_o, cos_o) = sin_cos(cos_o.max(1e-6));
    let o = [sin_o, 0.0, cos_o];
    let g1 = |v: [f64; 3], h: [f64; 3]| smith_g1(ggx, alpha, v, h);
    let mut sum = 0.0;
    for iu in 0..SLOPE_STEPS {
        let u = (iu as f64 + 0.5) / SLOPE_STEPS as f64;
        let r = u / (1.0 - u);
        let dr = 1.0 / ((1.0 - u) * (1.0 - u) * SLOPE_STEPS as f64);
        let t2 = alpha * alpha * r * r;
        let cos2 = 1.0 / (1.0 + t2);
        let d_slope = if ggx {
            1.0 / (PI * alpha * alpha * (1.0 + r * r).powi(2)) / cos2.sqrt()
        } else {
            (-r * r).exp() / (PI * alpha * alpha) / cos2.sqrt()
        };
        for ip in 0..SLOPE_AZIMUTHS {
            let phi = 2.0 * PI * (ip as f64 + 0.5) / SLOPE_AZIMUTHS as f64;
            let (p, q) = (alpha * r * phi.cos(), alpha * r * phi.sin());
            let len = (1.0 + p * p + q * q).sqrt();
            let h = [-p / len, -q / len, 1.0 / len];
            let oh = dot(o, h);
            if oh <= 0.0 {
                continue;
            }
            // Snell across the microfacet: F, and the refracted cosine
            let sin2_t = (1.0 - oh * oh) / (eta * eta);
            let (f, cos_t) = if sin2_t >= 1.0 {
                (1.0, 0.0)
            } else {
                let ct = (1.0 - sin2_t).sqrt();
                let rs = (oh - eta * ct) / (oh + eta * ct);
                let rp = (eta * oh - ct) / (eta * oh + ct);
                (0.5 * (rs * rs + rp * rp), ct)
            };
            let i = [
                2.0 * oh * h[0] - o[0],
                2.0 * oh * h[1] - o[1],
                2.0 * oh * h[2] - o[2],
            ];
            let mut weight = 0.0;
            if i[2] > 0.0 {
                weight += f * g1(i, h).powi(power);
            }
            if f < 1.0 {
                let k = oh / eta - cos_t;
                let t = [
                    -o[0] / eta + k * h[0],
                    -o[1] / eta + k * h[1],
                    -o[2] / eta + k * h[2],
                ];
                if t[2] < 0.0 {
                    weight += (1.0 - f) * (g1(t, h) / (eta * eta)).powi(power);
                }
            }
            let area = alpha * alpha * r * dr * 2.0 * PI / SLOPE_AZIMUTHS as f64;
            sum += d_slope * g1(o, h) * weight * oh / cos_o * area;
        }
    }
    sum
}

/// The two lobes of a rough dielectric interface (both specular factors 1)
/// of roughness `alpha` and index ratio `eta` (eta_t / eta_i) for light
/// from cos θ = `cos_o`, without the 1 / eta² of radiance: (∫ F G1(i, h),
/// ∫ (1 − F) G1(t, h)) over the visible normals h, i the mirrored and t
/// the refracted direction (each 0 on the wrong side). The second is a
/// rough plastic's coating transmittance T(cos_o), the first its rough
/// reflectance (from inside with 1 / eta); the same slope grid as
/// [`microfacet_weight_moment`].
pub fn rough_interface_lobes(ggx: bool, alpha: f64, eta: f64, cos_o: f64) -> (f64, f64) {
    let (sin_o, cos_o) = sin_cos(cos_o.max(1e-6));
    let o = [sin_o, 0.0, cos_o];
    let g1 = |v: [f64; 3], h: [f64; 3]| smith_g1(ggx, alpha, v, h);
    let (mut reflected, mut refracted) = (0.0, 0.0);
    for iu in 0..SLOPE_STEPS {
        let u = (iu as f64 + 0.5) / SLOPE_STEPS as f64;
        let r = u / (1.0 - u);
        let dr = 1.0 / ((1.0 - u) * (1.0 - u) * SLOPE_STEPS as f64);
        let t2 = alpha * alpha * r * r;
        let cos2 = 1.0 / (1.0 + t2);
        let d_slope = if ggx {
            1.0 / (PI * alpha * alpha * (1.0 + r * r).powi(2)) / cos2.sqrt()
        } else {
            (-r * r).exp() / (PI * alpha * alpha) / cos2.sqrt()
        };
        for ip in 0..SLOPE_AZIMUTHS {
            let phi = 2.0 * PI * (ip as f64 + 0.5) / SLOPE_AZIMUTHS as f64;
            let (p, q) = (alpha * r * phi.cos(), alpha * r * phi.sin());
            let len = (1.0 + p * p + q * q).sqrt();
            let h = [-p / len, -q / len, 1.0 / len];
            let oh = dot(o, h);
            if oh <= 0.0 {
                continue;
            }
            let sin2_t = (1.0 - oh * oh) / (eta * eta);
            let (f, cos_t) = if sin2_t >= 1.0 {
                (1.0, 0.0)
            } else {
                let ct = (1.0 - sin2_t).sqrt();
                let rs = (oh - eta * ct) / (oh + eta * ct);
                let rp = (eta * oh - ct) / (eta * oh + ct);
                (0.5 * (rs * rs + rp * rp), ct)
            };
            let weight = d_slope * g1(o, h) * oh / cos_o * alpha * alpha * r * dr * 2.0 * PI
                / SLOPE_AZIMUTHS as f64;
            let i = [
                2.0 * oh * h[0] - o[0],
                2.0 * oh * h[1] - o[1],
                2.0 * oh * h[2] - o[2],
            ];
            if i[2] > 0.0 {
                reflected += weight * f * g1(i, h);
            }
            if f < 1.0 {
                let k = oh / eta - cos_t;
                let t = [
                    -o[0] / eta + k * h[0],
                    -o[1] / eta + k * h[1],
                    -o[2] / eta + k * h[2],
                ];
                if t[2] < 0.0 {
                    refracted += weight * (1.0 - f) * g1(t, h);
                }
            }
        }
    }
    (reflected, refracted)
}

/// A function of the view angle tabulated on a uniform grid of angles over
/// [0°, 90°] and interpolated linearly: evaluating the integrals for every
/// sub-pixel ray would take far too long.
pub struct AngleTable {
    values: Vec<f64>,
}

impl AngleTable {
    /// Tabulates `f(cos_o)` at `intervals + 1` angles from 0° to 90°.
    pub fn new(intervals: usize, f: impl Fn(f64) -> f64 + Sync) -> AngleTable {
        use rayon::prelude::*;
        let values = (0..=intervals)
            .into_par_iter()
            .map(|i| {
                let theta = 0.5 * PI * i as f64 / intervals as f64;
                f(theta.cos().clamp(0.0, 1.0))
            })
            .collect();
        AngleTable { values }
    }

    /// The tabulated function at the angle whose cosine is `cos_o`.
    pub fn at(&self, cos_o: f64) -> f64 {
        let intervals = self.values.len() - 1;
        let x = cos_o.clamp(0.0, 1.0).acos() / (0.5 * PI) * intervals as f64;
        let i = (x.floor() as usize).min(intervals - 1);
        let f = x - i as f64;
        self.values[i] * (1.0 - f) + self.values[i + 1] * f
    }
}

/// Dot product of two 3-vectors.
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Smith's Λ of direction `v` (local frame, z the normal) for GGX or
/// Beckmann of roughness `alpha`.
fn smith_lambda(ggx: bool, alpha: f64, v: [f64; 3]) -> f64 {
    let tan2 = (v[0] * v[0] + v[1] * v[1]) / (v[2] * v[2]);
    if tan2 == 0.0 {
        return 0.0;
    }
    if ggx {
        0.5 * (-1.0 + (1.0 + alpha * alpha * tan2).sqrt())
    } else {
        let a = 1.0 / (alpha * tan2.sqrt());
        0.5 * ((-a * a).exp() / (a * PI.sqrt()) - statrs::function::erf::erfc(a))
    }
}

/// Smith's masking G1 of direction `v` for microfacet normal `h`: 0 where
/// `v` sees the back of the facet.
fn smith_g1(ggx: bool, alpha: f64, v: [f64; 3], h: [f64; 3]) -> f64 {
    if dot(v, h) * v[2] <= 0.0 {
        0.0
    } else {
        1.0 / (1.0 + smith_lambda(ggx, alpha, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64, what: &str) {
        assert!(
            (a - b).abs() <= tol,
            "{what}: {a} vs {b} (diff {:e}, tol {tol:e})",
            a - b
        );
    }

    /// Angles the self-tests visit, as cosines.
    fn cosines() -> Vec<f64> {
        [0.0f64, 5.0, 20.0, 45.0, 60.0, 75.0, 85.0, 89.0]
            .iter()
            .map(|d| d.to_radians().cos())
            .collect()
    }

    #[test]
    fn phong_normal_incidence_is_ks() {
        // At normal incidence α = θ_i, and (n+2)/(n+1) E[cos α] = 1 exactly:
        // the normalised lobe loses nothing there, for every exponent
        for n in [0.0, 1.0, 20.0, 100.0, 1e6, 1e7] {
            close(
                phong_albedo(0.0, 0.8, n, 1.0),
                0.8,
                1e-7,
                &format!("n = {n}"),
            );
        }
    }

    #[test]
    fn phong_exponent_zero_has_closed_form() {
        // n = 0: ks/π times the projected area of the lune between the
        // upper hemisphere and the hemisphere around r, (π/2)(1 + cos θ_o)
        for c in cosines() {
            close(
                phong_albedo(0.0, 1.0, 0.0, c),
                0.5 * (1.0 + c),
                1e-7,
                &format!("cos_o = {c}"),
            );
        }
    }

    #[test]
    fn phong_huge_exponent_is_cosine() {
        // The lobe is nearly a delta at the mirror direction: the albedo is
        // ks (n+2)/(n+1) cos θ_o away from grazing
        let n = 1e6;
        for c in cosines().into_iter().filter(|&c| c > 0.05) {
            close(
                phong_albedo(0.0, 0.7, n, c),
                0.7 * (n + 2.0) / (n + 1.0) * c,
                1e-6,
                &format!("cos_o = {c}"),
            );
        }
    }

    #[test]
    fn phong_diffuse_only_is_kd() {
        for c in cosines() {
            close(
                phong_albedo(0.3, 0.0, 50.0, c),
                0.3,
                0.0,
                &format!("cos_o = {c}"),
            );
        }
    }

    #[test]
    fn phong_matches_the_plain_grid() {
        // The 2-D grid of the brief agrees with the exact φ average
        for n in [1.0, 20.0, 100.0, 1e6] {
            for c in [1.0, 0.7, 0.3, 0.1] {
                let a = phong_albedo(0.2, 0.8, n, c);
                let b = phong_albedo_grid(0.2, 0.8, n, c, 2000);
                close(a, b, 2e-5, &format!("n = {n}, cos_o = {c}"));
            }
        }
    }

    #[test]
    fn phong_never_exceeds_kd_plus_ks() {
        for n in [0.0, 1.0, 2.0, 20.0, 100.0, 1e6] {
            for i in 0..=90 {
                let c = (i as f64).to_radians().cos();
                let a = phong_albedo(0.3, 0.7, n, c);
                assert!((0.3..=1.0 + 1e-9).contains(&a), "n = {n}, {i} deg: {a}");
            }
        }
    }

    #[test]
    fn glossy_cone_zero_and_normal_incidence_are_refl() {
        for c in cosines() {
            close(
                glossy_albedo(0.8, 0.0, c),
                0.8,
                0.0,
                &format!("cone 0, cos_o = {c}"),
            );
        }
        for cone in [5.0, 30.0, 80.0, 89.9] {
            close(
                glossy_albedo(0.8, cone, 1.0),
                0.8,
                0.0,
                &format!("cone {cone}, normal"),
            );
        }
    }

    #[test]
    fn glossy_matches_the_closed_form() {
        for cone in [5.0, 30.0, 60.0, 80.0] {
            for c in cosines() {
                let a = glossy_albedo(1.0, cone, c);
                let b = glossy_albedo_closed_form(1.0, cone, c);
                close(a, b, 1e-5, &format!("cone {cone}, cos_o = {c}"));
            }
        }
        // Nothing is lost until the disc's rim reaches the horizon: D tilts
        // from r by at most atan(sin(cone)), 26.57° for a cone of 30°
        close(
            glossy_albedo(1.0, 30.0, 63.4f64.to_radians().cos()),
            1.0,
            0.0,
            "cone 30 at 63.4 deg",
        );
        assert!(glossy_albedo(1.0, 30.0, 63.5f64.to_radians().cos()) < 1.0);
        // At grazing, half the disc is below the surface
        close(glossy_albedo(1.0, 30.0, 0.0), 0.5, 1e-9, "grazing");
    }

    #[test]
    fn angle_table_interpolates() {
        let t = AngleTable::new(1024, |c| phong_albedo(0.0, 1.0, 0.0, c));
        for i in 0..200 {
            let c = i as f64 / 199.0;
            close(t.at(c), 0.5 * (1.0 + c), 1e-6, &format!("cos_o = {c}"));
        }
    }
}
