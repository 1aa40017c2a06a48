//! Each material's sampling, run on the device by the shade kernel's own
//! functions (`bsdf_sample`, `bsdf_eval`, through `shaders/test_bsdf.comp`),
//! tested against its pdf in the manner of pbrt-v4's `bsdfs_test` and
//! Mitsuba 3's `chi2.py`:
//!
//! - lambert, phong and glossy: a million samples are counted in cells of
//!   equal solid angle (rings of equal cos θ about an axis, cut into equal
//!   sectors of φ); the expected count of each cell is the pdf that
//!   `bsdf_eval` gives on the device, integrated over the cell; cells
//!   expecting fewer than 5 samples are pooled; Pearson's χ² gives a
//!   p-value, compared with a Šidák-corrected level for the whole family of
//!   tests. Also: the pdf integrates to the fraction of samples that go on,
//!   and every sample's weight is f · cos / pdf;
//! - rough conductors and rough dielectrics likewise, the rough dielectrics
//!   over the whole sphere (reflection above, refraction below) on a grid
//!   graded towards both lobes, with wo outside and inside;
//! - mirror and dielectric (delta lobes): exact directions (mirror, Snell),
//!   the exact weights, and the frequency of reflection against the exact
//!   Fresnel term by a binomial test, including total internal reflection.
//!
//! Incident angles: normal (cos θ = 1), 60° (0.5) and grazing (0.001).

use crate::common;

use common::materials::{fresnel, fresnel_conductor, glossy, lambert, material, phong};
use common::*;
use std::f64::consts::{PI, TAU};

use glam::{DVec3, Vec2, Vec3};
use lancer::render::{KernelBsdfSample, Renderer};
use lancer::scene::ColorSource;
use lancer::scene::{conductor_preset, MaterialKind, Microfacet, Scene, Sphere};
use statrs::distribution::{Binomial, ChiSquared, ContinuousCDF, DiscreteCDF};

/// Samples per χ² test.
const SAMPLES: usize = 1_000_000;
/// Samples per χ² test of a rough plastic: its glossy lobe gets only its
/// share of them (about a tenth at normal incidence), so eight times as
/// many give that lobe about the samples, and the power, of a rough
/// conductor's test.
const ROUGH_PLASTIC_SAMPLES: usize = 8 * SAMPLES;
/// Samples per setting of a delta material.
const DELTA_SAMPLES: usize = 200_000;
/// Significance level of the whole family of tests, split among them by
/// the Šidák correction.
const ALPHA: f64 = 0.01;
/// Cells expecting fewer samples than this are pooled.
const MIN_EXPECTED: f64 = 5.0;
/// Cosines of the incident angles: normal, 60 degrees, grazing.
const COS_ANGLES: [f64; 3] = [1.0, 0.5, 0.001];
/// Midpoint-rule points per side of a cell, integrating the pdf.
const INTEGRATION_POINTS: usize = 16;
/// Midpoint-rule points per side of a cell of a rough lobe at grazing
/// incidence, and of a rough plastic's.
const GRAZING_POINTS: usize = 48;
/// How much finer in cos θ than in φ a Phong lobe is integrated.
const PHONG_ROWS_PER_POINT: usize = 4;
/// Midpoint-rule points per side of a cell where the pdf steps.
const REFINED_POINTS: usize = 64;
/// Sectors of φ per ring of cells.
const SECTORS: usize = 40;
/// Rings of cells over the part of the sphere where a lobe lies.
const FINE_RINGS: usize = 20;
/// Rings of cells about a Phong lobe.
const PHONG_RINGS: usize = 30;
/// Steps of a graded grid on each side of a lobe's peak, in cos θ and in φ.
const GRADED_STEPS: usize = 20;
/// How far the pdf's integral may stray from the fraction of samples that
/// go on, beyond five binomial standard deviations: the midpoint rule's
/// error on cells cut by the horizon.
const INTEGRAL_TOLERANCE: f64 = 1e-3;
/// Relative tolerance of f32 figures the kernel computes two ways.
const F32_TOLERANCE: f32 = 1e-4;

/// A material under test and its name in the tables.
struct TestMaterial {
    name: &'static str,
    kind: MaterialKind,
}

/// The diffuse colour of the phong materials: `kd` in red, 0.8 `kd` in green
/// and 0.6 `kd` in blue.
fn warm(kd: f32) -> Vec3 {
    Vec3::new(kd, kd * 0.8, kd * 0.6)
}

/// The reflectance of the glossy materials.
const GLOSSY_REFLECTANCE: Vec3 = Vec3::new(0.9, 0.7, 0.5);

/// Index of the mirror in [`materials`].
const MIRROR: u32 = 7;
/// Index of the dielectric in [`materials`].
const DIELECTRIC: u32 = 8;
/// Materials `0..CHI2_MATERIALS` of [`materials`] get the χ² test.
const CHI2_MATERIALS: u32 = 7;
/// The rough conductors of [`materials`]: each gets the χ² test, the
/// anisotropic ones also with wo off the tangent's plane.
const ROUGH: std::ops::Range<u32> = 11..18;
/// Index of the smooth gold conductor in [`materials`].
const CONDUCTOR: u32 = 20;
/// Negative controls: samples of the first material against the pdf of
/// the second, a near miss the test must reject.
const CONTROLS: [(u32, u32); 4] = [(2, 9), (5, 10), (12, 18), (19, 12)];
/// The rough dielectrics of [`materials`]: each gets the χ² test from both
/// sides, the anisotropic ones also with wo off the tangent's plane.
const ROUGH_DIELECTRIC: std::ops::Range<u32> = 21..26;
/// Negative controls of the rough dielectrics, tested with wo outside and
/// inside: GGX alpha 0.3 against 0.34, and ior 1.5 against 1.6.
const ROUGH_DIELECTRIC_CONTROLS: [(u32, u32); 2] = [(22, 26), (22, 27)];
/// The smooth plastics of [`materials`]: their diffuse base gets the χ²
/// test, the coating's mirror samples counted apart (as not going on).
const PLASTIC: std::ops::Range<u32> = 28..30;
/// The narrowest Phong lobe and glossy cone of [`materials`], tested by
/// χ² besides materials `0..CHI2_MATERIALS`.
const NARROW: [u32; 2] = [30, 31];
/// Azimuths of wo (from the tangent) at which the anisotropic rough
/// conductors are tested besides 0.
const ANISOTROPIC_PHI_DEG: [f64; 1] = [60.0];
/// The rough plastics of [`materials`]: each gets the χ² test (both
/// lobes, the coating's visible-normal reflection and the base's cosine
/// samples, against the mixture pdf).
const ROUGH_PLASTIC: std::ops::Range<u32> = 32..37;
/// Negative control of the rough plastics: GGX alpha 0.3 against 0.36.
const ROUGH_PLASTIC_CONTROL: (u32, u32) = (33, 36);
/// Blends (Mitsuba's `blendbsdf`): a lambert and a GGX conductor, and a
/// rough plastic and an anisotropic Beckmann conductor.
const BLEND: std::ops::Range<u32> = 37..39;
/// The first blend at weight 0.3 sampled, its pdf at weight 0.4 claimed.
const BLEND_CONTROL: (u32, u32) = (37, 39);
/// Principled materials (Mitsuba's `principled`): diffuse-heavy with
/// sheen; an anisotropic metal under a clearcoat; a nearly smooth one under
/// a clearcoat, with sampling rates of its own.
const PRINCIPLED: std::ops::Range<u32> = 40..43;
/// The anisotropic metal of roughness 0.3 sampled, its pdf at 0.36 claimed.
const PRINCIPLED_CONTROL: (u32, u32) = (41, 43);
/// Blends whose second component samples a delta lobe: a lambert and a
/// smooth gold conductor, a lambert and a smooth plastic.
const BLEND_DELTA: std::ops::Range<u32> = 44..46;
/// Weight of the delta components of `BLEND_DELTA`.
const BLEND_DELTA_WEIGHTS: [f32; 2] = [0.4, 0.5];
/// Index of refraction of the dielectric.
const IOR: f32 = 1.5;
/// Tint of the dielectric, applied at each refraction.
const TINT: [f32; 3] = [0.9, 0.8, 0.7];

/// Every material of the test scene, in scene order.
fn materials() -> Vec<TestMaterial> {
    let m = |name, kind| TestMaterial { name, kind };
    vec![
        m("lambert", lambert(Vec3::new(0.8, 0.6, 0.4))),
        m("phong n=1 kd=.5 ks=.4", phong(warm(0.5), 0.4, 1.0)),
        m("phong n=20 kd=.3 ks=.6", phong(warm(0.3), 0.6, 20.0)),
        m("phong n=300 kd=.05 ks=.9", phong(warm(0.05), 0.9, 300.0)),
        m("glossy 10deg", glossy(GLOSSY_REFLECTANCE, 10.0)),
        m("glossy 30deg", glossy(GLOSSY_REFLECTANCE, 30.0)),
        m("glossy 70deg", glossy(GLOSSY_REFLECTANCE, 70.0)),
        m(
            "mirror",
            MaterialKind::Mirror {
                reflectance: Vec3::new(0.9, 0.8, 0.7),
            },
        ),
        m(
            "dielectric",
            MaterialKind::Dielectric {
                ior: IOR,
                tint: Vec3::from(TINT),
            },
        ),
        m("phong n=24 kd=.3 ks=.6", phong(warm(0.3), 0.6, 24.0)),
        m("glossy 33deg", glossy(GLOSSY_REFLECTANCE, 33.0)),
        m("ggx a=.05 Au", rough(Microfacet::Ggx, 0.05, 0.05, "Au")),
        m("ggx a=.3 Cu", rough(Microfacet::Ggx, 0.3, 0.3, "Cu")),
        m(
            "ggx au=.05 av=.4 Al",
            rough(Microfacet::Ggx, 0.05, 0.4, "Al"),
        ),
        m("ggx a=1 none", rough(Microfacet::Ggx, 1.0, 1.0, "none")),
        m(
            "beckmann a=.1 Au",
            rough(Microfacet::Beckmann, 0.1, 0.1, "Au"),
        ),
        m(
            "beckmann a=.5 none",
            rough(Microfacet::Beckmann, 0.5, 0.5, "none"),
        ),
        m(
            "beckmann au=.3 av=.08 Cr",
            rough(Microfacet::Beckmann, 0.3, 0.08, "Cr"),
        ),
        m("ggx a=.34 Cu", rough(Microfacet::Ggx, 0.34, 0.34, "Cu")),
        m(
            "beckmann a=.3 Cu",
            rough(Microfacet::Beckmann, 0.3, 0.3, "Cu"),
        ),
        m(
            "conductor Au",
            MaterialKind::Conductor {
                ior: conductor_preset("Au").unwrap(),
                specular_reflectance: Vec3::new(0.9, 0.8, 1.0),
            },
        ),
        m(
            "rd ggx a=.05",
            rough_glass(Microfacet::Ggx, 0.05, 0.05, IOR),
        ),
        m("rd ggx a=.3", rough_glass(Microfacet::Ggx, 0.3, 0.3, IOR)),
        m(
            "rd ggx au=.05 av=.4",
            rough_glass(Microfacet::Ggx, 0.05, 0.4, IOR),
        ),
        m(
            "rd beckmann a=.1",
            rough_glass(Microfacet::Beckmann, 0.1, 0.1, IOR),
        ),
        m(
            "rd beckmann au=.3 av=.08",
            rough_glass(Microfacet::Beckmann, 0.3, 0.08, IOR),
        ),
        m(
            "rd ggx a=.34",
            rough_glass(Microfacet::Ggx, 0.34, 0.34, IOR),
        ),
        m(
            "rd ggx a=.3 ior 1.6",
            rough_glass(Microfacet::Ggx, 0.3, 0.3, 1.6),
        ),
        m(
            "plastic ior 1.49",
            MaterialKind::Plastic {
                diffuse_reflectance: ColorSource::Constant(Vec3::new(0.7, 0.15, 0.1)),
                specular_reflectance: Vec3::new(0.8, 0.9, 1.0),
                ior: 1.49,
                nonlinear: false,
            },
        ),
        m(
            "plastic nonlinear ior 1.9",
            MaterialKind::Plastic {
                diffuse_reflectance: ColorSource::Constant(Vec3::new(0.1, 0.6, 0.9)),
                specular_reflectance: Vec3::ONE,
                ior: 1.9,
                nonlinear: true,
            },
        ),
        m("phong n=3000 kd=.05 ks=.9", phong(warm(0.05), 0.9, 3000.0)),
        m("glossy 5deg", glossy(GLOSSY_REFLECTANCE, 5.0)),
        m(
            "rp ggx a=.05 ior 1.5",
            rough_plastic(Microfacet::Ggx, 0.05, Vec3::new(0.7, 0.15, 0.1), 1.5, false),
        ),
        m(
            "rp ggx a=.3 ior 1.9 nl",
            rough_plastic(Microfacet::Ggx, 0.3, Vec3::new(0.1, 0.6, 0.9), 1.9, true),
        ),
        m(
            "rp beckmann a=.1 ior 1.33",
            rough_plastic(
                Microfacet::Beckmann,
                0.1,
                Vec3::new(0.5, 0.5, 0.2),
                1.33,
                false,
            ),
        ),
        m(
            "rp beckmann a=.6 ior 1.49",
            rough_plastic(Microfacet::Beckmann, 0.6, Vec3::splat(0.9), 1.49, false),
        ),
        m(
            "rp ggx a=.36 ior 1.9 nl",
            rough_plastic(Microfacet::Ggx, 0.36, Vec3::new(0.1, 0.6, 0.9), 1.9, true),
        ),
        m("blend .3 lambert, ggx a=.2 Au", lambert_and_gold(0.3)),
        m(
            "blend .7 rp ggx a=.1, beckmann .05/.4 Cu",
            MaterialKind::Blend {
                weight: ColorSource::Constant(Vec3::splat(0.7)),
                components: Box::new([
                    rough_plastic(Microfacet::Ggx, 0.1, Vec3::new(0.2, 0.5, 0.8), 1.5, false),
                    rough(Microfacet::Beckmann, 0.05, 0.4, "Cu"),
                ]),
            },
        ),
        m("blend .4 lambert, ggx a=.2 Au", lambert_and_gold(0.4)),
        m(
            "principled r=.35 sheen .8 flat .5",
            principled(Principled {
                roughness: 0.35,
                specular_tint_sheen_flatness: [0.6, 0.8, 0.5],
                ..Principled::default()
            }),
        ),
        m(
            "principled metal .8 r=.3 aniso .7 coat .9",
            coated_metal(0.3),
        ),
        m(
            "principled r=.2 coat .5 rates 2/1/.5",
            principled(Principled {
                roughness: 0.2,
                clearcoat: [0.5, 0.0],
                rates: [2.0, 1.0, 0.5],
                ..Principled::default()
            }),
        ),
        m(
            "principled metal .8 r=.36 aniso .7 coat .9",
            coated_metal(0.36),
        ),
        m(
            "blend .4 lambert, conductor Au",
            lambert_and(
                BLEND_DELTA_WEIGHTS[0],
                MaterialKind::Conductor {
                    ior: conductor_preset("Au").unwrap(),
                    specular_reflectance: Vec3::ONE,
                },
            ),
        ),
        m(
            "blend .5 lambert, plastic ior 1.49",
            lambert_and(
                BLEND_DELTA_WEIGHTS[1],
                MaterialKind::Plastic {
                    diffuse_reflectance: ColorSource::Constant(Vec3::new(0.1, 0.3, 0.7)),
                    specular_reflectance: Vec3::ONE,
                    ior: 1.49,
                    nonlinear: false,
                },
            ),
        ),
    ]
}

/// The settings of a test's principled material that its sampling sees,
/// and a few it does not (the specular tint, sheen and flatness).
#[derive(Clone, Copy)]
struct Principled {
    metallic: f32,
    roughness: f32,
    anisotropic: f32,
    /// The specular tint, sheen and flatness.
    specular_tint_sheen_flatness: [f32; 3],
    /// The clearcoat and its gloss.
    clearcoat: [f32; 2],
    /// The sampling rates of the specular, clearcoat and diffuse lobes.
    rates: [f32; 3],
}

impl Default for Principled {
    fn default() -> Self {
        Principled {
            metallic: 0.0,
            roughness: 0.5,
            anisotropic: 0.0,
            specular_tint_sheen_flatness: [0.0; 3],
            clearcoat: [0.0; 2],
            rates: [1.0; 3],
        }
    }
}

/// A principled metal (metallic 0.8) of roughness `roughness`, anisotropic
/// 0.7, under a clearcoat of 0.9 and gloss 0.6.
fn coated_metal(roughness: f32) -> MaterialKind {
    principled(Principled {
        metallic: 0.8,
        roughness,
        anisotropic: 0.7,
        clearcoat: [0.9, 0.6],
        ..Principled::default()
    })
}

/// A principled material of a warm base colour and eta 1.5 with `p`.
fn principled(p: Principled) -> MaterialKind {
    let [spec_tint, sheen, flatness] = p.specular_tint_sheen_flatness;
    MaterialKind::Principled(Box::new(lancer::scene::Principled {
        base_color: ColorSource::Constant(Vec3::new(0.8, 0.5, 0.3)),
        roughness: p.roughness,
        anisotropic: p.anisotropic,
        metallic: p.metallic,
        spec_tint,
        sheen,
        sheen_tint: 0.5,
        clearcoat: p.clearcoat[0],
        clearcoat_gloss: p.clearcoat[1],
        flatness,
        eta: 1.5,
        sampling_rates: p.rates,
        weight_textures: None,
    }))
}

/// A blend of a warm lambert and a GGX gold of alpha 0.2, `weight` gold.
fn lambert_and_gold(weight: f32) -> MaterialKind {
    lambert_and(weight, rough(Microfacet::Ggx, 0.2, 0.2, "Au"))
}

/// The warm lambert of the blends.
const BLEND_LAMBERT: Vec3 = Vec3::new(0.8, 0.6, 0.4);

/// A blend of the warm lambert and `second`, `weight` the second.
fn lambert_and(weight: f32, second: MaterialKind) -> MaterialKind {
    MaterialKind::Blend {
        weight: ColorSource::Constant(Vec3::splat(weight)),
        components: Box::new([lambert(BLEND_LAMBERT), second]),
    }
}

/// Samples of the χ² test of a material of kind `kind`.
fn samples_for(kind: &MaterialKind) -> usize {
    match kind {
        MaterialKind::RoughPlastic { .. } => ROUGH_PLASTIC_SAMPLES,
        MaterialKind::Blend { components, .. } => {
            components.iter().map(samples_for).max().unwrap_or(SAMPLES)
        }
        _ => SAMPLES,
    }
}

/// A rough plastic with a bluish coating (specular 0.8, 0.9, 1), so that
/// the lobe choice is not the even one.
fn rough_plastic(
    distribution: Microfacet,
    alpha: f32,
    diffuse: Vec3,
    ior: f32,
    nonlinear: bool,
) -> MaterialKind {
    MaterialKind::RoughPlastic {
        distribution,
        alpha,
        diffuse_reflectance: lancer::scene::ColorSource::Constant(diffuse),
        specular_reflectance: Vec3::new(0.8, 0.9, 1.0),
        ior,
        nonlinear,
    }
}

/// A rough dielectric of index `ior` (inside over outside), its
/// reflection and refraction tinted apart so that a swap would show.
fn rough_glass(distribution: Microfacet, alpha_u: f32, alpha_v: f32, ior: f32) -> MaterialKind {
    MaterialKind::RoughDielectric {
        distribution,
        alpha_u,
        alpha_v,
        alpha_textures: None,
        ior,
        specular_reflectance: Vec3::new(0.9, 0.8, 1.0),
        specular_transmittance: Vec3::new(1.0, 0.9, 0.7),
    }
}

/// The χ² tests of the rough dielectrics: `(material, azimuth of wo in
/// degrees, wo outside)`, three incident angles each.
fn rough_dielectric_settings() -> Vec<(u32, f64, bool)> {
    let materials = materials();
    let mut out = Vec::new();
    for i in ROUGH_DIELECTRIC {
        for front in [true, false] {
            out.push((i, 0.0, front));
            if let MaterialKind::RoughDielectric {
                alpha_u, alpha_v, ..
            } = materials[i as usize].kind
            {
                if alpha_u != alpha_v {
                    out.extend(ANISOTROPIC_PHI_DEG.map(|phi| (i, phi, front)));
                }
            }
        }
    }
    out
}

/// A rough conductor of Mitsuba preset `preset`.
fn rough(distribution: Microfacet, alpha_u: f32, alpha_v: f32, preset: &str) -> MaterialKind {
    MaterialKind::RoughConductor {
        distribution,
        alpha_u,
        alpha_v,
        alpha_textures: None,
        ior: conductor_preset(preset).expect("a Mitsuba preset"),
        specular_reflectance: Vec3::ONE,
    }
}

/// The χ² tests of the rough conductors: `(material, azimuth of wo in
/// degrees)`, three incident angles each.
fn rough_settings() -> Vec<(u32, f64)> {
    let materials = materials();
    let mut out = Vec::new();
    for i in ROUGH {
        out.push((i, 0.0));
        if let MaterialKind::RoughConductor {
            alpha_u, alpha_v, ..
        } = materials[i as usize].kind
        {
            if alpha_u != alpha_v {
                out.extend(ANISOTROPIC_PHI_DEG.map(|phi| (i, phi)));
            }
        }
    }
    out
}

/// Settings of the dielectric: wo on the front (outside) or back (inside)
/// side, and cos θ. Inside, the critical angle has cos θ = 0.745: the
/// last three settings reflect totally.
const DIELECTRIC_SETTINGS: [(bool, f64); 9] = [
    (true, 1.0),
    (true, 0.5),
    (true, 0.001),
    (false, 1.0),
    (false, 0.8),
    (false, 0.75),
    (false, 0.74),
    (false, 0.5),
    (false, 0.001),
];

/// The statistical tests of the family: a χ² test per material and angle,
/// and a binomial test per dielectric setting that is not total internal
/// reflection (that one is exact: every sample must reflect).
fn family_size() -> usize {
    let binomial = DIELECTRIC_SETTINGS
        .iter()
        .filter(|(front, c)| fresnel(*c, eta(*front)) < 1.0)
        .count();
    (CHI2_MATERIALS as usize
        + rough_settings().len()
        + rough_dielectric_settings().len()
        + PLASTIC.len()
        + NARROW.len()
        + ROUGH_PLASTIC.len()
        + BLEND.len()
        + PRINCIPLED.len()
        + BLEND_DELTA.len())
        * COS_ANGLES.len()
        + binomial
}

/// The Šidák-corrected level of each test: the family of `family_size()`
/// independent tests then rejects a true hypothesis with probability `ALPHA`.
fn sidak_level() -> f64 {
    1.0 - (1.0 - ALPHA).powf(1.0 / family_size() as f64)
}

/// A scene holding every test material, on one sphere each (so that the
/// kernels are specialised for all of them), with a wave of 2^18 paths.
fn scene() -> Scene {
    let mut scene = load("tests/scenes/furnace.toml");
    scene.render.spp = 64;
    scene.materials = materials()
        .into_iter()
        .map(|m| material(m.name, m.kind))
        .collect();
    scene.spheres = (0..scene.materials.len() as u32)
        .map(|i| Sphere {
            center: Vec3::new(3.0 * i as f32, 0.0, -10.0),
            radius: 1.0,
            material: i,
            mitsuba_frame: None,
        })
        .collect();
    scene
}

/// The direction light leaves by at cos θ from the normal +z.
fn outgoing(cos_theta: f64) -> DVec3 {
    outgoing_at(cos_theta, 0.0)
}

/// The direction light leaves by at cos θ from the normal +z and azimuth
/// `phi_deg` degrees from the tangent +x.
fn outgoing_at(cos_theta: f64, phi_deg: f64) -> DVec3 {
    let s = (1.0 - cos_theta * cos_theta).sqrt();
    let phi = phi_deg.to_radians();
    DVec3::new(s * phi.cos(), s * phi.sin(), cos_theta)
}

/// The mirror direction of `wo` about +z.
fn reflect(wo: DVec3) -> DVec3 {
    DVec3::new(-wo.x, -wo.y, wo.z)
}

/// `count` triples of seeded uniform numbers in [0, 1).
fn uniforms(seed: u64, count: usize) -> Vec<Vec3> {
    let mut rng = fastrand::Rng::with_seed(seed);
    (0..count)
        .map(|_| Vec3::new(rng.f32(), rng.f32(), rng.f32()))
        .collect()
}

/// `count` pairs of uniform numbers in [0, 1), from `seed`.
fn uniform_pairs(seed: u64, count: usize) -> Vec<Vec2> {
    let mut rng = fastrand::Rng::with_seed(seed);
    (0..count)
        .map(|_| Vec2::new(rng.f32(), rng.f32()))
        .collect()
}

/// Cells of the sphere: a grid in (cos θ, φ) about `axis` (φ = 0 along
/// `t`), between the cosines `edges` (ascending from -1 to 1) and the
/// angles `phi_edges` (ascending from -π to π). In (cos θ, φ) solid angle
/// is plain area, so the pdf integrates with no Jacobian.
struct Cells {
    axis: DVec3,
    t: DVec3,
    b: DVec3,
    edges: Vec<f64>,
    phi_edges: Vec<f64>,
}

/// A point where the pdf is evaluated: its direction, the solid angle it
/// stands for, and its cell.
struct IntegrationPoint {
    direction: Vec3,
    weight: f64,
    cell: usize,
}

/// `n` equal steps from `lo` to `hi`, both ends included.
fn uniform_edges(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..=n)
        .map(|i| lo + (hi - lo) * i as f64 / n as f64)
        .collect()
}

/// Edges from `lo` to `hi`, `per_side` steps on each side of `centre`,
/// the first `first` wide at the centre and widening outwards (a power
/// law): fine where a lobe peaks, yet covering the whole range.
fn graded_edges(lo: f64, hi: f64, centre: f64, first: f64, per_side: usize) -> Vec<f64> {
    let side = |length: f64| -> Vec<f64> {
        if length <= 0.0 {
            return Vec::new();
        }
        let m = per_side as f64;
        let power = ((length / first).ln() / m.ln()).max(1.0);
        (1..=per_side)
            .map(|j| length * (j as f64 / m).powf(power))
            .collect()
    };
    let mut edges: Vec<f64> = side(centre - lo).iter().rev().map(|d| centre - d).collect();
    edges.push(centre);
    edges.extend(side(hi - centre).iter().map(|d| centre + d));
    edges.dedup();
    *edges.first_mut().expect("edges") = lo;
    *edges.last_mut().expect("edges") = hi;
    edges
}

/// Edges from `lo` to `hi`, `per_side` steps on each side of `centre`
/// whose distances from it grow geometrically from `first`: each cell is
/// a fixed multiple of its distance from the peak, as the heavy tail of a
/// GGX lobe (1 / distance²) needs for the midpoint rule.
fn geometric_edges(lo: f64, hi: f64, centre: f64, first: f64, per_side: usize) -> Vec<f64> {
    let side = |length: f64| -> Vec<f64> {
        if length <= first {
            return if length > 0.0 {
                vec![length]
            } else {
                Vec::new()
            };
        }
        let ratio = (length / first).powf(1.0 / (per_side - 1) as f64);
        (0..per_side)
            .map(|j| first * ratio.powi(j as i32))
            .collect()
    };
    let mut edges: Vec<f64> = side(centre - lo).iter().rev().map(|d| centre - d).collect();
    edges.push(centre);
    edges.extend(side(hi - centre).iter().map(|d| centre + d));
    edges.dedup();
    *edges.first_mut().expect("edges") = lo;
    *edges.last_mut().expect("edges") = hi;
    edges
}

impl Cells {
    /// The grid about `axis` with φ = 0 towards `towards` (any direction
    /// when none is given or it lies along the axis).
    fn new(axis: DVec3, towards: Option<DVec3>, edges: Vec<f64>, phi_edges: Vec<f64>) -> Cells {
        let t = towards.and_then(|d| d.reject_from(axis).try_normalize());
        let (t, b) = match t {
            Some(t) => (t, axis.cross(t)),
            None => axis.any_orthonormal_pair(),
        };
        Cells {
            axis,
            t,
            b,
            edges,
            phi_edges,
        }
    }

    /// `coarse` rings from cos = -1 to `cap`, then [`FINE_RINGS`] from
    /// `cap` to 1, each cut into [`SECTORS`] equal sectors.
    fn capped(axis: DVec3, cap: f64, coarse: usize) -> Cells {
        let mut edges = uniform_edges(-1.0, cap, coarse);
        edges.pop();
        edges.extend(uniform_edges(cap, 1.0, FINE_RINGS));
        Cells::new(axis, None, edges, uniform_edges(-PI, PI, SECTORS))
    }

    /// `rings` rings about `axis` whose widths in 1 - cos grow
    /// geometrically from `first` at the axis, each cut into [`SECTORS`]
    /// equal sectors: fine near the axis for a peaked lobe, yet covering
    /// the sphere.
    fn graded_rings(axis: DVec3, first: f64, rings: usize) -> Cells {
        let ratio = (2.0 / first).powf(1.0 / (rings - 1) as f64);
        let mut edges: Vec<f64> = (0..rings)
            .map(|j| 1.0 - first * ratio.powi(j as i32))
            .collect();
        edges[rings - 1] = -1.0;
        edges.reverse();
        edges.push(1.0);
        Cells::new(axis, None, edges, uniform_edges(-PI, PI, SECTORS))
    }

    /// The upper hemisphere about the normal +z on a grid graded towards
    /// the lobe about direction `peak` (width about `width` radians), and
    /// the lower hemisphere as one ring of [`SECTORS`] sectors.
    fn about_lobe(peak: DVec3, width: f64) -> Cells {
        // A lobe `width` wide spans about width (sin θ + width / 2) in cos θ
        // about its peak, and width / sin θ in φ
        let first = width / 8.0;
        let sin_peak = (1.0 - peak.z * peak.z).max(0.0).sqrt();
        let mut edges = vec![-1.0];
        let c_first = first * (sin_peak + width / 2.0);
        edges.extend(graded_edges(
            0.0,
            1.0,
            peak.z.clamp(0.0, 1.0),
            c_first,
            GRADED_STEPS,
        ));
        // φ = 0 towards the peak: the grid is graded about φ = 0
        let phi_first = (first / sin_peak.max(first)).min(0.5);
        let phi_edges = graded_edges(-PI, PI, 0.0, phi_first, GRADED_STEPS);
        Cells::new(DVec3::Z, Some(peak), edges, phi_edges)
    }

    /// The whole sphere about the normal +z, φ = 0 towards the reflected
    /// peak `peak`: the upper hemisphere graded geometrically towards cos θ = `peak.z`
    /// for a lobe about `width` radians wide, the lower towards cos θ =
    /// `t_z` for a refracted lobe about `width_t` wide, and φ graded about 0.
    fn about_two_lobes(peak: DVec3, width: f64, t_z: f64, width_t: f64) -> Cells {
        let (first, first_t) = (width / 8.0, width_t / 8.0);
        let sin_peak = (1.0 - peak.z * peak.z).max(0.0).sqrt();
        let sin_t = (1.0 - t_z * t_z).max(0.0).sqrt();
        let mut edges = geometric_edges(
            -1.0,
            0.0,
            t_z.clamp(-1.0, 0.0),
            first_t * (sin_t + width_t / 2.0),
            GRADED_STEPS,
        );
        edges.pop();
        edges.extend(geometric_edges(
            0.0,
            1.0,
            peak.z.clamp(0.0, 1.0),
            first * (sin_peak + width / 2.0),
            GRADED_STEPS,
        ));
        // φ steps fine enough for the narrower lobe in φ
        let phi_first = (first / sin_peak.max(first))
            .min(first_t / sin_t.max(first_t))
            .min(0.5);
        let phi_edges = geometric_edges(-PI, PI, 0.0, phi_first, GRADED_STEPS);
        Cells::new(DVec3::Z, Some(peak), edges, phi_edges)
    }

    fn rings(&self) -> usize {
        self.edges.len() - 1
    }

    fn sectors(&self) -> usize {
        self.phi_edges.len() - 1
    }

    fn count(&self) -> usize {
        self.rings() * self.sectors()
    }

    /// The cell that holds direction `d`.
    fn index(&self, d: DVec3) -> usize {
        let d = d.normalize();
        let c = d.dot(self.axis).clamp(-1.0, 1.0);
        let phi = d.dot(self.b).atan2(d.dot(self.t));
        let bin = |edges: &[f64], x: f64| {
            (edges.partition_point(|&e| e <= x).max(1) - 1).min(edges.len() - 2)
        };
        bin(&self.edges, c) * self.sectors() + bin(&self.phi_edges, phi)
    }

    /// The direction at (cos θ, φ).
    fn direction(&self, c: f64, phi: f64) -> DVec3 {
        let s = (1.0 - c * c).max(0.0).sqrt();
        s * (phi.cos() * self.t + phi.sin() * self.b) + c * self.axis
    }

    /// The angles φ in (lo, hi) where the circle of cos θ = `c` crosses the
    /// surface (z = 0): there the pdf drops to 0, and the integration
    /// splits so that no midpoint straddles the step.
    fn horizon_crossings(&self, c: f64, lo: f64, hi: f64) -> Vec<f64> {
        // z = s (cos φ t.z + sin φ b.z) + c axis.z = amp cos(φ - phi0) + c axis.z
        let s = (1.0 - c * c).max(0.0).sqrt();
        let amp = s * self.t.z.hypot(self.b.z);
        if amp <= 0.0 {
            return Vec::new();
        }
        let q = -c * self.axis.z / amp;
        if q.abs() >= 1.0 {
            return Vec::new();
        }
        let phi0 = self.b.z.atan2(self.t.z);
        let w = q.acos();
        let mut crossings: Vec<f64> = [phi0 - w, phi0 + w]
            .into_iter()
            .flat_map(|x| [x - TAU, x, x + TAU])
            .filter(|x| lo < *x && *x < hi)
            .collect();
        crossings.sort_by(f64::total_cmp);
        crossings
    }

    /// The midpoint-rule points of cell `cell`, appended to `points`:
    /// `rows` rows of cos θ, and along each row `k` points of φ on each
    /// side of the surface where the row crosses it.
    fn cell_points(&self, cell: usize, rows: usize, k: usize, points: &mut Vec<IntegrationPoint>) {
        let (ring, sector) = (cell / self.sectors(), cell % self.sectors());
        let (c0, c1) = (self.edges[ring], self.edges[ring + 1]);
        let (phi0, phi1) = (self.phi_edges[sector], self.phi_edges[sector + 1]);
        let dc = (c1 - c0) / rows as f64;
        for i in 0..rows {
            let c = c0 + dc * (i as f64 + 0.5);
            let mut cuts = vec![phi0];
            cuts.extend(self.horizon_crossings(c, phi0, phi1));
            cuts.push(phi1);
            for piece in cuts.windows(2) {
                let step = (piece[1] - piece[0]) / k as f64;
                for j in 0..k {
                    let phi = piece[0] + step * (j as f64 + 0.5);
                    points.push(IntegrationPoint {
                        direction: self.direction(c, phi).as_vec3(),
                        weight: dc * step,
                        cell,
                    });
                }
            }
        }
    }

    /// The midpoint-rule points of the cells `cells`, `k` by `k` each.
    fn integration_points(
        &self,
        cells: impl Iterator<Item = usize>,
        k: usize,
    ) -> Vec<IntegrationPoint> {
        self.integration_rows(cells, k, k)
    }

    /// The midpoint-rule points of the cells `cells`, `rows` rows of cos θ
    /// by `k` points of φ each.
    fn integration_rows(
        &self,
        cells: impl Iterator<Item = usize>,
        rows: usize,
        k: usize,
    ) -> Vec<IntegrationPoint> {
        let mut points = Vec::new();
        for cell in cells {
            self.cell_points(cell, rows, k, &mut points);
        }
        points
    }
}

/// The cells a material's samples are counted in, for light leaving along
/// `wo`: equal cells about the normal for lambert; for phong a grid graded
/// towards its lobe; for glossy rings about the mirror direction that end
/// at the cone's edge, unless the surface cuts the cone (then such rings
/// could run along the cut, near the axis at grazing angles): then the
/// graded grid.
fn cells_for(kind: &MaterialKind, wo: DVec3, front: bool) -> Cells {
    let r = reflect(wo);
    match kind {
        MaterialKind::Lambert { .. } | MaterialKind::Plastic { .. } => {
            Cells::capped(DVec3::Z, 0.0, 1)
        }
        // Rings about the lobe, the first holding about 5% of the Phong lobe
        // (n + 1) / (2 pi) cos^n; near the surface a grid graded towards it
        // (cos^n(alpha) falls to 1/e at alpha = sqrt(2 / n))
        MaterialKind::Phong { exponent, .. } => {
            let n = *exponent as f64;
            if r.z >= 0.5 {
                Cells::graded_rings(r, 0.05 / (n + 1.0), PHONG_RINGS)
            } else {
                Cells::about_lobe(r, (2.0 / n.max(1.0)).sqrt().min(1.0))
            }
        }
        // Fine rings end at the cone's edge, tan = sin(cone angle) as on the device
        MaterialKind::Glossy { cone_angle_deg, .. } => {
            let tan = cone_angle_deg.to_radians().sin() as f64;
            let cone = tan.atan();
            if r.z > cone.sin() {
                Cells::capped(r, 1.0 / (1.0 + tan * tan).sqrt(), 1)
            } else {
                // The cone's extent in cos θ and in φ are edges: a cell
                // reaching past them by a sliver thinner than the midpoint
                // rule's spacing (at grazing, 1e-4 rad of a 0.06 rad sector)
                // would expect no sample yet receive some
                let mut cells = Cells::about_lobe(r, cone);
                let theta = r.z.clamp(-1.0, 1.0).acos();
                for c in [(theta + cone).cos(), (theta - cone).max(0.0).cos()] {
                    insert_edge(&mut cells.edges, c);
                }
                let reach = cone.sin() / theta.sin();
                if reach < 1.0 {
                    insert_edge(&mut cells.phi_edges, -reach.asin());
                    insert_edge(&mut cells.phi_edges, reach.asin());
                }
                cells
            }
        }
        // Rings about the mirror direction, the first holding a few percent
        // of the lobe (reflected directions spread about 2 alpha); near the
        // surface a grid graded towards it
        MaterialKind::RoughConductor {
            alpha_u, alpha_v, ..
        } => rough_reflection_cells(r, wo, alpha_u.min(*alpha_v) as f64),
        MaterialKind::RoughPlastic { alpha, .. } => rough_reflection_cells(r, wo, *alpha as f64),
        // Graded towards the narrowest component's lobe
        MaterialKind::Blend { components, .. } => {
            let alpha = |k: &MaterialKind| match k {
                MaterialKind::RoughConductor {
                    alpha_u, alpha_v, ..
                } => alpha_u.min(*alpha_v) as f64,
                MaterialKind::RoughPlastic { alpha, .. } => *alpha as f64,
                _ => 1.0,
            };
            let a = components.iter().map(alpha).fold(1.0, f64::min);
            rough_reflection_cells(r, wo, a)
        }
        // Graded towards the narrower of the specular lobe and the clearcoat
        MaterialKind::Principled(p) => {
            let (ax, ay) = p.alphas();
            let coat = if p.clearcoat > 0.0 {
                p.clearcoat_alpha()
            } else {
                1.0
            };
            rough_reflection_cells(r, wo, ax.min(ay).min(coat) as f64)
        }
        // Reflection above, refraction below: a grid about the normal
        // graded towards both lobes (the refracted one at Snell's direction,
        // or at the horizon past the critical angle)
        MaterialKind::RoughDielectric {
            alpha_u,
            alpha_v,
            ior,
            ..
        } => {
            let a = alpha_u.min(*alpha_v) as f64;
            let eta = if front {
                *ior as f64
            } else {
                1.0 / *ior as f64
            };
            let sin2_t = (1.0 - wo.z * wo.z) / (eta * eta);
            let t_z = -(1.0 - sin2_t).max(0.0).sqrt();
            // Refraction spreads the microfacet normals' angles by |1 - 1 / eta|
            let width = (2.0 * a).min(1.0);
            let width_t = width * (1.0 - 1.0 / eta).abs().max(0.05);
            let mut cells = Cells::about_two_lobes(r, width, t_z, width_t);
            // Entering a denser side, a refracted direction lies at or below
            // cos θ = -cos θ_o / eta (-wo / eta plus a negative multiple of
            // a normal above the surface): the density steps there, so it
            // must be an edge, or the midpoint rule spreads the step over a ring
            if eta > 1.0 {
                insert_edge(&mut cells.edges, -wo.z / eta);
            }
            if wo.z < 0.1 {
                // At grazing incidence the reflected lobe is a thin sheet in φ
                let phi_first = (a * wo.z).max(1e-5);
                if phi_first < cells.phi_edges[GRADED_STEPS + 1] {
                    cells.phi_edges = graded_edges(-PI, PI, 0.0, phi_first, GRADED_STEPS);
                }
            }
            cells
        }
        _ => unreachable!("no χ² test of a delta material"),
    }
}

/// Inserts `x` into the ascending `edges` unless it is there already or
/// outside them.
fn insert_edge(edges: &mut Vec<f64>, x: f64) {
    let at = edges.partition_point(|&e| e < x);
    if at > 0 && at < edges.len() && edges[at] != x {
        edges.insert(at, x);
    }
}

/// Rings about the mirror direction `r` of `wo`, the first holding a few
/// percent of a microfacet lobe of roughness `a` (reflected directions
/// spread about 2a); near the surface a grid graded towards it.
fn rough_reflection_cells(r: DVec3, wo: DVec3, a: f64) -> Cells {
    if r.z >= 0.5 {
        Cells::graded_rings(r, 0.2 * a * a, PHONG_RINGS)
    } else {
        // At grazing incidence the reflected lobe is a thin sheet in φ,
        // about alpha · cos θ wide: grade φ down to that
        let mut cells = Cells::about_lobe(r, (2.0 * a).min(1.0));
        let phi_first = (a * wo.z).max(1e-5);
        if phi_first < cells.phi_edges[GRADED_STEPS + 1] {
            cells.phi_edges = graded_edges(-PI, PI, 0.0, phi_first, GRADED_STEPS);
        }
        cells
    }
}

/// Pearson's χ² of observed against expected counts, the cells expecting
/// fewer than [`MIN_EXPECTED`] pooled (in ascending order of expectation,
/// until each pool expects enough; a last short pool joins the cell before
/// it). Returns χ², the cells after pooling, and the cells pooled.
fn pooled_chi2(observed: &[f64], expected: &[f64]) -> (f64, usize, usize) {
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let mut cells: Vec<(f64, f64)> = Vec::new();
    let (mut pool, mut pooled) = ((0.0, 0.0), 0);
    for i in order {
        if expected[i] < MIN_EXPECTED {
            pooled += 1;
        }
        pool = (pool.0 + observed[i], pool.1 + expected[i]);
        if pool.1 >= MIN_EXPECTED {
            cells.push(pool);
            pool = (0.0, 0.0);
        }
    }
    if pool != (0.0, 0.0) {
        match cells.last_mut() {
            Some(last) => *last = (last.0 + pool.0, last.1 + pool.1),
            None => cells.push(pool),
        }
    }
    let chi2 = cells
        .iter()
        .map(|&(o, e)| {
            if e > 0.0 {
                (o - e) * (o - e) / e
            } else {
                f64::INFINITY
            }
        })
        .sum();
    (chi2, cells.len(), pooled)
}

/// One χ² test's figures, for the table and the assertions.
struct Chi2Row {
    name: String,
    cos_theta: f64,
    /// Samples drawn.
    samples: usize,
    cells: usize,
    pooled: usize,
    chi2: f64,
    dof: usize,
    p: f64,
    /// Fraction of samples that go on.
    sampled: f64,
    /// The pdf's integral over the sphere.
    integral: f64,
    /// Samples whose pdf, weight or direction disagree with `bsdf_eval`.
    inconsistent: usize,
    first_inconsistency: Option<String>,
}

impl Chi2Row {
    fn print_header() {
        println!(
            "{:<26} {:>6} {:>8} {:>6} {:>7} {:>10} {:>5} {:>9} {:>8} {:>8}",
            "material",
            "cos",
            "samples",
            "cells",
            "pooled",
            "chi2",
            "dof",
            "p",
            "sampled",
            "int pdf"
        );
    }

    fn print(&self) {
        println!(
            "{:<26} {:>6} {:>8} {:>6} {:>7} {:>10.1} {:>5} {:>9.3e} {:>8.5} {:>8.5}",
            self.name,
            self.cos_theta,
            self.samples,
            self.cells,
            self.pooled,
            self.chi2,
            self.dof,
            self.p,
            self.sampled,
            self.integral
        );
    }

    /// Whether the pdf's integral is the fraction of samples that go on.
    fn integral_agrees(&self) -> bool {
        let p = self.integral.clamp(0.0, 1.0);
        let sigma = (p * (1.0 - p) / self.samples as f64).sqrt();
        (self.sampled - self.integral).abs() <= 5.0 * sigma + INTEGRAL_TOLERANCE
    }
}

/// Whether `a` and `b` agree to the relative tolerance [`F32_TOLERANCE`].
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= F32_TOLERANCE * a.abs().max(b.abs())
}

/// Why a sample disagrees with `bsdf_eval` at its own direction, if it does:
/// a direction the pdf calls impossible, a pdf other than `bsdf_eval`'s
/// (non-delta lobes), or a weight other than f · cos / pdf.
fn inconsistency(s: &KernelBsdfSample, delta_apart: bool) -> Option<String> {
    // A plastic's mirror sample has no density to compare
    if !s.ok || (delta_apart && s.delta) {
        return None;
    }
    let wrong = if !s.wi.is_finite() || (s.wi.length() - 1.0).abs() > F32_TOLERANCE {
        "direction not unit"
    } else if s.eval.pdf <= 0.0 || !s.eval.pdf.is_finite() {
        "sampled where the pdf is 0"
    } else if !s.delta && !close(s.pdf, s.eval.pdf) {
        "pdf differs from bsdf_eval's"
    } else if !(0..3).all(|c| close(s.weight[c] * s.eval.pdf, s.eval.f_cos[c])) {
        "weight is not f cos / pdf"
    } else {
        return None;
    };
    Some(format!("{wrong}: {s:?}"))
}

/// Samples material `sampled` for light leaving at `cos_theta`, counts
/// the samples in cells, and tests the counts against the pdf of material
/// `claimed` integrated over the cells.
fn chi2_test(renderer: &mut Renderer, sampled: u32, claimed: u32, cos_theta: f64) -> Chi2Row {
    chi2_test_at(renderer, sampled, claimed, cos_theta, 0.0)
}

/// [`chi2_test`] with wo at azimuth `phi_deg` degrees from the tangent.
fn chi2_test_at(
    renderer: &mut Renderer,
    sampled: u32,
    claimed: u32,
    cos_theta: f64,
    phi_deg: f64,
) -> Chi2Row {
    chi2_test_side(renderer, sampled, claimed, cos_theta, phi_deg, true)
}

/// [`chi2_test_at`] with wo outside (`front`) or inside the surface.
fn chi2_test_side(
    renderer: &mut Renderer,
    sampled: u32,
    claimed: u32,
    cos_theta: f64,
    phi_deg: f64,
    front: bool,
) -> Chi2Row {
    let materials = materials();
    let wo = outgoing_at(cos_theta, phi_deg);
    let cells = cells_for(&materials[claimed as usize].kind, wo, front);
    // A plastic's mirror samples, and a blend's delta component's, have no density
    let delta_apart = match &materials[sampled as usize].kind {
        MaterialKind::Plastic { .. } => true,
        MaterialKind::Blend { components, .. } => components.iter().any(|c| {
            matches!(
                c,
                MaterialKind::Plastic { .. } | MaterialKind::Conductor { .. }
            )
        }),
        _ => false,
    };
    let count = samples_for(&materials[sampled as usize].kind);
    let seed = 0x5eed_0000
        + 16 * sampled as u64
        + (cos_theta * 1000.0) as u64
        + phi_deg as u64
        + if front { 0 } else { 0x100_0000 };
    let samples = renderer
        .sample_bsdf(sampled, wo.as_vec3(), front, &uniforms(seed, count))
        .expect("sampling on the device");

    // Count the samples that go on in their cells, the others in one more
    let mut observed = vec![0.0; cells.count() + 1];
    let mut inconsistent = 0;
    let mut first_inconsistency = None;
    for s in &samples {
        // A plastic's mirror samples have no density: with the samples
        // that end, they are the mass the pdf leaves out (glossy samples
        // are flagged delta too, but have the density bsdf_eval gives)
        if s.ok && !(delta_apart && s.delta) {
            observed[cells.index(s.wi.as_dvec3())] += 1.0;
        } else {
            observed[cells.count()] += 1.0;
        }
        if let Some(why) = inconsistency(s, delta_apart) {
            inconsistent += 1;
            first_inconsistency.get_or_insert(why);
        }
    }

    // Integrate the claimed pdf over each cell; the rest is the chance of no sample
    let mut expected = vec![0.0; cells.count()];
    let mut integrate = |points: Vec<IntegrationPoint>, expected: &mut Vec<f64>| {
        let directions: Vec<Vec3> = points.iter().map(|p| p.direction).collect();
        let pdf = renderer
            .eval_bsdf(claimed, wo.as_vec3(), front, &directions)
            .expect("evaluating on the device");
        let mut zero = vec![false; expected.len()];
        let mut nonzero = vec![false; expected.len()];
        for (p, e) in points.iter().zip(&pdf) {
            expected[p.cell] += count as f64 * p.weight * e.pdf as f64;
            zero[p.cell] |= e.pdf == 0.0;
            nonzero[p.cell] |= e.pdf != 0.0;
        }
        (0..expected.len())
            .filter(|&i| zero[i] && nonzero[i])
            .collect::<Vec<usize>>()
    };
    // A rough lobe at grazing incidence is a thin sheet: finer
    let points = match materials[claimed as usize].kind {
        MaterialKind::RoughConductor { .. }
        | MaterialKind::RoughDielectric { .. }
        | MaterialKind::RoughPlastic { .. }
        | MaterialKind::Blend { .. }
        | MaterialKind::Principled(_)
            if wo.z < 0.1 =>
        {
            GRAZING_POINTS
        }
        // A rough plastic's base spreads over the hemisphere, across the
        // coarse outer rings about its glossy lobe: there the midpoint
        // rule's error (1e-5 of the integral at 16 points a side) would
        // outweigh the few samples the coating sends below the surface
        MaterialKind::RoughPlastic { .. }
        | MaterialKind::Blend { .. }
        | MaterialKind::Principled(_) => GRAZING_POINTS,
        _ => INTEGRATION_POINTS,
    };
    // A Phong lobe about the axis of its rings is convex in cos θ across a
    // ring: the midpoint rule's error there, -(n h)^2 / 24 of each row h
    // wide, left 5e-5 of the mass of n = 3000 out (and 3e-5 of n = 300).
    // Rows 4 times finer make it 16 times smaller (the lobe is constant in φ).
    let rows = match materials[claimed as usize].kind {
        MaterialKind::Phong { .. } => PHONG_ROWS_PER_POINT * points,
        _ => points,
    };
    let all = cells.integration_rows(0..cells.count(), rows, points);
    let stepped = integrate(all, &mut expected);
    // Again, finer, over the cells where the pdf steps (the glossy cone's edge)
    for &i in &stepped {
        expected[i] = 0.0;
    }
    integrate(
        cells.integration_points(stepped.into_iter(), REFINED_POINTS),
        &mut expected,
    );
    let integral = expected.iter().sum::<f64>() / count as f64;
    expected.push((count as f64 * (1.0 - integral)).max(0.0));

    let (chi2, pooled_cells, pooled) = pooled_chi2(&observed, &expected);
    let dof = pooled_cells.saturating_sub(1);
    let p = if dof == 0 {
        0.0
    } else {
        ChiSquared::new(dof as f64).expect("dof > 0").sf(chi2)
    };
    let name = if sampled == claimed {
        materials[sampled as usize].name.to_string()
    } else {
        format!(
            "{} as {}",
            materials[sampled as usize].name, materials[claimed as usize].name
        )
    };
    let name = if front {
        name
    } else {
        format!("{name} inside")
    };
    Chi2Row {
        name: if phi_deg == 0.0 {
            name
        } else {
            format!("{name} phi={phi_deg}")
        },
        cos_theta,
        samples: count,
        cells: pooled_cells,
        pooled,
        chi2,
        dof,
        p,
        sampled: 1.0 - observed[cells.count()] / count as f64,
        integral,
        inconsistent,
        first_inconsistency,
    }
}

/// Runs the χ² test of each material of `range` at each angle, prints the
/// table, and asserts every figure.
fn chi2_tests(range: std::ops::Range<u32>) {
    chi2_tests_at(&range.map(|m| (m, 0.0)).collect::<Vec<_>>());
}

/// Runs the χ² test of each `(material, azimuth of wo in degrees)` at each
/// angle, prints the table, and asserts every figure.
fn chi2_tests_at(settings: &[(u32, f64)]) {
    chi2_tests_sides(
        &settings
            .iter()
            .map(|&(m, phi)| (m, phi, true))
            .collect::<Vec<_>>(),
    );
}

/// Runs the χ² test of each `(material, azimuth of wo in degrees, wo
/// outside)` at each angle, prints the table, and asserts every figure.
fn chi2_tests_sides(settings: &[(u32, f64, bool)]) {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let level = sidak_level();
    println!(
        "family of {} tests at alpha = {ALPHA}: Šidák level {level:.4e} per test",
        family_size()
    );
    Chi2Row::print_header();
    let mut failures = Vec::new();
    for &(material, phi_deg, front) in settings {
        for cos_theta in COS_ANGLES {
            let row = chi2_test_side(&mut renderer, material, material, cos_theta, phi_deg, front);
            row.print();
            let what = format!("{} at cos {}", row.name, row.cos_theta);
            if row.p.is_nan() || row.p < level {
                failures.push(format!("{what}: p = {:.3e} < {level:.3e}", row.p));
            }
            if !row.integral_agrees() {
                failures.push(format!(
                    "{what}: the pdf integrates to {:.5}, but {:.5} of the samples go on",
                    row.integral, row.sampled
                ));
            }
            if let Some(why) = &row.first_inconsistency {
                failures.push(format!("{what}: {} samples, first {why}", row.inconsistent));
            }
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn lambert_sampling_follows_its_pdf() {
    chi2_tests(0..1);
}

#[test]
fn phong_sampling_follows_its_pdf() {
    chi2_tests(1..4);
}

#[test]
fn glossy_sampling_follows_its_pdf() {
    chi2_tests(4..CHI2_MATERIALS);
}

/// The narrowest lobes, Phong n = 3000 and a glossy cone of 5°, at every
/// angle down to grazing.
#[test]
fn narrow_lobe_sampling_follows_its_pdf() {
    chi2_tests_at(&NARROW.map(|m| (m, 0.0)));
}

/// GGX and Beckmann rough conductors, isotropic and anisotropic, from
/// nearly smooth to alpha = 1, sampled by visible normals.
#[test]
fn rough_conductor_sampling_follows_its_pdf() {
    chi2_tests_at(&rough_settings());
}

/// GGX and Beckmann rough dielectrics, isotropic and anisotropic, with wo
/// outside (ior 1.5) and inside (1 / 1.5: past the critical angle a smooth
/// surface would reflect everything), sampled by visible normals and the
/// Fresnel choice between reflection and refraction.
#[test]
fn rough_dielectric_sampling_follows_its_pdf() {
    chi2_tests_sides(&rough_dielectric_settings());
}

/// Smooth plastics: the diffuse base's samples follow its pdf (cosine
/// times the chance of choosing the base), and the coating's mirror
/// samples come at the rate the pdf leaves out.
#[test]
fn plastic_sampling_follows_its_pdf() {
    chi2_tests(PLASTIC);
}

/// Rough plastics, GGX and Beckmann, linear and not, from alpha 0.05 to
/// 0.6: the coating's visible-normal reflections and the base's cosine
/// samples, chosen by the coating's transmittance, follow the mixture pdf.
#[test]
fn rough_plastic_sampling_follows_its_pdf() {
    chi2_tests(ROUGH_PLASTIC);
}

/// Blends: the component picked by the weight, the direction weighed by the
/// mixture's f · cos over the mixture's pdf, which its samples follow.
#[test]
fn blend_sampling_follows_its_pdf() {
    chi2_tests_at(&[
        (BLEND.start, 0.0),
        (BLEND.start + 1, ANISOTROPIC_PHI_DEG[0]),
    ]);
}

/// The test has power for blends: samples at weight 0.3 against the pdf at
/// weight 0.4 are rejected.
#[test]
fn chi2_rejects_a_near_miss_of_a_blend() {
    assert_near_miss_rejected(BLEND_CONTROL);
}

/// Principled materials: the diffuse lobe's cosine samples, the clearcoat's
/// GTR1 normals and the specular lobe's visible GGX normals, chosen by the
/// lobes' probabilities, follow the mixture pdf (the anisotropic one with
/// wo turned 60° from the tangent).
#[test]
fn principled_sampling_follows_its_pdf() {
    chi2_tests_at(&[
        (PRINCIPLED.start, 0.0),
        (PRINCIPLED.start + 1, ANISOTROPIC_PHI_DEG[0]),
        (PRINCIPLED.start + 2, 0.0),
    ]);
}

/// The test has power for principled materials: samples of roughness 0.3
/// against the pdf of 0.36 are rejected.
#[test]
fn chi2_rejects_a_near_miss_of_a_principled() {
    assert_near_miss_rejected(PRINCIPLED_CONTROL);
}

/// Blends with a delta component: the other component's samples follow
/// the mixture's pdf, and the delta samples come at the rate it leaves out.
#[test]
fn blend_delta_sampling_follows_its_pdf() {
    chi2_tests(BLEND_DELTA);
}

/// A blend's delta sample is weighed as Mitsuba 3.9.1's `blendbsdf`
/// weighs it: the lobe's probability p (1 for a conductor, Mitsuba's
/// choice for a plastic's coating) mixed with the lambert's density at the
/// mirror direction, (w p W + (1 - w) kd cos / pi) / (w p + (1 - w) cos / pi)
/// for the lobe's own weight W; and it comes with probability w p.
#[test]
fn blend_delta_lobe_is_weighed_as_mitsuba_weighs_it() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let materials = materials();
    for (i, w) in BLEND_DELTA.zip(BLEND_DELTA_WEIGHTS) {
        let MaterialKind::Blend { components, .. } = &materials[i as usize].kind else {
            unreachable!("the delta blends' indices")
        };
        let w = w as f64;
        for cos_theta in [1.0, 0.5, 0.05] {
            let wo = outgoing(cos_theta);
            // The lobe's probability p and its f cos summed over the lobe, p W
            let (p, lobe): (f64, [f64; 3]) = match &components[1] {
                MaterialKind::Conductor { ior, .. } => (
                    1.0,
                    std::array::from_fn(|c| {
                        fresnel_conductor(cos_theta, ior.eta[c] as f64, ior.k[c] as f64)
                    }),
                ),
                MaterialKind::Plastic {
                    diffuse_reflectance: ColorSource::Constant(d),
                    specular_reflectance,
                    ior,
                    ..
                } => {
                    let f = fresnel(cos_theta, *ior as f64);
                    let d_mean = d.as_dvec3().element_sum() / 3.0;
                    let s_mean = specular_reflectance.as_dvec3().element_sum() / 3.0;
                    let ws = s_mean / (d_mean + s_mean);
                    (
                        f * ws / (f * ws + (1.0 - f) * (1.0 - ws)),
                        std::array::from_fn(|c| specular_reflectance[c] as f64 * f),
                    )
                }
                _ => unreachable!("the delta blends' second components"),
            };
            let density = cos_theta / PI;
            let mixed = w * p + (1.0 - w) * density;
            let count = 20_000;
            let samples = renderer
                .sample_bsdf(i, wo.as_vec3(), true, &uniforms(29 + i as u64, count))
                .expect("sampling on the device");
            let mut mirrored = 0;
            for s in samples.iter().filter(|s| s.delta) {
                mirrored += 1;
                assert!(s.ok, "cos {cos_theta}: {s:?}");
                assert!(
                    same_direction(s.wi, reflect(wo), 1e-6),
                    "cos {cos_theta}: {s:?}"
                );
                for c in 0..3 {
                    let expected =
                        (w * lobe[c] + (1.0 - w) * BLEND_LAMBERT[c] as f64 * density) / mixed;
                    let rel = (s.weight[c] as f64 - expected).abs() / expected;
                    assert!(rel < 1e-4, "cos {cos_theta}: {s:?}, expected {expected}");
                }
            }
            // The delta lobe's frequency, w p, by a binomial test
            let pv = binomial_p(mirrored, count as u64, w * p);
            println!(
                "{} cos {cos_theta}: P(delta) {:.5}, {mirrored} of {count}, p {pv:.3e}",
                materials[i as usize].name,
                w * p
            );
            assert!(
                pv > sidak_level(),
                "cos {cos_theta}: {mirrored} delta samples, p {pv:.3e}"
            );
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// Samples of material `sampled` are rejected by the χ² test against the
/// pdf of material `claimed`, at cos θ 0.5.
fn assert_near_miss_rejected((sampled, claimed): (u32, u32)) {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let level = sidak_level();
    Chi2Row::print_header();
    let row = chi2_test(&mut renderer, sampled, claimed, 0.5);
    row.print();
    assert!(
        row.p < level,
        "{}: p = {:.3e} should be below {level:.3e}",
        row.name,
        row.p
    );
}

/// The test has power for the rough plastics: samples of GGX alpha 0.3
/// against the pdf of alpha 0.36 are rejected.
#[test]
fn chi2_rejects_a_near_miss_of_a_rough_plastic() {
    assert_near_miss_rejected(ROUGH_PLASTIC_CONTROL);
}

/// A smooth plastic's coating reflects about the normal with the weight
/// specular_reflectance · F / P(mirror), where P(mirror) is Mitsuba's
/// choice F w / (F w + (1 - F)(1 - w)) and w the mean specular colour over
/// the sum of the mean colours; the exact Fresnel term of the f64 reference.
#[test]
fn plastic_coating_reflects_by_its_fresnel_term() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let materials = materials();
    for i in PLASTIC {
        let MaterialKind::Plastic {
            diffuse_reflectance,
            specular_reflectance,
            ior,
            ..
        } = &materials[i as usize].kind
        else {
            unreachable!("the plastics' indices")
        };
        let ColorSource::Constant(d) = diffuse_reflectance else {
            unreachable!("the plastics' colours")
        };
        let d_mean = d.as_dvec3().element_sum() / 3.0;
        let s_mean = specular_reflectance.as_dvec3().element_sum() / 3.0;
        let w = s_mean / (d_mean + s_mean);
        for cos_theta in [1.0, 0.8, 0.5, 0.2, 0.05, 0.001] {
            let wo = outgoing(cos_theta);
            let f = fresnel(cos_theta, *ior as f64);
            let p = f * w / (f * w + (1.0 - f) * (1.0 - w));
            let samples = renderer
                .sample_bsdf(i, wo.as_vec3(), true, &uniforms(11 + i as u64, 20_000))
                .expect("sampling on the device");
            let mut mirrored = 0;
            for s in samples.iter().filter(|s| s.delta) {
                mirrored += 1;
                assert!(s.ok && s.pdf == 0.0, "cos {cos_theta}: {s:?}");
                assert!(
                    same_direction(s.wi, reflect(wo), 1e-6),
                    "cos {cos_theta}: {s:?}"
                );
                for c in 0..3 {
                    let expected = specular_reflectance[c] as f64 * f / p;
                    let rel = (s.weight[c] as f64 - expected).abs() / expected;
                    assert!(rel < 1e-4, "cos {cos_theta}: {s:?}, expected {expected}");
                }
            }
            println!(
                "{} cos {cos_theta}: P(mirror) {p:.5}, {mirrored} of 20000 mirrored",
                materials[i as usize].name
            );
            assert!(
                mirrored > 0 || p < 1e-3,
                "cos {cos_theta}: no mirror sample"
            );
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// The test has power for the rough dielectrics: GGX alpha 0.3 against
/// 0.34, and ior 1.5 against 1.6 (which moves the refracted lobe and the
/// share of reflection), from both sides, are rejected.
#[test]
fn chi2_rejects_a_near_miss_of_a_rough_dielectric() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let level = sidak_level();
    Chi2Row::print_header();
    for (sampled, claimed) in ROUGH_DIELECTRIC_CONTROLS {
        for front in [true, false] {
            let row = chi2_test_side(&mut renderer, sampled, claimed, 0.5, 0.0, front);
            row.print();
            assert!(
                row.p < level,
                "{}: p = {:.3e} should be below {level:.3e}",
                row.name,
                row.p
            );
        }
    }
}

/// The test has power: samples of one material against the pdf of a near
/// neighbour (Phong exponent 20 against 24, a glossy cone of 30° against
/// 33°, GGX alpha 0.3 against 0.34, Beckmann against GGX at alpha 0.3)
/// are rejected at the same level.
#[test]
fn chi2_rejects_a_near_miss() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let level = sidak_level();
    Chi2Row::print_header();
    for (sampled, claimed) in CONTROLS {
        let row = chi2_test(&mut renderer, sampled, claimed, 0.5);
        row.print();
        assert!(
            row.p < level,
            "{}: p = {:.3e} should be below {level:.3e}",
            row.name,
            row.p
        );
    }
}

#[test]
fn pooling_keeps_every_count() {
    // Five cells expect 1 each (pooled into one), two expect 10
    let observed = [2.0, 0.0, 1.0, 1.0, 0.0, 12.0, 9.0];
    let expected = [1.0, 1.0, 1.0, 1.0, 1.0, 10.0, 10.0];
    let (chi2, cells, pooled) = pooled_chi2(&observed, &expected);
    assert_eq!((cells, pooled), (3, 5));
    assert!((chi2 - (1.0 / 5.0 + 4.0 / 10.0 + 1.0 / 10.0)).abs() < 1e-12);
    // A short last pool joins the cell before it
    let (chi2, cells, pooled) = pooled_chi2(&[2.0, 4.0, 6.0], &[3.0, 3.0, 4.0]);
    assert_eq!((cells, pooled), (1, 3));
    assert!((chi2 - 4.0 / 10.0).abs() < 1e-12);
}

/// `eta_t / eta_i` seen from the side wo lies on.
fn eta(front: bool) -> f64 {
    if front {
        IOR as f64
    } else {
        1.0 / IOR as f64
    }
}

#[test]
fn fresnel_reference_has_the_textbook_values() {
    // Normal incidence: ((n - 1) / (n + 1))^2, from either side
    assert!((fresnel(1.0, 1.5) - 0.04).abs() < 1e-15);
    assert!((fresnel(1.0, 1.0 / 1.5) - 0.04).abs() < 1e-15);
    // Brewster's angle, tan = n: no p-polarised reflection
    let brewster = 1.5f64.atan().cos();
    let cos_t = (1.0 - (1.0 - brewster * brewster) / 2.25).sqrt();
    let r_s = (brewster - 1.5 * cos_t) / (brewster + 1.5 * cos_t);
    assert!((fresnel(brewster, 1.5) - 0.5 * r_s * r_s).abs() < 1e-15);
    // Total internal reflection past the critical angle, none before
    let critical = (1.0 - 1.0 / 2.25f64).sqrt();
    assert_eq!(fresnel(critical - 1e-9, 1.0 / 1.5), 1.0);
    assert!(fresnel(critical + 1e-6, 1.0 / 1.5) < 1.0);
}

/// Two-sided binomial p-value of `k` successes in `n` trials of chance `p`.
fn binomial_p(k: u64, n: u64, p: f64) -> f64 {
    let b = Binomial::new(p, n).expect("binomial");
    let below = b.cdf(k);
    let above = if k == 0 { 1.0 } else { b.sf(k - 1) };
    (2.0 * below.min(above)).min(1.0)
}

/// Whether `a` and `b` are the same direction to `tolerance` per component.
fn same_direction(a: Vec3, b: DVec3, tolerance: f64) -> bool {
    (a.as_dvec3() - b).abs().max_element() <= tolerance
}

#[test]
fn dielectric_follows_snell_and_fresnel() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let level = sidak_level();
    let tint = Vec3::from(TINT);
    println!(
        "{:<6} {:>6} {:>8} {:>10} {:>10} {:>9}",
        "side", "cos", "samples", "F", "reflected", "p"
    );
    let mut failures = Vec::new();
    for (i, (front, cos_theta)) in DIELECTRIC_SETTINGS.into_iter().enumerate() {
        let eta = eta(front);
        let wo = outgoing(cos_theta);
        let f = fresnel(cos_theta, eta);
        // Snell: the tangential part scales by 1 / eta, the rest goes down
        let sin2_t = (1.0 - cos_theta * cos_theta) / (eta * eta);
        let refracted = DVec3::new(-wo.x / eta, 0.0, -(1.0 - sin2_t).max(0.0).sqrt());
        let samples = renderer
            .sample_bsdf(
                DIELECTRIC,
                wo.as_vec3(),
                front,
                &uniforms(0xd1e1 + i as u64, DELTA_SAMPLES),
            )
            .expect("sampling on the device");
        let what = format!(
            "{} at cos {cos_theta}",
            if front { "outside" } else { "inside" }
        );
        let mut reflected = 0u64;
        let mut wrong = Vec::new();
        for s in &samples {
            let ok = s.ok && s.delta && s.pdf == 0.0;
            let right = if s.wi.z > 0.0 {
                reflected += 1;
                same_direction(s.wi, reflect(wo), 1e-6) && s.weight == Vec3::ONE
            } else {
                let weight = tint / (eta * eta) as f32;
                same_direction(s.wi, refracted, 1e-5)
                    && (0..3).all(|c| close(s.weight[c], weight[c]))
            };
            if !(ok && right) {
                wrong.push(*s);
            }
        }
        let n = DELTA_SAMPLES as u64;
        let p = if f < 1.0 {
            binomial_p(reflected, n, f)
        } else {
            f64::from(reflected == n)
        };
        println!(
            "{:<6} {:>6} {:>8} {:>10.6} {:>10.6} {:>9.3e}",
            if front { "out" } else { "in" },
            cos_theta,
            n,
            f,
            reflected as f64 / n as f64,
            p
        );
        if f == 1.0 && reflected != n {
            failures.push(format!(
                "{what}: total internal reflection, yet {} of {n} samples refract",
                n - reflected
            ));
        } else if p < level {
            failures.push(format!(
                "{what}: {reflected} of {n} reflect, Fresnel says {f:.6}: p = {p:.3e} < {level:.3e}"
            ));
        }
        if let Some(first) = wrong.first() {
            failures.push(format!(
                "{what}: {} samples with a wrong direction, weight or flag, first {first:?}",
                wrong.len()
            ));
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn mirror_reflects_exactly() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let reflectance = Vec3::new(0.9, 0.8, 0.7);
    for (i, cos_theta) in COS_ANGLES.into_iter().enumerate() {
        for front in [true, false] {
            let wo = outgoing(cos_theta);
            let samples = renderer
                .sample_bsdf(MIRROR, wo.as_vec3(), front, &uniforms(i as u64, 1000))
                .expect("sampling on the device");
            for s in &samples {
                assert!(
                    s.ok && s.delta && s.pdf == 0.0 && s.weight == reflectance,
                    "cos {cos_theta}: {s:?}"
                );
                assert!(
                    same_direction(s.wi, reflect(wo), 1e-6),
                    "cos {cos_theta}: {:?} is not the mirror direction of {wo}",
                    s.wi
                );
                // A delta lobe has no density to evaluate
                assert_eq!((s.eval.f_cos, s.eval.pdf), (Vec3::ZERO, 0.0), "{s:?}");
            }
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

#[test]
fn conductor_fresnel_reference_has_the_textbook_values() {
    // Normal incidence: ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2)
    let (eta, k) = (0.2, 3.9);
    let normal = ((eta - 1.0) * (eta - 1.0) + k * k) / ((eta + 1.0) * (eta + 1.0) + k * k);
    assert!((fresnel_conductor(1.0, eta, k) - normal).abs() < 1e-14);
    // k = 0 is a dielectric; eta 0, k 1 reflects everything
    for c in [1.0, 0.7, 0.2, 0.01] {
        assert!((fresnel_conductor(c, 1.5, 0.0) - fresnel(c, 1.5)).abs() < 1e-14);
        assert!((fresnel_conductor(c, 0.0, 1.0) - 1.0).abs() < 1e-14);
    }
    // Grazing incidence reflects everything
    assert!((fresnel_conductor(1e-9, eta, k) - 1.0).abs() < 1e-6);
}

/// The smooth conductor reflects about the normal, by the conductor's
/// Fresnel term of Mitsuba's gold preset times its specular reflectance,
/// per channel, at every angle; the perfect reflector (material `none`)
/// returns exactly its specular reflectance.
#[test]
fn conductor_reflects_by_its_fresnel_term() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let MaterialKind::Conductor {
        ior,
        specular_reflectance,
    } = materials()[CONDUCTOR as usize].kind
    else {
        unreachable!("the conductor's index")
    };
    for cos_theta in [1.0, 0.8, 0.5, 0.2, 0.05, 0.001] {
        let wo = outgoing(cos_theta);
        let samples = renderer
            .sample_bsdf(CONDUCTOR, wo.as_vec3(), true, &uniforms(7, 100))
            .expect("sampling on the device");
        let expected: Vec<f64> = (0..3)
            .map(|c| {
                specular_reflectance[c] as f64
                    * fresnel_conductor(cos_theta, ior.eta[c] as f64, ior.k[c] as f64)
            })
            .collect();
        for s in &samples {
            assert!(s.ok && s.delta && s.pdf == 0.0, "cos {cos_theta}: {s:?}");
            assert!(
                same_direction(s.wi, reflect(wo), 1e-6),
                "cos {cos_theta}: {s:?}"
            );
            for c in 0..3 {
                let rel = (s.weight[c] as f64 - expected[c]).abs() / expected[c];
                assert!(
                    rel < 2e-5,
                    "cos {cos_theta}, channel {c}: {s:?}, expected {expected:?}"
                );
            }
            assert_eq!((s.eval.f_cos, s.eval.pdf), (Vec3::ZERO, 0.0), "{s:?}");
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// Cosine samples at the edges of the unit square, where the concentric
/// disc reaches radius 1 and the direction would lie in the tangent plane,
/// still go on with the exact Lambert weight: a white furnace loses no
/// sample there (one in 2^24 per dimension, a few per 8K frame).
#[test]
fn cosine_samples_at_the_disc_rim_go_on_with_the_albedo() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let below_one = 1.0 - f32::EPSILON / 2.0;
    let rim: Vec<Vec3> = [
        (0.0, 0.5),
        (0.5, 0.0),
        (0.0, 0.0),
        (below_one, 0.5),
        (0.5, below_one),
    ]
    .into_iter()
    .flat_map(|(x, y)| [Vec3::new(x, y, 0.5), Vec3::new(y, x, 0.5)])
    .collect();
    let albedo = Vec3::new(0.8, 0.6, 0.4);
    for cos_theta in COS_ANGLES {
        let samples = renderer
            .sample_bsdf(0, outgoing(cos_theta).as_vec3(), true, &rim)
            .expect("sampling on the device");
        for (u, s) in rim.iter().zip(&samples) {
            assert!(s.ok && !s.delta && s.pdf > 0.0, "u {u}: {s:?}");
            assert!(
                (s.weight - albedo).abs().max_element() < 1e-5,
                "u {u}: {s:?}"
            );
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// Cosine samples near the disc's rim keep the height of the exact
/// concentric map, sqrt(1 - r^2) for the f32 radius r of the square's
/// point, to 1e-5: 1 - dot(d, d) cancelled there to a few ulps of 1, up
/// to half of the height for u one ulp from the square's edge.
#[test]
fn cosine_samples_near_the_disc_rim_keep_their_height() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let step = f32::EPSILON / 2.0;
    let near: Vec<Vec3> = (1..=64)
        .flat_map(|k| {
            let (low, high) = (k as f32 * step, 1.0 - k as f32 * step);
            let across = (k as f32 * 0.0137).fract();
            [(low, across), (high, across), (across, low), (across, high)]
        })
        .map(|(x, y)| Vec3::new(x, y, 0.5))
        .collect();
    let samples = renderer
        .sample_bsdf(0, outgoing(1.0).as_vec3(), true, &near)
        .expect("sampling on the device");
    let mut worst = (0.0f64, Vec3::ZERO);
    for (u, s) in near.iter().zip(&samples) {
        assert!(s.ok, "u {u}: {s:?}");
        let o = (2.0 * u.truncate().as_dvec2()) - 1.0;
        let r = o.x.abs().max(o.y.abs());
        let exact = ((1.0 - r) * (1.0 + r)).sqrt();
        let rel = (s.wi.z as f64 / exact - 1.0).abs();
        if rel > worst.0 {
            worst = (rel, *u);
        }
    }
    println!(
        "worst relative error of the height {:.2e} at u {}",
        worst.0, worst.1
    );
    assert!(
        worst.0 < 1e-5,
        "the height is off by {:.2e} at u {}",
        worst.0,
        worst.1
    );
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// Width and height of the environment map the light-sampling tests use.
const ENVMAP_SIZE: (u32, u32) = (24, 13);
/// Rings of cells (equal steps of cos θ) over the sphere for the
/// environment map's χ² test; each is cut into [`SECTORS`] sectors.
const ENVMAP_RINGS: usize = 40;
/// Midpoint-rule points per side of a cell for the environment map, whose
/// pdf steps at the edges of its own cells.
const ENVMAP_POINTS: usize = 32;

/// Writes the test environment map (linear RGB EXR) at `path`: a sky
/// brightening towards the top row, a black band four columns wide (no
/// sample may land there), and a sun of radiance 400 around texel (15, 3).
fn write_test_envmap(path: &std::path::Path) {
    let (w, h) = ENVMAP_SIZE;
    let img = image::Rgb32FImage::from_fn(w, h, |x, y| {
        let up = 1.0 - y as f32 / (h - 1) as f32;
        let mut c = [0.2 + 0.8 * up, 0.3 + 0.5 * up, 0.5 + 0.7 * up];
        if x < 4 {
            c = [0.0; 3];
        }
        if (x, y) == (15, 3) {
            c = [400.0, 380.0, 300.0];
        } else if x.abs_diff(15) <= 1 && y.abs_diff(3) <= 1 {
            c = [20.0, 18.0, 12.0];
        }
        image::Rgb(c)
    });
    img.save(path).expect("writing the test environment map");
}

/// The furnace's sphere under the test environment map, turned by
/// `angle` radians about an oblique axis, as the only light; the map is
/// written to a scratch folder named `tag`.
fn envmap_scene(tag: &str, angle: f32) -> Scene {
    let path = scratch(tag).join("envmap.exr");
    write_test_envmap(&path);
    let mut scene = load("tests/scenes/furnace.toml");
    scene.environment = Vec3::ZERO;
    let to_world = glam::Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), angle);
    scene.envmap = Some(lancer::scene::EnvMap {
        file: path,
        scale: 1.5,
        to_local: to_world.transpose(),
    });
    scene
}

/// Samples the environment map with the shade kernel's `sample_light` from
/// the renderer of `sampled`, counts the directions in cells of the sphere,
/// and tests the counts against the pdf the renderer of `claimed` gives
/// (`envmap_pdf`) integrated over each cell. Returns the row and how many
/// samples `sample_light` refused.
fn envmap_chi2(sampled: &mut Renderer, claimed: &mut Renderer, name: &str) -> (Chi2Row, usize) {
    let cells = Cells::new(
        DVec3::new(0.3, -0.5, 0.8).normalize(),
        None,
        uniform_edges(-1.0, 1.0, ENVMAP_RINGS),
        uniform_edges(-PI, PI, SECTORS),
    );
    let samples = sampled
        .sample_lights(
            Vec3::new(0.2, 0.1, -0.3),
            &uniform_pairs(0x5eed_e4a9, SAMPLES),
        )
        .expect("sampling on the device");
    let mut observed = vec![0.0; cells.count() + 1];
    let mut refused = 0;
    for s in &samples {
        if !s.ok {
            refused += 1;
            observed[cells.count()] += 1.0;
            continue;
        }
        observed[cells.index(s.wi.as_dvec3())] += 1.0;
    }
    let points = cells.integration_points(0..cells.count(), ENVMAP_POINTS);
    let directions: Vec<Vec3> = points.iter().map(|p| p.direction).collect();
    let pdf = claimed
        .eval_envmap(&directions)
        .expect("evaluating on the device");
    let mut expected = vec![0.0; cells.count()];
    for (p, e) in points.iter().zip(&pdf) {
        expected[p.cell] += SAMPLES as f64 * p.weight * e.env_pdf as f64;
    }
    let integral = expected.iter().sum::<f64>() / SAMPLES as f64;
    expected.push((SAMPLES as f64 * (1.0 - integral)).max(0.0));
    if std::env::var("CHI2_DEBUG").is_ok() {
        let mut worst: Vec<usize> = (0..cells.count()).filter(|&i| expected[i] > 5.0).collect();
        worst.sort_by(|&a, &b| {
            let r = |i: usize| (observed[i] - expected[i]).powi(2) / expected[i];
            r(b).total_cmp(&r(a))
        });
        for &i in worst.iter().take(12) {
            let (ring, sector) = (i / cells.sectors(), i % cells.sectors());
            eprintln!(
                "cell ring {ring} [{:.7}, {:.7}] sector {sector} [{:.5}, {:.5}]: observed {} expected {:.1}",
                cells.edges[ring], cells.edges[ring + 1], cells.phi_edges[sector], cells.phi_edges[sector + 1],
                observed[i], expected[i]
            );
        }
        let zero_obs: f64 = (0..cells.count())
            .filter(|&i| expected[i] == 0.0)
            .map(|i| observed[i])
            .sum();
        let small: Vec<usize> = (0..cells.count()).filter(|&i| expected[i] < 5.0).collect();
        let so: f64 = small.iter().map(|&i| observed[i]).sum();
        let se: f64 = small.iter().map(|&i| expected[i]).sum();
        eprintln!("observed where expected 0: {zero_obs}; small cells: observed {so} expected {se:.1}; none cell: o {} e {:.1}", observed[cells.count()], SAMPLES as f64 * (1.0 - expected.iter().sum::<f64>() / SAMPLES as f64));
        let mut byc: Vec<usize> = small.clone();
        byc.sort_by(|&a, &b| (observed[b] - expected[b]).total_cmp(&(observed[a] - expected[a])));
        for &i in byc.iter().take(8) {
            let (ring, sector) = (i / cells.sectors(), i % cells.sectors());
            eprintln!("  small cell ring {ring} [{:.7}, {:.7}] sector {sector} [{:.5}, {:.5}]: observed {} expected {:.2}", cells.edges[ring], cells.edges[ring + 1], cells.phi_edges[sector], cells.phi_edges[sector + 1], observed[i], expected[i]);
        }
        // Per ring sums
        for ring in 0..cells.rings() {
            let o: f64 = (0..cells.sectors())
                .map(|j| observed[ring * cells.sectors() + j])
                .sum();
            let e: f64 = (0..cells.sectors())
                .map(|j| expected[ring * cells.sectors() + j])
                .sum();
            if e > 0.0 {
                eprintln!(
                    "ring {ring} [{:.7}, {:.7}]: o {o} e {e:.1} z {:.2}",
                    cells.edges[ring],
                    cells.edges[ring + 1],
                    (o - e) / e.sqrt()
                );
            }
        }
    }
    let (chi2, pooled_cells, pooled) = pooled_chi2(&observed, &expected);
    let dof = pooled_cells.saturating_sub(1);
    let p = ChiSquared::new(dof.max(1) as f64)
        .expect("dof > 0")
        .sf(chi2);
    let row = Chi2Row {
        name: name.to_string(),
        cos_theta: 0.0,
        samples: SAMPLES,
        cells: pooled_cells,
        pooled,
        chi2,
        dof,
        p,
        sampled: 1.0 - observed[cells.count()] / SAMPLES as f64,
        integral,
        inconsistent: 0,
        first_inconsistency: None,
    };
    (row, refused)
}

/// Next-event estimation samples the environment map by its piecewise
/// constant distribution, and the directions follow the pdf an escaped
/// path's MIS weight uses (`envmap_pdf`), through a rotated `to_world`, a
/// black band and a sun: a χ² test over 1600 cells of the sphere. The pdf
/// integrates to 1, and no sample lands where the map is black.
#[test]
fn envmap_sampling_follows_its_pdf() {
    let ctx = context();
    let scene = envmap_scene("chi2_envmap", 0.7);
    let mut renderer = Renderer::new(&ctx, &scene, &options(1 << 18)).expect("renderer");
    let mut same = Renderer::new(&ctx, &scene, &options(1 << 18)).expect("renderer");
    let (row, refused) = envmap_chi2(&mut renderer, &mut same, "envmap");
    Chi2Row::print_header();
    row.print();
    assert_eq!(refused, 0, "sample_light refused samples");
    assert!(row.p >= ALPHA, "envmap: p = {:.3e} < {ALPHA}", row.p);
    assert!(
        (row.integral - 1.0).abs() < INTEGRAL_TOLERANCE,
        "the pdf integrates to {}",
        row.integral
    );

    // No sample comes from the black band: its directions have radiance 0
    let black = renderer
        .sample_lights(Vec3::ZERO, &uniform_pairs(0x5eed_b1ac, 100_000))
        .expect("sampling on the device")
        .iter()
        .filter(|s| s.le.max_element() <= 0.0)
        .count();
    assert_eq!(black, 0, "samples of zero radiance");
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// The environment map's χ² test has power: its samples against the pdf
/// of the same map turned 1° further are rejected.
#[test]
fn envmap_chi2_rejects_a_turned_map() {
    let ctx = context();
    let scene = envmap_scene("chi2_envmap_control", 0.7);
    let mut renderer = Renderer::new(&ctx, &scene, &options(1 << 18)).expect("renderer");
    let turned = envmap_scene("chi2_envmap_turned", 0.7 + 1f32.to_radians());
    let mut other = Renderer::new(&ctx, &turned, &options(1 << 18)).expect("renderer");
    let (row, _) = envmap_chi2(&mut renderer, &mut other, "envmap as turned 1 deg");
    Chi2Row::print_header();
    row.print();
    assert!(
        row.p < 1e-6,
        "a map turned 1 degree passed: p = {:.3e}",
        row.p
    );
}

/// Index of the Phong material of exponent 3000 in [`materials`].
const PHONG_3000: u32 = NARROW[0];

/// The mirror direction about +z, the Phong exponent and the chance of
/// its diffuse lobe for material `index` of [`materials`].
fn phong_of(index: u32) -> (f64, f64) {
    let MaterialKind::Phong {
        diffuse: lancer::scene::ColorSource::Constant(kd),
        specular,
        exponent,
    } = materials()[index as usize].kind
    else {
        unreachable!("a phong material")
    };
    let (d, s) = (
        kd.as_dvec3().element_sum(),
        specular.as_dvec3().element_sum(),
    );
    (exponent as f64, d / (d + s))
}

/// `bsdf_eval`'s pdf of Phong n = 3000 is the f64 formula pd cos / π +
/// (1 - pd) (n + 1) / 2π cos^n to 2e-6 from the peak to 0.01 off it in
/// 1 - cos: pow(dot(r, wi), n) in f32 was off by up to 3e-4 there (an ulp
/// of cos near 1 is n · 6e-8 of cos^n), low on average, so that the pdf
/// integrated to 0.9999 and the χ² of the narrow lobe failed.
#[test]
fn phong_pdf_is_exact_near_a_narrow_peak() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let (n, pd) = phong_of(PHONG_3000);
    for cos_theta in [1.0, 0.5] {
        let wo = outgoing(cos_theta);
        let (t, b) = reflect(wo).any_orthonormal_pair();
        let directions: Vec<Vec3> = (0..1400)
            .map(|i| {
                let y = 1e-7 * 1.005f64.powi(i);
                let (c, s) = (1.0 - y, (y * (2.0 - y)).sqrt());
                let phi = 0.37 * i as f64;
                (s * (phi.cos() * t + phi.sin() * b) + c * reflect(wo)).as_vec3()
            })
            .collect();
        let evals = renderer
            .eval_bsdf(PHONG_3000, wo.as_vec3(), true, &directions)
            .expect("evaluating on the device");
        let mut worst = (0.0f64, 0.0f64);
        for (d, e) in directions.iter().zip(&evals) {
            // The exact pdf at the f32 direction the device was given
            let d = d.as_dvec3().normalize();
            let r = reflect(wo);
            let y = d.cross(r).length_squared() / (1.0 + d.dot(r));
            let exact = pd * d.z / PI + (1.0 - pd) * (n + 1.0) / TAU * (n * (-y).ln_1p()).exp();
            let rel = (e.pdf as f64 / exact - 1.0).abs();
            if rel > worst.0 {
                worst = (rel, y);
            }
        }
        println!(
            "cos {cos_theta}: worst relative error {:.2e} at 1 - cos {:.3e}",
            worst.0, worst.1
        );
        assert!(
            worst.0 < 2e-6,
            "cos {cos_theta}: the pdf is off by {:.2e} at 1 - cos = {:.3e}",
            worst.0,
            worst.1
        );
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// Phong n = 3000 samples its lobe at the angle u^(1 / (n + 1)) gives in
/// f64, to 1e-4 of 1 - cos from 1e-6 off the peak: exp(log(u) / (n + 1))
/// in f32 rounded cos to its ulps near 1 (6e-8, 6% of 1 - cos there).
#[test]
fn phong_samples_keep_their_angle_near_a_narrow_peak() {
    let ctx = context();
    let mut renderer = Renderer::new(&ctx, &scene(), &options(1 << 18)).expect("renderer");
    let (n, pd) = phong_of(PHONG_3000);
    let wo = outgoing(0.5);
    let r = reflect(wo);
    // u.z past pd picks the lobe; u.x from 1 - 2^-24 down to 0.001
    let lobe = (pd as f32 + 1.0) / 2.0;
    let us: Vec<Vec3> = (0..1400)
        .map(|i| 1.0 - (1e-3f64.ln() * i as f64 / 1400.0).exp().max(1.0 - 0.999))
        .map(|one_minus_u| (1.0 - one_minus_u) as f32)
        .chain((1..=64).map(|k| 1.0 - k as f32 * f32::EPSILON / 2.0))
        .enumerate()
        .map(|(i, x)| Vec3::new(x, (i as f32 * 0.618).fract(), lobe))
        .collect();
    let samples = renderer
        .sample_bsdf(PHONG_3000, wo.as_vec3(), true, &us)
        .expect("sampling on the device");
    let mut worst = (0.0f64, 0.0f64);
    for (u, s) in us.iter().zip(&samples) {
        assert!(s.ok, "u {u}: {s:?}");
        let exact = -((u.x as f64).ln() / (n + 1.0)).exp_m1();
        if exact < 1e-6 {
            continue;
        }
        let d = s.wi.as_dvec3().normalize();
        let y = d.cross(r).length_squared() / (1.0 + d.dot(r));
        let rel = (y / exact - 1.0).abs();
        if rel > worst.0 {
            worst = (rel, exact);
        }
    }
    println!(
        "worst relative error of 1 - cos {:.2e} at {:.3e}",
        worst.0, worst.1
    );
    assert!(
        worst.0 < 1e-4,
        "1 - cos is off by {:.2e} at {:.3e}",
        worst.0,
        worst.1
    );
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}
