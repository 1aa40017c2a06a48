//! Material tests: phong, glossy, mirror and dielectric against figures
//! known without rendering (directional albedo in a white furnace, energy
//! conservation, limits that must reproduce another material or no object
//! at all), and the orientation of textures.
//!
//! Every test renders small images on the default device and prints its
//! figures (`cargo test --test it materials:: -- --nocapture`).

use crate::common;

#[path = "common/albedo.rs"]
mod albedo;

use albedo::{
    glossy_albedo, microfacet_albedo, microfacet_weight_moment, phong_albedo,
    rough_dielectric_weight_moment, rough_interface_lobes, AngleTable,
};
use common::materials::{fresnel, glossy, material, phong};
use common::*;
use glam::{DVec3, Vec3};
use lancer::analysis::ztest::z_test;
use lancer::internal::gpu::pack::fresnel_diffuse_reflectance;
use lancer::internal::gpu::rough_plastic::{rough_coating, RoughCoating};
use lancer::render::{RenderOptions, RenderOutput};
use lancer::scene::{ComplexIor, MaterialKind, Microfacet, Scene};
use lancer::util::metrics::{count_nonfinite, max_abs_diff};

// ------------------------------------------------------------------ helpers

/// Wave size for these small renders.
const WAVE: u32 = 1 << 16;

/// The camera rays of `shaders/generate.comp`, in f64 on the CPU.
struct CameraRays {
    eye: DVec3,
    u: DVec3,
    v: DVec3,
    w: DVec3,
    tan_u: f64,
    tan_v: f64,
    width: f64,
    height: f64,
}

impl CameraRays {
    fn new(scene: &Scene) -> CameraRays {
        let c = &scene.camera;
        let eye = c.eye.as_dvec3();
        let w = (eye - c.look_at.as_dvec3()).normalize();
        let u = c.up.as_dvec3().cross(w).normalize();
        let v = w.cross(u);
        let tan_v = (0.5 * c.vfov_deg as f64).to_radians().tan();
        let (width, height) = (scene.render.width as f64, scene.render.height as f64);
        CameraRays {
            eye,
            u,
            v,
            w,
            tan_u: tan_v * width / height,
            tan_v,
            width,
            height,
        }
    }

    /// Unit direction of the ray through the film point (x, y), in pixels
    /// from the top-left corner of the image.
    fn dir(&self, x: f64, y: f64) -> DVec3 {
        let ndc_x = 2.0 * x / self.width - 1.0;
        let ndc_y = 1.0 - 2.0 * y / self.height;
        (ndc_x * self.tan_u * self.u + ndc_y * self.tan_v * self.v - self.w).normalize()
    }

    /// Mean of `f(dir)` over an n x n grid of cell centres in pixel (px, py).
    fn pixel_mean(&self, px: usize, py: usize, n: usize, f: impl Fn(DVec3) -> f64) -> f64 {
        let mut sum = 0.0;
        for j in 0..n {
            for i in 0..n {
                let x = px as f64 + (i as f64 + 0.5) / n as f64;
                let y = py as f64 + (j as f64 + 0.5) / n as f64;
                sum += f(self.dir(x, y));
            }
        }
        sum / (n * n) as f64
    }
}

/// The scene's material named `name`, by index.
fn material_index(scene: &Scene, name: &str) -> usize {
    scene
        .materials
        .iter()
        .position(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material {name}"))
}

/// A furnace case: a material and its directional albedo.
struct Case {
    name: String,
    kind: MaterialKind,
    albedo: Box<dyn Fn(f64) -> f64 + Sync>,
    /// Every sample weighs between 0 and 1, so that a (1 - a) / spp bounds
    /// a pixel's variance (glossy with reflectance 1: 0 or 1; a blend of
    /// components whose weights are at most 1).
    bernoulli: bool,
    /// The second moment of a sample's weight, where it is known: the
    /// variance floor of a pixel (rare small weights that 64 samples miss
    /// make the film's own variance too small).
    second_moment: Option<Box<dyn Fn(f64) -> f64 + Sync>>,
}

fn phong_case(kd: f64, ks: f64, n: f64) -> Case {
    Case {
        name: format!("phong kd {kd} ks {ks} n {n:e}"),
        kind: phong(Vec3::splat(kd as f32), ks as f32, n as f32),
        albedo: Box::new(move |c| phong_albedo(kd, ks, n, c)),
        bernoulli: false,
        second_moment: None,
    }
}

fn glossy_case(cone: f64) -> Case {
    Case {
        name: format!("glossy refl 1 cone {cone}"),
        kind: glossy(Vec3::ONE, cone as f32),
        albedo: Box::new(move |c| glossy_albedo(1.0, cone, c)),
        bernoulli: true,
        second_moment: None,
    }
}

/// A rough perfect reflector (Mitsuba's material `none`).
fn rough_case(distribution: Microfacet, alpha: f64) -> Case {
    let ggx = distribution == Microfacet::Ggx;
    Case {
        name: format!("roughconductor {} a {alpha}", distribution.name()),
        kind: MaterialKind::RoughConductor {
            distribution,
            alpha_u: alpha as f32,
            alpha_v: alpha as f32,
            alpha_textures: None,
            ior: ComplexIor::PERFECT,
            specular_reflectance: Vec3::ONE,
        },
        albedo: Box::new(move |c| microfacet_albedo(ggx, alpha, c)),
        bernoulli: false,
        second_moment: Some(Box::new(move |c| {
            microfacet_weight_moment(ggx, alpha, c, 2)
        })),
    }
}

/// A rough dielectric of index ratio `ior` seen from outside: what
/// reflects and what refracts (scaled by 1 / ior²) both escape to the
/// furnace, the quad being the only surface.
fn rough_dielectric_case(distribution: Microfacet, alpha: f64, ior: f64) -> Case {
    let ggx = distribution == Microfacet::Ggx;
    Case {
        name: format!(
            "roughdielectric {} a {alpha} ior {ior}",
            distribution.name()
        ),
        kind: MaterialKind::RoughDielectric {
            distribution,
            alpha_u: alpha as f32,
            alpha_v: alpha as f32,
            alpha_textures: None,
            ior: ior as f32,
            specular_reflectance: Vec3::ONE,
            specular_transmittance: Vec3::ONE,
        },
        albedo: Box::new(move |c| rough_dielectric_weight_moment(ggx, alpha, ior, c, 1)),
        bernoulli: false,
        second_moment: Some(Box::new(move |c| {
            rough_dielectric_weight_moment(ggx, alpha, ior, c, 2)
        })),
    }
}

/// The diffuse Fresnel reflectance 2 ∫ F(μ) μ dμ over μ in [0, 1] of an
/// interface of index ratio `eta`, by the midpoint rule in f64 (exact
/// Fresnel, total internal reflection where eta < 1).
fn diffuse_fresnel(eta: f64) -> f64 {
    let n = 200_000;
    (0..n)
        .map(|k| {
            let mu = (k as f64 + 0.5) / n as f64;
            2.0 * fresnel(mu, eta) * mu / n as f64
        })
        .sum()
}

/// 2 ∫ (1 - F(μ))² μ dμ: the cosine-weighted mean of the squared
/// transmittance, for the second moment of a plastic's diffuse samples.
fn diffuse_transmittance_squared(eta: f64) -> f64 {
    let n = 200_000;
    (0..n)
        .map(|k| {
            let mu = (k as f64 + 0.5) / n as f64;
            let t = 1.0 - fresnel(mu, eta);
            2.0 * t * t * mu / n as f64
        })
        .sum()
}

/// A white smooth plastic (diffuse 1, specular 1, linear) of index `ior`:
/// the coating reflects F, and the base returns (1 - F) (1 - Fdr_ext) /
/// (ior² (1 - Fdr_int)), with Fdr_ext the exact diffuse reflectance from
/// outside and Fdr_int Mitsuba's fit from inside, as the device uses it.
/// With the exact Fdr_int the base would return exactly 1 - F (1 - Fdr_ext
/// = ior² (1 - Fdr_int)), so the albedo is 1 to within the fit's error.
fn plastic_case(ior: f64) -> Case {
    let fdr_int = f64::from(fresnel_diffuse_reflectance(1.0 / ior as f32));
    let fdr_ext = diffuse_fresnel(ior);
    let base = (1.0 - fdr_ext) / (ior * ior * (1.0 - fdr_int));
    let t2 = diffuse_transmittance_squared(ior) / (ior * ior * (1.0 - fdr_int)).powi(2);
    Case {
        name: format!("plastic white ior {ior}"),
        kind: MaterialKind::Plastic {
            diffuse_reflectance: lancer::scene::ColorSource::Constant(Vec3::ONE),
            specular_reflectance: Vec3::ONE,
            ior: ior as f32,
            nonlinear: false,
        },
        albedo: Box::new(move |c| {
            let f = fresnel(c, ior);
            f + (1.0 - f) * base
        }),
        bernoulli: false,
        // Equal mean colours: the mirror is chosen with chance F, weight 1;
        // the base with 1 - F, weight (1 - F_o) / (ior² (1 - Fdr_int))
        second_moment: Some(Box::new(move |c| {
            let f = fresnel(c, ior);
            f + (1.0 - f) * t2
        })),
    }
}

/// The reflectance of a thin slab of index ratio `ior` at cosine `c`:
/// the Fresnel reflectance R of one face, and the light reflected back and
/// forth between the faces, R + (1 - R)² R / (1 - R²) = 2R / (1 + R)
/// (Mitsuba's `thindielectric`).
fn thin_slab_reflectance(c: f64, ior: f64) -> f64 {
    let r = fresnel(c, ior);
    r + (1.0 - r) * (1.0 - r) * r / (1.0 - r * r)
}

/// A thin dielectric of index ratio `ior` with a grey
/// `specular_transmittance` `t` (reflection factor 1): what reflects (R')
/// and what passes straight through (1 - R', times `t`) both escape to the
/// furnace. Each lobe is chosen with its own probability, so a sample
/// weighs 1 or `t`.
fn thin_dielectric_case(ior: f64, t: f64) -> Case {
    Case {
        name: format!("thindielectric ior {ior} transmittance {t}"),
        kind: MaterialKind::ThinDielectric {
            ior: ior as f32,
            specular_reflectance: Vec3::ONE,
            specular_transmittance: Vec3::splat(t as f32),
        },
        albedo: Box::new(move |c| {
            let r = thin_slab_reflectance(c, ior);
            r + (1.0 - r) * t
        }),
        bernoulli: false,
        second_moment: Some(Box::new(move |c| {
            let r = thin_slab_reflectance(c, ior);
            r + (1.0 - r) * t * t
        })),
    }
}

/// A rough plastic's coating transmittance at cosine `c`, interpolated
/// in its table as the device interpolates it (in f64).
fn coating_transmittance(coating: &RoughCoating, c: f64) -> f64 {
    let n = coating.transmittance.len();
    let x = c.clamp(0.0, 1.0) * (n - 1) as f64;
    let k = (x as usize).min(n - 2);
    let w = x - k as f64;
    let t = |i: usize| f64::from(coating.transmittance[i]);
    t(k) * (1.0 - w) + t(k + 1) * w
}

/// A rough plastic of diffuse colour `kd` (grey) under a coating of index
/// `ior`: the coating's rough reflection (the reflected lobe of the rough
/// interface, by the slope quadrature) plus the base's kd_eff T(cos_o) /
/// ior² · 2 ∫ T(μ) μ dμ, T and the internal reflectance R from the table
/// lancer computes (src/gpu/rough_plastic.rs; checked apart by
/// `rough_plastic_coating_matches_quadrature_and_mitsuba`), kd_eff = kd /
/// (1 - R), or kd / (1 - kd R) when `nonlinear`.
fn rough_plastic_case(
    distribution: Microfacet,
    alpha: f64,
    ior: f64,
    kd: f64,
    nonlinear: bool,
) -> Case {
    let ggx = distribution == Microfacet::Ggx;
    let coating = rough_coating(distribution, alpha as f32, ior as f32);
    let r = f64::from(coating.internal_reflectance);
    let kd_eff = kd / (1.0 - if nonlinear { kd * r } else { r });
    // 2 ∫ T(μ) μ dμ by the midpoint rule on the interpolated table
    let n = 20_000;
    let hemisphere: f64 = (0..n)
        .map(|k| {
            let mu = (k as f64 + 0.5) / n as f64;
            2.0 * coating_transmittance(&coating, mu) * mu / n as f64
        })
        .sum();
    Case {
        name: format!(
            "roughplastic {} a {alpha} ior {ior} kd {kd}{}",
            distribution.name(),
            if nonlinear { " nonlinear" } else { "" }
        ),
        kind: MaterialKind::RoughPlastic {
            distribution,
            alpha: alpha as f32,
            diffuse_reflectance: lancer::scene::ColorSource::Constant(Vec3::splat(kd as f32)),
            specular_reflectance: Vec3::ONE,
            ior: ior as f32,
            nonlinear,
        },
        albedo: Box::new(move |c| {
            let specular = rough_interface_lobes(ggx, alpha, ior, c).0;
            specular + kd_eff * coating_transmittance(&coating, c) / (ior * ior) * hemisphere
        }),
        bernoulli: false,
        second_moment: None,
    }
}

/// A blend (Mitsuba's `blendbsdf`) of a rough perfect GGX reflector and a
/// grey lambert, `weight` lambert: its albedo is the mixture of theirs.
fn blend_case(weight: f64, alpha: f64, kd: f64) -> Case {
    let conductor = rough_case(Microfacet::Ggx, alpha).kind;
    Case {
        name: format!("blend {weight}: roughconductor ggx a {alpha}, lambert kd {kd}"),
        kind: MaterialKind::Blend {
            weight: lancer::scene::ColorSource::Constant(Vec3::splat(weight as f32)),
            components: Box::new([
                conductor,
                MaterialKind::Lambert {
                    albedo: lancer::scene::ColorSource::Constant(Vec3::splat(kd as f32)),
                },
            ]),
        },
        albedo: Box::new(move |c| (1.0 - weight) * microfacet_albedo(true, alpha, c) + weight * kd),
        // Each component's f · cos is at most its pdf (the conductor's
        // G2 / G1, the lambert's kd), so a sample's weight, the mixture's
        // f · cos over the mixture's pdf, lies in [0, 1]: its variance is
        // at most a (1 - a), the bound the floor needs where the rare small
        // weights of grazing directions are missed by a pixel's 64 samples
        bernoulli: true,
        second_moment: None,
    }
}

/// The albedo cases of the furnace test.
fn albedo_cases() -> Vec<Case> {
    vec![
        blend_case(0.3, 0.2, 1.0),
        blend_case(0.8, 0.05, 0.6),
        rough_plastic_case(Microfacet::Ggx, 0.3, 1.5, 1.0, false),
        rough_plastic_case(Microfacet::Beckmann, 0.1, 1.33, 0.8, true),
        rough_plastic_case(Microfacet::Ggx, 0.02, 1.9, 0.5, false),
        plastic_case(1.49),
        plastic_case(1.9),
        thin_dielectric_case(1.5046 / 1.000277, 1.0),
        thin_dielectric_case(1.5, 0.0),
        thin_dielectric_case(2.419, 0.5),
        rough_dielectric_case(Microfacet::Ggx, 0.2, 1.5),
        rough_dielectric_case(Microfacet::Ggx, 0.7, 1.5),
        rough_dielectric_case(Microfacet::Beckmann, 0.3, 1.33),
        rough_case(Microfacet::Ggx, 0.1),
        rough_case(Microfacet::Ggx, 0.6),
        rough_case(Microfacet::Beckmann, 0.3),
        phong_case(0.0, 1.0, 1.0),
        phong_case(0.0, 1.0, 100.0),
        phong_case(0.0, 1.0, 1e6),
        phong_case(0.3, 0.7, 20.0),
        glossy_case(5.0),
        glossy_case(30.0),
        glossy_case(80.0),
    ]
}

/// The furnace quad scene with the material replaced.
fn furnace_with(base: &Scene, kind: &MaterialKind) -> Scene {
    let mut scene = base.clone();
    let i = material_index(&scene, "surface");
    scene.materials[i].kind = kind.clone();
    scene
}

/// Cosine of the view angle of a camera ray at the plane y = 0 (normal +y).
fn view_cosine(d: DVec3) -> f64 {
    (-d.y).clamp(0.0, 1.0)
}

/// Where a ray from `eye` along `d` meets the plane y = 0, if it does.
fn plane_hit(eye: DVec3, d: DVec3) -> Option<DVec3> {
    (d.y < 0.0).then(|| eye - eye.y / d.y * d)
}

/// The furnace quad's half-size (tests/scenes/furnace_quad.toml).
const QUAD_HALF: f64 = 1000.0;

/// How a render compares with a per-pixel expectation (grey: the same for
/// every channel).
struct Agreement {
    /// Pixels whose three channels are all within 5 sigma + 1e-4.
    pass_fraction: f64,
    /// Image means of the render and of the expectation.
    mean_render: f64,
    mean_expected: f64,
    /// Standard deviation of the render's image mean.
    sigma_mean: f64,
    /// Largest |render - expected| / sigma over channels with sigma > 0.
    worst_z: f64,
}

impl Agreement {
    fn new(out: &RenderOutput, expected: &[f64]) -> Agreement {
        Agreement::with_floor(out, expected, &vec![0.0; expected.len()])
    }

    /// As [`Agreement::new`], with sigma at least `sqrt(var_floor)` per
    /// pixel: where an estimator is 0 or 1 (glossy: the sample is below the
    /// surface or not) a pixel whose loss is rare often shows 1 in every
    /// sample, with a sample variance of 0, and only the model's variance
    /// a (1 - a) / spp says how far from 1 it may read.
    fn with_floor(out: &RenderOutput, expected: &[f64], var_floor: &[f64]) -> Agreement {
        let pixels = expected.len();
        assert_eq!(out.mean.len(), 3 * pixels);
        let mut passed = 0;
        let mut worst_z = 0.0f64;
        let (mut sum_r, mut sum_e, mut sum_var) = (0.0, 0.0, 0.0);
        for (p, &e) in expected.iter().enumerate() {
            let mut ok = true;
            for c in 0..3 {
                let a = out.mean[3 * p + c] as f64;
                let var = out.var_of_mean[3 * p + c] as f64;
                let sigma = var.max(var_floor[p]).sqrt();
                ok &= (a - e).abs() <= 5.0 * sigma + 1e-4;
                if sigma > 0.0 {
                    worst_z = worst_z.max((a - e).abs() / sigma);
                }
                sum_r += a;
                sum_e += e;
                sum_var += var;
            }
            passed += ok as usize;
        }
        let n = (3 * pixels) as f64;
        Agreement {
            pass_fraction: passed as f64 / pixels as f64,
            mean_render: sum_r / n,
            mean_expected: sum_e / n,
            sigma_mean: sum_var.sqrt() / n,
            worst_z,
        }
    }

    fn rel_mean(&self) -> f64 {
        (self.mean_render - self.mean_expected) / self.mean_expected
    }

    /// At least 99.5 % of pixels within 5 sigma and the image mean within 0.5 %.
    fn passes(&self) -> bool {
        self.pass_fraction >= 0.995 && self.rel_mean().abs() <= 0.005
    }
}

// ------------------------------------------------------------------- tests

/// Each pixel of a huge quad in a white furnace shows the directional
/// albedo of its material at the pixel's view angles: the phong and glossy
/// formulas of docs/scene-format.md, integrated on the CPU (tests/it/common/albedo.rs).
///
/// A pixel passes when each channel is within 5 sigma + 1e-4 of the mean
/// albedo over a 4 x 4 grid of its camera rays; sigma from the render's
/// variance of the mean, but for glossy (every sample weighs 0 or 1) at
/// least the binomial sqrt(a (1 - a) / spp): where a is just below 1 most
/// pixels see no sample lost and report a variance of 0 (the counts of such
/// pixels match a^spp).
#[test]
fn furnace_directional_albedo_matches_integration() {
    let ctx = context();
    let base = load("tests/scenes/furnace_quad.toml");
    let cam = CameraRays::new(&base);
    let (w, h) = (base.render.width as usize, base.render.height as usize);

    // View angles covered, and every sub-pixel ray must hit the quad
    let (mut lo, mut hi) = (90.0f64, 0.0f64);
    for py in 0..h {
        for px in 0..w {
            for (x, y) in [(px, py), (px + 1, py), (px, py + 1), (px + 1, py + 1)] {
                let d = cam.dir(x as f64, y as f64);
                let p = plane_hit(cam.eye, d).expect("camera ray above the horizon");
                assert!(
                    p.x.abs() < QUAD_HALF && p.z.abs() < QUAD_HALF,
                    "camera ray misses the quad"
                );
                let theta = view_cosine(d).acos().to_degrees();
                lo = lo.min(theta);
                hi = hi.max(theta);
            }
        }
    }
    println!(
        "furnace quad: {w}x{h}, {} spp, view angles {lo:.1} to {hi:.1} deg",
        base.render.spp
    );
    assert!(lo < 6.0 && hi > 80.0, "view angles {lo}..{hi}");

    for case in albedo_cases() {
        let table = AngleTable::new(2048, &case.albedo);
        let expected: Vec<f64> = (0..w * h)
            .map(|p| cam.pixel_mean(p % w, p / w, 4, |d| table.at(view_cosine(d))))
            .collect();
        let out = render(&ctx, &furnace_with(&base, &case.kind), &options(WAVE));
        let spp = out.spp as f64;
        let floor: Vec<f64> = if case.bernoulli {
            expected.iter().map(|a| a * (1.0 - a) / spp).collect()
        } else if let Some(m2) = &case.second_moment {
            let m2 = AngleTable::new(256, m2);
            (0..w * h)
                .map(|p| {
                    let second = cam.pixel_mean(p % w, p / w, 4, |d| m2.at(view_cosine(d)));
                    (second - expected[p] * expected[p]).max(0.0) / spp
                })
                .collect()
        } else {
            vec![0.0; expected.len()]
        };
        let good = Agreement::with_floor(&out, &expected, &floor);
        let plain = Agreement::new(&out, &expected);
        let scaled: Vec<f64> = expected.iter().map(|e| 0.97 * e).collect();
        let wrong = Agreement::with_floor(&out, &scaled, &floor);
        let (emin, emax) = expected
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &e| (a.min(e), b.max(e)));
        println!(
            "  {:<32} albedo {emin:.4}..{emax:.4}: {:.2}% pixels pass ({:.2}% without the variance floor), \
             worst z {:.2}, mean {:.5} vs {:.5} ({:+.3}%, sigma {:.3}%); x0.97: {:.2}% pass, {:+.3}%",
            case.name,
            100.0 * good.pass_fraction,
            100.0 * plain.pass_fraction,
            good.worst_z,
            good.mean_render,
            good.mean_expected,
            100.0 * good.rel_mean(),
            100.0 * good.sigma_mean / good.mean_expected,
            100.0 * wrong.pass_fraction,
            100.0 * wrong.rel_mean(),
        );
        assert!(
            good.passes(),
            "{}: {:.2}% of pixels within 5 sigma (need 99.5%), image mean off by {:+.3}% (at most 0.5%)",
            case.name,
            100.0 * good.pass_fraction,
            100.0 * good.rel_mean()
        );
        assert!(
            !wrong.passes(),
            "{}: an albedo 3% too low passes as well: the test has no power",
            case.name
        );
    }
}

/// The furnace quad seen from a camera whose rows run from normal
/// incidence (near the bottom) past the horizon: view angles 0 to 90 degrees.
fn grazing_furnace(base: &Scene) -> Scene {
    let mut scene = base.clone();
    let pitch = 45.0f32.to_radians();
    scene.camera.eye = Vec3::new(0.0, 1.0, 0.0);
    scene.camera.look_at = scene.camera.eye + Vec3::new(0.0, -pitch.cos(), -pitch.sin());
    scene.camera.vfov_deg = 100.0;
    scene
}

/// Largest (mean - limit) / sigma over the image's channels, the largest
/// mean, and the number of channels above limit + 5 sigma + `slack`, sigma
/// being the film's standard error or, where larger, `var_floor`'s root.
fn above(out: &RenderOutput, limit: f64, var_floor: f64, slack: f64) -> (f64, f64, usize) {
    let mut worst_z = f64::MIN;
    let mut max_mean = f64::MIN;
    let mut over = 0;
    for (&m, &v) in out.mean.iter().zip(&out.var_of_mean) {
        let (m, s) = (m as f64, (v as f64).max(var_floor).sqrt());
        max_mean = max_mean.max(m);
        if s > 0.0 {
            worst_z = worst_z.max((m - limit) / s);
        }
        if m > limit + 5.0 * s + slack {
            over += 1;
        }
    }
    (worst_z, max_mean, over)
}

/// Phong (ks = 1, including exponents 0 and 1, whose albedo is exactly 1 at
/// normal incidence) and glossy (reflectance 1) never return more light
/// than arrives, at any view angle up to grazing; no NaN. A case whose
/// model itself returns a little more than 1 (the white smooth plastic,
/// through Mitsuba's fit of the internal diffuse Fresnel reflectance)
/// is held to its own largest albedo over the view angles instead.
#[test]
fn phong_and_glossy_never_exceed_one() {
    let ctx = context();
    let base = grazing_furnace(&load("tests/scenes/furnace_quad.toml"));
    let mut cases = vec![phong_case(0.0, 1.0, 0.0)];
    cases.extend(albedo_cases());
    cases.push(phong_case(0.5, 0.5, 1.0));
    cases.push(glossy_case(89.0));
    cases.push(rough_case(Microfacet::Ggx, 0.01));
    cases.push(rough_case(Microfacet::Ggx, 1.0));
    cases.push(rough_case(Microfacet::Beckmann, 0.05));
    cases.push(rough_case(Microfacet::Beckmann, 1.0));
    println!(
        "grazing furnace: view angles 0 to 90 deg, {} spp",
        base.render.spp
    );
    for case in cases {
        let out = render(&ctx, &furnace_with(&base, &case.kind), &options(WAVE));
        let nonfinite = count_nonfinite(&out.mean);
        let limit = (0..=1000)
            .map(|k| (case.albedo)(f64::from(k) / 1000.0))
            .fold(1.0, f64::max);
        // Where the case knows its weights' second moment, floor each
        // pixel's variance by the largest per-sample variance over the view
        // angles, over spp: 64 samples can miss the rare weights that make
        // it (see `Case::second_moment`). The floor may exceed a pixel's
        // own variance, which loosens the check for those cases only
        let var_floor = case.second_moment.as_ref().map_or(0.0, |m2| {
            (0..=1000)
                .map(|k| {
                    let c = f64::from(k) / 1000.0;
                    m2(c) - (case.albedo)(c).powi(2)
                })
                .fold(0.0, f64::max)
                / f64::from(base.render.spp)
        });
        let (worst_z, max_mean, over) = above(&out, limit, var_floor, 1e-6);
        println!(
            "  {:<32} max pixel {max_mean:.6}, limit {limit:.6}, max (mean - limit) / sigma {worst_z:+.2}, \
             {over} channels over, {nonfinite} NaN/Inf, {} dropped samples",
            case.name, out.stats.nonfinite_samples
        );
        assert_eq!(nonfinite, 0, "{}: non-finite pixels", case.name);
        assert_eq!(
            out.stats.nonfinite_samples, 0,
            "{}: non-finite samples",
            case.name
        );
        assert_eq!(
            over, 0,
            "{}: {over} channels above {limit} + 5 sigma (max {max_mean})",
            case.name
        );
    }
}

/// A nearly smooth rough perfect reflector returns (almost) all the light
/// at normal incidence, and rougher ones lose what leaves below the horizon
/// or is masked (single scattering), by the quadrature of the microfacet
/// model; every albedo is at most 1.
#[test]
fn rough_conductor_albedo_quadrature_bounds() {
    for ggx in [true, false] {
        let smooth = microfacet_albedo(ggx, 0.01, 1.0);
        assert!(
            (smooth - 1.0).abs() < 1e-4,
            "ggx {ggx}: alpha 0.01: {smooth}"
        );
        let mut last = smooth;
        for alpha in [0.1, 0.3, 0.6, 1.0] {
            let e = microfacet_albedo(ggx, alpha, 1.0);
            println!("ggx {ggx} alpha {alpha}: albedo at normal incidence {e:.5}");
            assert!(e <= last + 1e-6 && e > 0.3, "ggx {ggx} alpha {alpha}: {e}");
            last = e;
            for c in [0.9, 0.5, 0.1, 0.01] {
                let e = microfacet_albedo(ggx, alpha, c);
                assert!(
                    e > 0.0 && e <= 1.0 + 1e-6,
                    "ggx {ggx} alpha {alpha} cos {c}: {e}"
                );
            }
        }
    }
}

/// The rough dielectric's quadrature tends to the smooth dielectric's
/// albedo F + (1 - F) / eta² (the exact Fresnel term; radiance scaled by
/// 1 / eta² on the way in) as alpha goes to 0, from either side, and stays
/// within the bound of its largest sample weight at every roughness.
#[test]
fn rough_dielectric_albedo_quadrature_tends_to_the_smooth_dielectric() {
    for ggx in [true, false] {
        for eta in [1.5, 1.0 / 1.5, 1.33] {
            for c in [1.0, 0.8, 0.5] {
                let f = fresnel(c, eta);
                let smooth = f + (1.0 - f) / (eta * eta);
                let e = rough_dielectric_weight_moment(ggx, 0.002, eta, c, 1);
                println!("ggx {ggx} eta {eta:.4} cos {c}: alpha 0.002 {e:.6}, smooth {smooth:.6}");
                assert!(
                    (e - smooth).abs() < 2e-3 * smooth,
                    "ggx {ggx} eta {eta} cos {c}: {e} vs the smooth {smooth}"
                );
            }
            // Each sample weighs at most 1 (reflected) or 1 / eta² (refracted)
            let bound = (1.0 / (eta * eta)).max(1.0);
            for alpha in [0.1, 0.4, 1.0] {
                for c in [1.0, 0.5, 0.05] {
                    let e = rough_dielectric_weight_moment(ggx, alpha, eta, c, 1);
                    assert!(
                        e > 0.1 && e <= bound * (1.0 + 1e-6),
                        "ggx {ggx} eta {eta} alpha {alpha} cos {c}: {e} above {bound}"
                    );
                }
            }
        }
    }
}

/// Mitsuba's fits of the diffuse Fresnel reflectance, which lancer's smooth
/// plastic computes once on the CPU, agree with the integral of the exact
/// Fresnel term (within 0.1% where the fits are best, 1% elsewhere), and
/// with them a white plastic returns all the light to within 0.6%.
#[test]
fn plastic_diffuse_fresnel_fit_matches_integration() {
    for (eta, tolerance) in [
        (1.0 / 1.33, 2e-3),
        (1.0 / 1.49, 2e-3),
        (1.0 / 1.9, 1e-2),
        (1.33, 2e-3),
        (1.49, 2e-3),
        (1.9, 2e-3),
        (2.5, 2e-3),
    ] {
        let fit = f64::from(fresnel_diffuse_reflectance(eta as f32));
        let exact = diffuse_fresnel(eta);
        println!(
            "eta {eta:.4}: Mitsuba's fit {fit:.6}, integral {exact:.6}, relative {:+.3e}",
            fit / exact - 1.0
        );
        assert!(
            (fit / exact - 1.0).abs() < tolerance,
            "eta {eta}: {fit} vs {exact}"
        );
    }
    // Reciprocity: 1 - Fdr(eta) = eta² (1 - Fdr(1 / eta)), exactly for the integrals
    for ior in [1.33, 1.49, 1.9] {
        let lhs = 1.0 - diffuse_fresnel(ior);
        let rhs = ior * ior * (1.0 - diffuse_fresnel(1.0 / ior));
        assert!((lhs - rhs).abs() < 1e-6, "ior {ior}: {lhs} vs {rhs}");
        let white = (1.0 - diffuse_fresnel(ior))
            / (ior * ior * (1.0 - f64::from(fresnel_diffuse_reflectance(1.0 / ior as f32))));
        println!("ior {ior}: a white plastic's base returns {white:.5} of what enters it");
        assert!((white - 1.0).abs() < 6e-3, "ior {ior}: {white}");
    }
}

/// The rough plastic's coating figures that lancer computes once per
/// material (src/gpu/rough_plastic.rs: Gauss-Legendre over the visible
/// normals' sampling space) agree with an independent quadrature over the
/// microfacet slopes (tests/it/common/albedo.rs): the transmittance T(μ) at
/// every entry of the table within 1e-3, and the internal reflectance,
/// Mitsuba's rule (twice the mean of R(μ) μ over the table's cosines) on
/// the slopes' R, within 5e-4. They also agree with Mitsuba 3.9.1's own
/// tables (tests/reference/roughplastic_coating.json, read back from its
/// BSDF by tools/roughplastic_coating.py): GGX within 2e-3, Beckmann
/// within 4e-3 (Mitsuba's Beckmann masking is a rational fit within
/// 0.35%, lancer's the exact one).
#[test]
fn rough_plastic_coating_matches_quadrature_and_mitsuba() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/reference/roughplastic_coating.json");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("reference tables")).unwrap();
    let coatings = json["coatings"].as_array().unwrap();
    assert_eq!(coatings.len(), 24);
    let (mut worst_slopes, mut worst_mitsuba) = (0.0f64, 0.0f64);
    for c in coatings {
        let ggx = c["distribution"] == "ggx";
        let distribution = if ggx {
            Microfacet::Ggx
        } else {
            Microfacet::Beckmann
        };
        let alpha = c["alpha"].as_f64().unwrap();
        let eta = c["eta"].as_f64().unwrap();
        let ours = rough_coating(distribution, alpha as f32, eta as f32);
        let theirs: Vec<f64> = (c["transmittance"].as_array().unwrap().iter())
            .map(|x| x.as_f64().unwrap())
            .collect();
        let r_theirs = c["internal_reflectance"].as_f64().unwrap();
        let r_ours = f64::from(ours.internal_reflectance);
        // The slope quadrature, at every cosine of the table for R, at
        // every fourth for T (the rest are interpolated on the device anyway)
        let cosines: Vec<f64> = (0..64).map(|k| (k as f64 / 63.0).max(1e-6)).collect();
        let r_slopes = 2.0
            * cosines
                .iter()
                .map(|&mu| rough_interface_lobes(ggx, alpha, 1.0 / eta, mu).0 * mu)
                .sum::<f64>()
            / 64.0;
        let mut dt_slopes = 0.0f64;
        let mut dt_mitsuba = 0.0f64;
        for (k, &mu) in cosines.iter().enumerate() {
            let t = f64::from(ours.transmittance[k]);
            dt_mitsuba = dt_mitsuba.max((t - theirs[k]).abs());
            if k % 4 == 0 || k == 63 {
                dt_slopes = dt_slopes.max((t - rough_interface_lobes(ggx, alpha, eta, mu).1).abs());
            }
        }
        println!(
            "{} alpha {alpha} eta {eta}: T vs slopes {dt_slopes:.2e}, vs Mitsuba {dt_mitsuba:.2e}; \
             R {r_ours:.5}, slopes {r_slopes:.5}, Mitsuba {r_theirs:.5}",
            c["distribution"]
        );
        assert!(
            dt_slopes < 1e-3,
            "T off the slope quadrature by {dt_slopes}"
        );
        assert!(
            (r_ours - r_slopes).abs() < 5e-4,
            "R {r_ours} vs the slopes' {r_slopes}"
        );
        let tolerance = if ggx { 2e-3 } else { 4e-3 };
        assert!(dt_mitsuba < tolerance, "T off Mitsuba's by {dt_mitsuba}");
        assert!(
            (r_ours - r_theirs).abs() < tolerance,
            "R {r_ours} vs Mitsuba's {r_theirs}"
        );
        worst_slopes = worst_slopes.max(dt_slopes);
        worst_mitsuba = worst_mitsuba.max(dt_mitsuba);
    }
    println!("largest T differences: {worst_slopes:.2e} (slopes), {worst_mitsuba:.2e} (Mitsuba)");
}

/// Huge Phong exponents (the lobe narrower than f32 resolves) give no NaN or
/// Inf and no gain, at every view angle.
#[test]
fn phong_stable_at_huge_exponents() {
    let ctx = context();
    let base = grazing_furnace(&load("tests/scenes/furnace_quad.toml"));
    let cam = CameraRays::new(&base);
    let (w, h) = (base.render.width as usize, base.render.height as usize);
    for n in [1e6f64, 1e7] {
        let case = phong_case(0.0, 1.0, n);
        let out = render(&ctx, &furnace_with(&base, &case.kind), &options(WAVE));
        let nonfinite = count_nonfinite(&out.mean) + count_nonfinite(&out.var_of_mean);
        let (worst_z, max_mean, over) = above(&out, 1.0, 0.0, 1e-6);
        // For information: how far the image is from the integrated albedo
        // (rays that miss the quad see the environment, 1)
        let table = AngleTable::new(2048, &case.albedo);
        let on_quad = |d: DVec3| matches!(plane_hit(cam.eye, d), Some(q) if q.x.abs() < QUAD_HALF && q.z.abs() < QUAD_HALF);
        let expected: Vec<f64> = (0..w * h)
            .map(|p| {
                let (x, y) = (p % w, p / w);
                let corners = [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)];
                let hits = corners
                    .iter()
                    .filter(|&&(cx, cy)| on_quad(cam.dir(cx as f64, cy as f64)))
                    .count();
                // A finer grid on the pixels the quad's far edge crosses
                let n = if hits == 0 || hits == 4 { 4 } else { 32 };
                cam.pixel_mean(x, y, n, |d| {
                    if on_quad(d) {
                        table.at(view_cosine(d))
                    } else {
                        1.0
                    }
                })
            })
            .collect();
        let agreement = Agreement::new(&out, &expected);
        println!(
            "  phong n {n:e}: {nonfinite} NaN/Inf pixels, {} dropped samples, max pixel {max_mean:.6}, \
             max (mean - 1) / sigma {worst_z:+.2}, {over} over; vs albedo: {:.2}% pass, mean {:+.4}%",
            out.stats.nonfinite_samples,
            100.0 * agreement.pass_fraction,
            100.0 * agreement.rel_mean()
        );
        assert_eq!(nonfinite, 0, "n = {n}: non-finite pixels");
        assert_eq!(
            out.stats.nonfinite_samples, 0,
            "n = {n}: non-finite samples"
        );
        assert_eq!(
            over, 0,
            "n = {n}: {over} channels above 1 + 5 sigma (max {max_mean})"
        );
    }
}

/// The Cornell box with its short block made of one material, at 64 x 64.
fn cornell_with_short_block(kind: MaterialKind) -> Scene {
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 64;
    scene.render.height = 64;
    scene.render.spp = 16;
    scene.materials.push(material("short", kind));
    let index = (scene.materials.len() - 1) as u32;
    // The short block is centred at (0.33, 0.3, 0.3); every one of its
    // triangles has its centroid within 0.35 of that, nothing else within 0.9
    let centre = Vec3::new(0.33, 0.3, 0.3);
    let mut found = 0;
    for t in &mut scene.triangles {
        if ((t.p[0] + t.p[1] + t.p[2]) / 3.0).distance(centre) < 0.45 {
            t.material = index;
            found += 1;
        }
    }
    assert_eq!(found, 12, "short block triangles");
    scene
}

/// Glossy with cone angle 0 is the mirror: the same image, same seed.
#[test]
fn glossy_cone_zero_equals_mirror() {
    let ctx = context();
    let refl = Vec3::new(0.9, 0.8, 0.7);
    let mirror = render(
        &ctx,
        &cornell_with_short_block(MaterialKind::Mirror { reflectance: refl }),
        &options(WAVE),
    );
    let cone0 = render(
        &ctx,
        &cornell_with_short_block(MaterialKind::Glossy {
            reflectance: refl,
            cone_angle_deg: 0.0,
        }),
        &options(WAVE),
    );
    let cone5 = render(
        &ctx,
        &cornell_with_short_block(MaterialKind::Glossy {
            reflectance: refl,
            cone_angle_deg: 5.0,
        }),
        &options(WAVE),
    );
    let d0 = max_abs_diff(&mirror.mean, &cone0.mean);
    let differing = differing_bits(&mirror.mean, &cone0.mean);
    let d5 = max_abs_diff(&mirror.mean, &cone5.mean);
    println!(
        "cornell short block, mirror vs glossy cone 0: max |diff| {d0:e}, {differing} of {} channels not \
         bit-identical; vs cone 5: max |diff| {d5:e}",
        mirror.mean.len()
    );
    assert!(
        d0 <= 1e-5,
        "glossy cone 0 differs from mirror by up to {d0}"
    );
    // The block must be visible, or the comparison means nothing
    assert!(
        d5 > 1e-2,
        "glossy cone 5 is as close to the mirror as cone 0: {d5}"
    );
}

/// A dielectric sphere of ior 1 (no tint) bends and reflects nothing: the
/// scene renders as if it were not there.
#[test]
fn ior_one_sphere_is_invisible() {
    let ctx = context();
    let mut with = load("tests/scenes/dielectric.toml");
    // Paths through the sphere take two more segments: give the depth room
    // so that truncation does not tell the scenes apart (at the file's
    // max_depth 8 the ior 1 sphere darkens the image by about 1.1%)
    with.render.max_depth = 24;
    // Shadow rays stop at the sphere, so the floor under it is lit by BSDF
    // samples only: a heavy-tailed estimator, whose sample variance in a
    // pixel that found the light rarely says it is far off. Fewer pixels,
    // more samples each (at 64 x 64 x 64 spp some 20 pixels fail that way).
    with.render.width = 32;
    with.render.height = 32;
    with.render.spp = 1024;
    let glass = material_index(&with, "glass");
    with.materials[glass].kind = MaterialKind::Dielectric {
        ior: 1.0,
        tint: Vec3::ONE,
    };
    let sphere = with
        .spheres
        .iter()
        .position(|s| s.material as usize == glass)
        .expect("glass sphere");
    let mut without = with.clone();
    without.spheres.remove(sphere);
    let a = render(&ctx, &with, &options(WAVE));
    let b = render(&ctx, &without, &options(WAVE));
    let z = z_test(&a.mean, &a.var_of_mean, &b.mean, &b.var_of_mean, 0.01);
    println!(
        "ior 1 sphere vs no sphere ({} spp, max_depth {}):\n{z}",
        a.spp, with.render.max_depth
    );
    assert!(
        z.pass_fraction >= 0.995,
        "only {:.2}% of pixels pass",
        100.0 * z.pass_fraction
    );
    assert!(
        z.mean_rel_diff.abs() <= 0.01,
        "image means differ by {:+.3}%",
        100.0 * z.mean_rel_diff
    );
    // And the test can tell: the real glass sphere fails it
    let mut glass15 = with.clone();
    glass15.materials[glass].kind = MaterialKind::Dielectric {
        ior: 1.5,
        tint: Vec3::ONE,
    };
    let c = render(&ctx, &glass15, &options(WAVE));
    let zc = z_test(&c.mean, &c.var_of_mean, &b.mean, &b.var_of_mean, 0.01);
    println!(
        "ior 1.5 sphere vs no sphere: {:.2}% of pixels pass",
        100.0 * zc.pass_fraction
    );
    assert!(
        zc.pass_fraction < 0.995,
        "an ior 1.5 sphere passes as invisible"
    );
}

/// A thin dielectric that only reflects (`specular_transmittance` 0) in
/// the white furnace shows the slab's summed reflectance 2R / (1 + R) at
/// each view angle; the reflectance of one face alone, R, must fail.
#[test]
fn thin_dielectric_reflects_both_faces() {
    let ctx = context();
    let base = load("tests/scenes/furnace_quad.toml");
    let cam = CameraRays::new(&base);
    let w = base.render.width as usize;
    let ior = 1.5;
    let case = thin_dielectric_case(ior, 0.0);
    let out = render(&ctx, &furnace_with(&base, &case.kind), &options(WAVE));
    let spp = out.spp as f64;
    let image = |f: &(dyn Fn(f64) -> f64 + Sync)| -> Vec<f64> {
        let table = AngleTable::new(2048, f);
        (0..out.mean.len() / 3)
            .map(|p| cam.pixel_mean(p % w, p / w, 4, |d| table.at(view_cosine(d))))
            .collect()
    };
    let slab = image(&|c| thin_slab_reflectance(c, ior));
    // Each sample weighs 1 or 0: a binomial variance floor
    let floor: Vec<f64> = slab.iter().map(|a| a * (1.0 - a) / spp).collect();
    let good = Agreement::with_floor(&out, &slab, &floor);
    let one_face = image(&|c| fresnel(c, ior));
    let wrong = Agreement::with_floor(&out, &one_face, &floor);
    println!(
        "thin dielectric ior {ior}, reflection only: vs 2R/(1+R): {:.2}% pixels pass, mean {:.5} vs {:.5} \
         ({:+.3}%); vs R: {:.2}% pass, {:+.3}%",
        100.0 * good.pass_fraction,
        good.mean_render,
        good.mean_expected,
        100.0 * good.rel_mean(),
        100.0 * wrong.pass_fraction,
        100.0 * wrong.rel_mean(),
    );
    assert!(good.passes(), "the slab's reflectance fails");
    assert!(!wrong.passes(), "one face's reflectance passes as well");
}

/// A glass sphere in a white furnace: every pixel is 1.
#[test]
fn glass_sphere_in_white_furnace_gives_one() {
    let ctx = context();
    let scene = load("tests/scenes/furnace_glass.toml");
    let sphere = scene.spheres[0];
    let ior = match scene.materials[sphere.material as usize].kind {
        MaterialKind::Dielectric { ior, .. } => ior as f64,
        _ => panic!("the sphere is not a dielectric"),
    };
    let depth = scene.render.max_depth as i32;
    let cam = CameraRays::new(&scene);
    let (w, h) = (scene.render.width as usize, scene.render.height as usize);

    // Energy lost to max_depth: a path that enters the sphere (1 - R) and
    // reflects at its next depth - 2 inner hits (R each: inside a sphere the
    // angle of incidence stays the one it entered with) has no segment left
    let centre = sphere.center.as_dvec3();
    let radius = sphere.radius as f64;
    let loss_at = |d: DVec3, depth: i32| {
        let oc = cam.eye - centre;
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - radius * radius);
        if disc <= 0.0 {
            return 0.0;
        }
        let cos_i = disc.sqrt() / radius; // at the near hit
        let r = fresnel(cos_i, ior);
        (1.0 - r) * r.powi(depth - 2)
    };
    let loss_image = |depth: i32| -> Vec<f64> {
        (0..w * h)
            .map(|p| cam.pixel_mean(p % w, p / w, 8, |d| loss_at(d, depth)))
            .collect()
    };
    let loss = loss_image(depth);
    let mean_loss = loss.iter().sum::<f64>() / loss.len() as f64;
    let max_loss = loss.iter().cloned().fold(0.0, f64::max);
    let loss_half_depth = loss_image(depth / 2).iter().sum::<f64>() / (w * h) as f64;

    let out = render(&ctx, &scene, &options(WAVE));
    let ones = vec![1.0; w * h];
    let agreement = Agreement::new(&out, &ones);
    let lossy: Vec<f64> = loss.iter().map(|l| 1.0 - l).collect();
    let agreement_lossy = Agreement::new(&out, &lossy);
    let min_pixel = out.mean.iter().cloned().fold(f32::MAX, f32::min);
    println!(
        "glass furnace (ior {ior}, max_depth {depth}, {} spp): loss to max_depth: image mean {mean_loss:.2e}, \
         worst pixel {max_loss:.2e} (at max_depth {}: {loss_half_depth:.2e}); render: {:.2}% pixels within \
         5 sigma of 1, worst z {:.2}, mean {:.6} ({:+.4}%, sigma {:.4}%), min pixel {min_pixel:.4}; vs 1 - loss: {:.2}% pass",
        out.spp,
        depth / 2,
        100.0 * agreement.pass_fraction,
        agreement.worst_z,
        agreement.mean_render,
        100.0 * agreement.rel_mean(),
        100.0 * agreement.sigma_mean,
        100.0 * agreement_lossy.pass_fraction,
    );
    assert!(
        mean_loss < 1e-4,
        "max_depth {depth} loses {mean_loss:e} of the image"
    );
    assert!(
        agreement.pass_fraction == 1.0,
        "{:.2}% of pixels within 5 sigma of 1",
        100.0 * agreement.pass_fraction
    );
    assert!(
        agreement.rel_mean().abs() <= 0.005,
        "image mean {}",
        agreement.mean_render
    );
}

/// sRGB decoding of one 8-bit code, with the library's exact curve.
fn srgb_decode(code: u8) -> f64 {
    f64::from(lancer::util::color::srgb_decode(f32::from(code) / 255.0))
}

/// A texture decoded to linear RGB, row 0 at the top.
struct Texture {
    width: usize,
    height: usize,
    texels: Vec<[f64; 3]>,
}

impl Texture {
    fn load(path: &str) -> Texture {
        let img = image::open(repo(path))
            .unwrap_or_else(|e| panic!("{path}: {e}"))
            .to_rgb8();
        let (width, height) = (img.width() as usize, img.height() as usize);
        let texels = img
            .pixels()
            .map(|p| [srgb_decode(p[0]), srgb_decode(p[1]), srgb_decode(p[2])])
            .collect();
        Texture {
            width,
            height,
            texels,
        }
    }

    fn texel(&self, x: i64, y: i64) -> [f64; 3] {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width + x]
    }

    /// Bilinear lookup with repeat wrapping, v = 0 at the bottom row, as
    /// docs/scene-format.md says.
    fn lookup(&self, u: f64, v: f64) -> [f64; 3] {
        let x = u * self.width as f64 - 0.5;
        let y = (1.0 - v) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        std::array::from_fn(|c| {
            let top = self.texel(x0, y0)[c] * (1.0 - fx) + self.texel(x0 + 1, y0)[c] * fx;
            let bottom =
                self.texel(x0, y0 + 1)[c] * (1.0 - fx) + self.texel(x0 + 1, y0 + 1)[c] * fx;
            top * (1.0 - fy) + bottom * fy
        })
    }
}

/// A rendered pixel's colour.
fn pixel(out: &RenderOutput, x: usize, y: usize) -> [f64; 3] {
    let i = 3 * (y * out.width as usize + x);
    [
        out.mean[i] as f64,
        out.mean[i + 1] as f64,
        out.mean[i + 2] as f64,
    ]
}

fn colour_close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|c| (a[c] - b[c]).abs() <= tol)
}

/// A textured quad that fills the view shows the texture upright: uv (0, 0)
/// at the quad's origin, u along edge_u, v along edge_v, v = 0 the bottom
/// row of the image file.
#[test]
fn texture_orientation_on_a_quad() {
    let ctx = context();
    let scene = load("tests/scenes/tex_orientation.toml");
    let tex = Texture::load("tests/scenes/tex/quadrants.png");
    assert_eq!((tex.width, tex.height), (8, 8));
    // The file: one colour per 4 x 4 quadrant (but the corner texels), all distinct
    let quadrant = |qx: i64, qy: i64| tex.texel(4 * qx + 2, 4 * qy + 2); // qy = 0: top half of the file
    let colours = [
        quadrant(0, 0),
        quadrant(1, 0),
        quadrant(0, 1),
        quadrant(1, 1),
    ];
    for (qi, q) in colours.iter().enumerate() {
        for (ti, t) in tex.texels.iter().enumerate() {
            let (x, y) = (ti % 8, ti / 8);
            let corner = (x, y) == (0, 0) || (x, y) == (7, 7);
            if (x / 4 + 2 * (y / 4)) == qi && !corner {
                assert_eq!(t, q, "texel ({x}, {y}) differs from its quadrant");
            }
        }
        for other in &colours[qi + 1..] {
            assert!(
                !colour_close(*q, *other, 0.1),
                "two quadrants share a colour"
            );
        }
    }
    println!("quadrants.png (linear): top-left {:?}, top-right {:?}, bottom-left {:?}, bottom-right {:?}",
        colours[0], colours[1], colours[2], colours[3]);

    let out = render(&ctx, &scene, &options(WAVE));
    let (w, h) = (out.width as usize, out.height as usize);

    // Every pixel: the bilinear texture at the pixel centre's uv (texel
    // centres fall on pixel edges, so the filter is bilinear inside each
    // pixel and its box-filtered mean is its value at the centre)
    let mut passed = 0;
    let mut worst = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let u = (x as f64 + 0.5) / w as f64;
            let v = 1.0 - (y as f64 + 0.5) / h as f64;
            let e = tex.lookup(u, v);
            let a = pixel(&out, x, y);
            let mut ok = true;
            for c in 0..3 {
                let sigma = (out.var_of_mean[3 * (y * w + x) + c] as f64).sqrt();
                ok &= (a[c] - e[c]).abs() <= 5.0 * sigma + 1e-3;
                worst = worst.max((a[c] - e[c]).abs());
            }
            passed += ok as usize;
        }
    }
    let fraction = passed as f64 / (w * h) as f64;

    // The four quadrant centres of the image, against the file's quadrants
    // under lancer's convention and under flipped u and flipped v
    let centres = [
        (w / 4, h / 4),
        (3 * w / 4, h / 4),
        (w / 4, 3 * h / 4),
        (3 * w / 4, 3 * h / 4),
    ];
    let matches = |expect: &dyn Fn(usize, usize) -> [f64; 3]| {
        centres
            .iter()
            .all(|&(x, y)| colour_close(pixel(&out, x, y), expect(x, y), 2e-3))
    };
    // Image quadrant (x < w/2, y < h/2) is u < 0.5, v > 0.5: the file's top-left
    let q = |flip_u: bool, flip_v: bool| {
        move |x: usize, y: usize| {
            let qx = ((x >= w / 2) != flip_u) as i64;
            let qy = ((y >= h / 2) != flip_v) as i64;
            quadrant(qx, qy)
        }
    };
    let right = matches(&q(false, false));
    let flip_u = matches(&q(true, false));
    let flip_v = matches(&q(false, true));
    for &(x, y) in &centres {
        println!("  image pixel ({x}, {y}): {:?}", pixel(&out, x, y));
    }
    println!(
        "texture orientation: {:.2}% of pixels within 5 sigma + 1e-3 of the bilinear texture, worst |diff| \
         {worst:.2e}; quadrant centres match: lancer's convention {right}, flipped u {flip_u}, flipped v {flip_v}",
        100.0 * fraction
    );
    assert!(right, "quadrant centres do not show the texture upright");
    assert!(!flip_u && !flip_v, "a flipped expectation matches too");
    assert!(
        fraction >= 0.995,
        "only {:.2}% of pixels match the texture",
        100.0 * fraction
    );
}

/// Texture coordinates far from [0, 1] (1e7 to 1e30, either sign) repeat
/// to a finite texel inside the texture: every pixel is a colour of the
/// texture (in [0, 1] under a white furnace), none is NaN or black.
#[test]
fn texture_coordinates_far_from_the_unit_square_stay_in_bounds() {
    let ctx = context();
    let dir = tempfile::tempdir().unwrap();
    let texture = repo("tests/scenes/tex/quadrants.png");
    for far in ["1e7", "-3.3e9", "1e20", "-1e30", "3e38"] {
        let obj = format!(
            "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
             vt {far} {far}\nvt {far} 0.5\nvt 0.25 {far}\nvt {far} {far}\n\
             f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
        );
        std::fs::write(dir.path().join("far.obj"), obj).unwrap();
        let camera = "eye = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfov = 90";
        let scene_text = scene_header((16, 16), 4, 2, camera, "[1, 1, 1]")
            + &format!(
                "[materials.t]\ntype = \"lambert\"\nalbedo_texture = {texture:?}\n\
                 [[objects]]\ntype = \"mesh\"\nfile = \"far.obj\"\nmaterial = \"t\"\n"
            );
        let path = dir.path().join("far.toml");
        std::fs::write(&path, scene_text).unwrap();
        let scene = lancer::scene::load(&path).unwrap_or_else(|e| panic!("{far}: {e}"));
        let out = render(&ctx, &scene, &RenderOptions::default());
        let (lo, hi) = out
            .mean
            .iter()
            .fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        assert!(
            lo >= 0.0 && hi <= 1.0 + 1e-5,
            "uv {far}: pixels in [{lo}, {hi}]"
        );
        let brightest = out
            .mean
            .chunks(3)
            .map(|p| p[0] + p[1] + p[2])
            .fold(0.0, f32::max);
        assert!(brightest > 0.1, "uv {far}: the quad is black");
    }
}
