//! Plain CPU scene types: what a scene file says, after validation.
//!
//! These are kept apart from the packed `Gpu*` structs in `crate::gpu`; the
//! one conversion between them lives in `crate::gpu::pack`.

use glam::Vec3;
use std::path::{Path, PathBuf};

/// A linear RGB colour.
pub type Rgb = Vec3;

/// `[render]`: image size, sampling and the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels (>= 1).
    pub width: u32,
    /// Image height in pixels (>= 1).
    pub height: u32,
    /// Samples per pixel (>= 1).
    pub spp: u32,
    /// Longest path in segments from the camera (>= 1).
    pub max_depth: u32,
    /// Seed of every random number.
    pub seed: u32,
    /// Camera rays pass through area emitters and see no environment
    /// (Mitsuba's `hide_emitters`); false in TOML scenes.
    pub hide_emitters: bool,
    /// Light is found by emitter sampling alone, with MIS weight 1, and
    /// paths end after it (Mitsuba's `direct` with `bsdf_samples` 0; needs
    /// `max_depth` 2); false in TOML scenes.
    pub emitter_sampling_only: bool,
    /// Light is found by BSDF sampling alone (Mitsuba's `direct` with
    /// `emitter_samples` 0): the scene renders with the BSDF-sampling
    /// estimator whatever the render options ask, so point, spot and
    /// directional lights add nothing, as in Mitsuba; false in TOML scenes.
    pub bsdf_sampling_only: bool,
    /// How many times each delta light's sample counts: 1, but for
    /// Mitsuba's `direct` integrator, which weighs each of its
    /// `emitter_samples` samples of a delta light by 1 rather than by 1 /
    /// `emitter_samples` (`src/integrators/direct.cpp`), so its point, spot
    /// and directional lights come out `emitter_samples` times brighter;
    /// lancer reproduces that to render what Mitsuba renders.
    pub delta_light_gain: u32,
    /// The pixel reconstruction filter (`render.filter`; box by default).
    pub filter: PixelFilter,
    /// Film positions stay inside the image, as Mitsuba's film with
    /// `sample_border` false (its default) keeps its samples: a pixel
    /// within the filter's radius of the edge sees the filter cut at the
    /// edge and renormalised, `∫_film f L / ∫_film f` (see
    /// `crate::scene::filter`). Set only where that changes something: an
    /// XML scene whose filter reaches past its pixel; false in TOML scenes,
    /// whose filters look past the edge (as with `sample_border` true).
    pub filter_inside_film: bool,
    /// Russian roulette may end a path at the hit that ends segment
    /// `rr_depth` and at every later hit (the camera ray is segment 1), as
    /// Mitsuba's `rr_depth` counts (`render.rr_depth`, >= 1;
    /// [`DEFAULT_RR_DEPTH`] in TOML scenes, Mitsuba's default 5 in its XML).
    /// It changes the noise, never the expected image.
    pub rr_depth: u32,
}

/// `render.rr_depth` of a TOML scene that does not state it: the start that
/// reached a given error soonest in lancer's measurements (see
/// `docs/accuracy.md`, *Russian roulette*).
pub const DEFAULT_RR_DEPTH: u32 = 5;

/// Mitsuba's default `rr_depth` (`src/integrators/path.cpp`), for its XML.
pub const MITSUBA_RR_DEPTH: u32 = 5;

/// A pixel reconstruction filter, as Mitsuba 3 defines its `rfilter`
/// plugins: separable, `f(x) f(y)`, with `x` and `y` the offset in pixels
/// from the pixel's centre. lancer samples each path's film position from
/// the filter (filter importance sampling; see `crate::scene::filter`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PixelFilter {
    /// `box`: 1 on [-0.5, 0.5), the pixel itself (lancer's default).
    Box,
    /// `tent`: `max(0, 1 - |x| / radius)`.
    Tent {
        /// Half width in pixels (Mitsuba's default 1).
        radius: f32,
    },
    /// `gaussian`: `max(0, exp(-x^2 / (2 stddev^2)) - exp(-r^2 / (2 stddev^2)))`
    /// with radius `r = 4 stddev` (Mitsuba's default filter).
    Gaussian {
        /// Standard deviation in pixels (Mitsuba's default 0.5).
        stddev: f32,
    },
    /// `mitchell`: the Mitchell-Netravali cubic of radius 2 (`catmullrom`
    /// is B = 0, C = 0.5).
    Mitchell {
        /// Mitchell and Netravali's B (Mitsuba's default 1/3).
        b: f32,
        /// Mitchell and Netravali's C (Mitsuba's default 1/3).
        c: f32,
    },
    /// `lanczos`: the windowed sinc `sinc(x) sinc(x / lobes)` of radius `lobes`.
    Lanczos {
        /// Side lobes, the radius in pixels (Mitsuba's default 3).
        lobes: u32,
    },
}

/// Render settings given outside the scene file (by the command line, or a
/// program) that replace the file's own before anything is checked or
/// derived from them: [`crate::scene::load_with`] applies them, then checks
/// the settings once ([`RenderSettings::check`]). A Mitsuba sensor's field
/// of view follows the overridden image size, as it does in Mitsuba.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RenderOverrides {
    /// Replaces `render.width`.
    pub width: Option<u32>,
    /// Replaces `render.height`.
    pub height: Option<u32>,
    /// Replaces `render.spp`.
    pub spp: Option<u32>,
    /// Replaces `render.max_depth`.
    pub max_depth: Option<u32>,
    /// Replaces `render.seed`.
    pub seed: Option<u32>,
}

impl RenderOverrides {
    /// Writes the overridden values into `render`.
    pub fn apply(&self, render: &mut RenderSettings) {
        for (value, field) in [
            (self.width, &mut render.width),
            (self.height, &mut render.height),
            (self.spp, &mut render.spp),
            (self.max_depth, &mut render.max_depth),
            (self.seed, &mut render.seed),
        ] {
            if let Some(v) = value {
                *field = v;
            }
        }
    }

    /// Whether the setting `key` of `[render]` (`"width"`, `"spp"`, ...) is
    /// overridden, so that a message about it points at no line of the file.
    pub fn sets(&self, key: &str) -> bool {
        match key {
            "width" => self.width.is_some(),
            "height" => self.height.is_some(),
            "spp" => self.spp.is_some(),
            "max_depth" => self.max_depth.is_some(),
            "seed" => self.seed.is_some(),
            _ => false,
        }
    }
}

/// `[camera]`: a pinhole or thin-lens camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Position of the eye.
    pub eye: Vec3,
    /// Point the camera looks at.
    pub look_at: Vec3,
    /// Up direction (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in degrees, 0 < vfov < 180.
    pub vfov_deg: f32,
    /// Thin-lens radius; 0 is a pinhole.
    pub aperture_radius: f32,
    /// Distance from the eye to the plane in focus.
    pub focus_distance: f32,
    /// Near clip plane: camera rays start this far from the eye along the
    /// optical axis (Mitsuba's `near_clip`); 0 is none.
    pub near_clip: f32,
    /// Far clip plane: camera rays end this far from the eye along the
    /// optical axis and see the environment beyond it (Mitsuba's
    /// `far_clip`); infinity is none.
    pub far_clip: f32,
    /// Where the image's centre is off the optical axis, in units of the
    /// image's half width (x, to the right) and half height (y, up): a
    /// camera ray through image position (x, y) in [-1, 1]^2 goes along
    /// `(x + shift.x) tan_u u + (y + shift.y) tan_v v - w`. Zero but for a
    /// Mitsuba sensor with a crop window off the film's centre or a
    /// `principal_point_offset`; the TOML format has none.
    pub shift: [f32; 2],
    /// Mitsuba's orthographic sensor, which replaces the pinhole: `None`
    /// for a perspective camera (and in every TOML scene).
    pub orthographic: Option<Orthographic>,
}

/// An orthographic camera (Mitsuba's `orthographic` sensor): every camera
/// ray runs along the optical axis from a point of the near plane. The ray
/// through image position (x, y) in [-1, 1]² (x to the right, y up, the
/// image's own window) starts at `origin + (x + shift.x) right + (y +
/// shift.y) up` and runs along `dir` for `far_clip - near_clip`.
/// `Camera::eye`, `look_at` and `up` are set to match; `vfov_deg`,
/// `aperture_radius` and `focus_distance` are not used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orthographic {
    /// Where the ray through the image's centre starts (without shift):
    /// `to_world` of (0, 0, near_clip).
    pub origin: Vec3,
    /// From the image's centre to its right edge's middle, on the near plane.
    pub right: Vec3,
    /// From the image's centre to its top edge's middle, on the near plane.
    pub up: Vec3,
    /// The unit direction of every camera ray.
    pub dir: Vec3,
}

/// A colour given as a constant, as a texture file, or as a Mitsuba
/// texture with lookup rules of its own.
#[derive(Debug, Clone, PartialEq)]
pub enum ColorSource {
    /// A constant linear RGB colour.
    Constant(Rgb),
    /// An sRGB-encoded image file, resolved to an absolute or scene-relative
    /// path, looked up by lancer's rule: bilinear, repeated.
    Texture(PathBuf),
    /// A Mitsuba texture whose lookup is not lancer's plain one: a bitmap
    /// with a `to_uv` transform, a wrap mode other than repeat or nearest
    /// filtering, or a checkerboard (XML only).
    Mapped(Box<MappedTexture>),
    /// Mitsuba's `mesh_attribute`: a value the mesh file gives each vertex
    /// (interpolated by the hit's barycentrics) or each face (XML only;
    /// PLY meshes). Each triangle holds it in [`Triangle::attribute`].
    Attribute(MeshAttribute),
}

/// Mitsuba's `mesh_attribute` texture: the mesh's attribute `name` (which
/// begins `vertex_` or `face_`), times `scale`.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshAttribute {
    /// The attribute's name, as Mitsuba's PLY loader names it
    /// (`vertex_color`, `face_weight`, ...).
    pub name: String,
    /// A factor on every value.
    pub scale: f32,
}

impl ColorSource {
    /// The image file the colour reads, if any.
    pub fn file(&self) -> Option<&Path> {
        match self {
            ColorSource::Constant(_) => None,
            ColorSource::Texture(p) => Some(p),
            ColorSource::Mapped(m) => match &m.pattern {
                TexturePattern::Bitmap(p) => Some(p),
                TexturePattern::Checkerboard { .. } => None,
            },
            ColorSource::Attribute(_) => None,
        }
    }

    /// Whether the colour varies over the surface (a texture of any kind).
    pub fn is_textured(&self) -> bool {
        !matches!(self, ColorSource::Constant(_))
    }
}

/// A Mitsuba texture with its lookup: what it shows, and how texture
/// coordinates reach it (Mitsuba 3.9's `src/textures/bitmap.cpp` and
/// `checkerboard.cpp`).
#[derive(Debug, Clone, PartialEq)]
pub struct MappedTexture {
    /// What the texture shows.
    pub pattern: TexturePattern,
    /// Mitsuba's `to_uv`, an affine map of its texture coordinates (v = 0
    /// at the image's top row) applied before the lookup, row by row:
    /// `u' = a[0] u + a[1] v + a[2]`, `v' = a[3] u + a[4] v + a[5]`.
    pub to_uv: [f32; 6],
    /// What a lookup outside [0, 1]² reads (bitmaps only).
    pub wrap: TextureWrap,
    /// How texels are interpolated (bitmaps only).
    pub filter: TextureFilter,
    /// The image's values are used as stored, not decoded from sRGB
    /// (Mitsuba's `raw`; bitmaps only).
    pub raw: bool,
}

impl MappedTexture {
    /// The identity `to_uv`.
    pub const IDENTITY_UV: [f32; 6] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
}

/// What a [`MappedTexture`] shows.
#[derive(Debug, Clone, PartialEq)]
pub enum TexturePattern {
    /// An image file (Mitsuba's `bitmap`), decoded as lancer decodes textures.
    Bitmap(PathBuf),
    /// Mitsuba's `checkerboard`: `color0` where the fractions of u and v are
    /// both above 1/2 or both not, `color1` elsewhere.
    Checkerboard {
        /// Linear RGB of the cells where both fractions agree.
        color0: Rgb,
        /// Linear RGB of the other cells.
        color1: Rgb,
    },
}

/// Mitsuba's `wrap_mode`: which texel an integer texel coordinate outside
/// the image reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TextureWrap {
    /// The image repeats.
    #[default]
    Repeat,
    /// The image repeats mirrored every other period.
    Mirror,
    /// The edge texels extend outwards.
    Clamp,
}

/// Mitsuba's `filter_type`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TextureFilter {
    /// Bilinear interpolation between the four nearest texel centres.
    #[default]
    Bilinear,
    /// The texel the point falls in.
    Nearest,
}

/// The scattering part of a material.
#[derive(Debug, Clone, PartialEq)]
pub enum MaterialKind {
    /// Lambertian diffuse.
    Lambert {
        /// Albedo colour or texture.
        albedo: ColorSource,
    },
    /// Normalised modified Phong.
    Phong {
        /// Diffuse colour or texture.
        diffuse: ColorSource,
        /// Specular colour.
        specular: Rgb,
        /// Phong exponent (>= 0).
        exponent: f32,
    },
    /// Perfect specular reflection.
    Mirror {
        /// Reflectance.
        reflectance: Rgb,
    },
    /// Blurry reflection by cone sampling.
    Glossy {
        /// Reflectance.
        reflectance: Rgb,
        /// Cone half-angle in degrees, 0 <= angle < 90.
        cone_angle_deg: f32,
    },
    /// Smooth dielectric with exact Fresnel.
    Dielectric {
        /// Index of refraction inside / outside.
        ior: f32,
        /// Tint applied at every refraction.
        tint: Rgb,
    },
    /// Smooth conductor: mirror reflection weighted by the Fresnel term of
    /// a complex index of refraction (Mitsuba's `conductor`).
    Conductor {
        /// Complex index of refraction, per channel.
        ior: ComplexIor,
        /// Factor on the reflection (1 for a physical conductor).
        specular_reflectance: Rgb,
    },
    /// Rough conductor: a microfacet model (Walter et al. 2007) with the
    /// conductor's Fresnel term, sampled by visible normals (Heitz 2018),
    /// as Mitsuba's `roughconductor`.
    RoughConductor {
        /// Distribution of the microfacet normals.
        distribution: Microfacet,
        /// Roughness along the surface's tangent (dp/du), > 0.
        alpha_u: f32,
        /// Roughness along the bitangent, > 0.
        alpha_v: f32,
        /// Textures that replace `alpha_u` or `alpha_v` where the roughness
        /// varies over the surface (Mitsuba XML only).
        alpha_textures: Option<Box<AlphaTextures>>,
        /// Complex index of refraction, per channel.
        ior: ComplexIor,
        /// Factor on the reflection (1 for a physical conductor).
        specular_reflectance: Rgb,
    },
    /// Rough dielectric: microfacet reflection and refraction (Walter et
    /// al. 2007) with the exact Fresnel term choosing between them,
    /// sampled by visible normals (Heitz 2018), as Mitsuba's
    /// `roughdielectric`. Read from Mitsuba XML only: the scene-format
    /// contract has no such material.
    RoughDielectric {
        /// Distribution of the microfacet normals.
        distribution: Microfacet,
        /// Roughness along the surface's tangent (dp/du), > 0.
        alpha_u: f32,
        /// Roughness along the bitangent, > 0.
        alpha_v: f32,
        /// Textures that replace `alpha_u` or `alpha_v` where the roughness
        /// varies over the surface.
        alpha_textures: Option<Box<AlphaTextures>>,
        /// Index of refraction inside over outside (Mitsuba's `int_ior /
        /// ext_ior`), > 0 and not 1.
        ior: f32,
        /// Factor on the reflection.
        specular_reflectance: Rgb,
        /// Factor on the refraction.
        specular_transmittance: Rgb,
    },
    /// Smooth plastic: a diffuse base under a smooth dielectric coating, as
    /// Mitsuba's `plastic` (mirror reflection by the coating's Fresnel term,
    /// and diffuse light refracted in and out, with the internal
    /// reflections summed). Read from Mitsuba XML only: the scene-format
    /// contract has no such material.
    Plastic {
        /// Colour or texture of the diffuse base.
        diffuse_reflectance: ColorSource,
        /// Factor on the coating's reflection.
        specular_reflectance: Rgb,
        /// Index of refraction of the coating over the outside, > 0.
        ior: f32,
        /// Mitsuba's `nonlinear`: the internal reflections darken and
        /// saturate the diffuse colour (`d / (1 - d Fdr)` instead of
        /// `d / (1 - Fdr)`).
        nonlinear: bool,
    },
    /// Thin dielectric: a slab of glass too thin to displace light, as
    /// Mitsuba's `thindielectric`. The Fresnel reflectance R at the angle
    /// of incidence, with the slab's inter-reflections summed, reflects
    /// R' = 2R / (1 + R) as a mirror; the rest, 1 - R', passes straight
    /// through, its direction unchanged. Read from Mitsuba XML only: the
    /// scene-format contract has no such material.
    ThinDielectric {
        /// Index of refraction of the slab over the outside, > 0.
        ior: f32,
        /// Factor on the reflection.
        specular_reflectance: Rgb,
        /// Factor on the transmission.
        specular_transmittance: Rgb,
    },
    /// Rough plastic: a diffuse base under a rough dielectric coating, as
    /// Mitsuba's `roughplastic` (microfacet reflection by the coating, and
    /// diffuse light refracted in and out through it, weighed by the
    /// coating's rough transmittance, with the internal reflections
    /// summed). Read from Mitsuba XML only: the scene-format contract has
    /// no such material.
    RoughPlastic {
        /// Distribution of the coating's microfacet normals.
        distribution: Microfacet,
        /// The coating's roughness (isotropic, as Mitsuba's), > 0.
        alpha: f32,
        /// Colour or texture of the diffuse base.
        diffuse_reflectance: ColorSource,
        /// Factor on the coating's reflection.
        specular_reflectance: Rgb,
        /// Index of refraction of the coating over the outside, > 0 and
        /// not 1.
        ior: f32,
        /// Mitsuba's `nonlinear`, as for [`MaterialKind::Plastic`].
        nonlinear: bool,
    },
    /// A blend of two materials, as Mitsuba's `blendbsdf`: `(1 - w)` times
    /// the first plus `w` times the second, sampled by picking one with
    /// those probabilities and weighed by the mixture's value over the
    /// mixture's pdf (a delta lobe's probability mixed with the other's
    /// density, as Mitsuba mixes them). The components scatter on the
    /// blend's sides; they are not glossy cones, do not transmit and are
    /// not blends (what `blendbsdf` is read with; see docs/mitsuba.md).
    /// Read from Mitsuba XML only: the scene-format contract has no such
    /// material.
    Blend {
        /// The weight w of the second component: a constant (its
        /// one-channel value) or a texture read as its luminance, clamped
        /// to [0, 1] (Mitsuba's `eval_1`).
        weight: ColorSource,
        /// The two components.
        components: Box<[MaterialKind; 2]>,
    },
    /// Mitsuba's `principled`, the Disney principled BRDF (Burley 2012, 2015)
    /// as Mitsuba 3 defines it: a diffuse lobe with retro-reflection and a
    /// fake subsurface, sheen, a GGX specular lobe whose Fresnel term mixes
    /// a dielectric's, a metal's and a tinted one, and a GTR1 clearcoat.
    /// Without its specular transmission (`spec_trans` 0, what lancer
    /// reads), it reflects on the front side only. Read from Mitsuba XML
    /// only: the scene-format contract has no such material.
    Principled(Box<Principled>),
}

/// The roughness of a rough conductor or dielectric where it varies over
/// the surface, as Mitsuba's `alpha` (or `alpha_u` and `alpha_v`) given as
/// textures: each read as one channel (its luminance, Mitsuba's `eval_1`)
/// and kept at least 1e-4, as Mitsuba's microfacet distribution keeps it.
/// A side without a texture keeps the material's constant.
#[derive(Debug, Clone, PartialEq)]
pub struct AlphaTextures {
    /// The roughness along the tangent, or `None` for `alpha_u`.
    pub u: Option<ColorSource>,
    /// The roughness along the bitangent, or `None` for `alpha_v`.
    pub v: Option<ColorSource>,
}

/// The parameters of a [`MaterialKind::Principled`], as Mitsuba's
/// `principled` names them. The weights lie in [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub struct Principled {
    /// The base colour: the diffuse colour, a metal's reflectance and the tint.
    pub base_color: ColorSource,
    /// Roughness: the specular lobe's GGX alpha is its square.
    pub roughness: f32,
    /// Anisotropy of the specular lobe (along dp/du and across it).
    pub anisotropic: f32,
    /// How metallic the surface is: the share of the metal's lobe.
    pub metallic: f32,
    /// How much the dielectric specular reflection takes the base colour.
    pub spec_tint: f32,
    /// The sheen lobe's weight (grazing retro-reflection of cloth).
    pub sheen: f32,
    /// How much the sheen takes the base colour.
    pub sheen_tint: f32,
    /// The clearcoat lobe's weight.
    pub clearcoat: f32,
    /// The clearcoat's gloss (its GTR1 alpha runs from 0.1 to 0.001).
    pub clearcoat_gloss: f32,
    /// The blend of the diffuse lobe towards the fake subsurface.
    pub flatness: f32,
    /// The index of refraction of the specular lobe (Mitsuba's `eta`, or
    /// `2 / (1 - sqrt(0.08 specular)) - 1` from `specular`), > 0.
    pub eta: f32,
    /// Mitsuba's sampling rates of the specular, clearcoat and diffuse
    /// lobes (>= 0, not all 0): they change the noise, not the image.
    pub sampling_rates: [f32; 3],
    /// Textures that give weights where they vary over the surface, in the
    /// order of [`Principled::WEIGHT_NAMES`], each read as one channel (its
    /// luminance, Mitsuba's `eval_1`); the constant of a weight with a
    /// texture is not read. `None` where every weight is constant (Mitsuba
    /// XML only).
    pub weight_textures: Option<Box<PrincipledTextures>>,
}

/// The textures of a [`Principled`]'s weights, in the order of
/// [`Principled::WEIGHT_NAMES`]: `None` where the weight is constant.
pub type PrincipledTextures = [Option<ColorSource>; Principled::WEIGHTS];

impl Principled {
    /// How many weights a principled material has that a texture may give.
    pub const WEIGHTS: usize = 9;

    /// Mitsuba's names of the weights that a texture may give, in the
    /// order of [`Principled::weights`] and [`PrincipledTextures`].
    pub const WEIGHT_NAMES: [&'static str; Principled::WEIGHTS] = [
        "roughness",
        "anisotropic",
        "metallic",
        "spec_tint",
        "sheen",
        "sheen_tint",
        "clearcoat",
        "clearcoat_gloss",
        "flatness",
    ];

    /// The constant weights, in the order of [`Principled::WEIGHT_NAMES`].
    pub fn weights(&self) -> [f32; Principled::WEIGHTS] {
        [
            self.roughness,
            self.anisotropic,
            self.metallic,
            self.spec_tint,
            self.sheen,
            self.sheen_tint,
            self.clearcoat,
            self.clearcoat_gloss,
            self.flatness,
        ]
    }

    /// The texture of the weight named `name` (one of
    /// [`Principled::WEIGHT_NAMES`]), if it has one.
    pub fn weight_texture(&self, name: &str) -> Option<&ColorSource> {
        let k = Principled::WEIGHT_NAMES.iter().position(|n| *n == name)?;
        self.weight_textures.as_ref()?[k].as_ref()
    }

    /// The GGX roughness along dp/du and across it, as Mitsuba's
    /// `calc_dist_params` gives it (at least 0.001).
    pub fn alphas(&self) -> (f32, f32) {
        let r2 = self.roughness * self.roughness;
        if self.anisotropic == 0.0 {
            return (r2.max(0.001), r2.max(0.001));
        }
        let aspect = (1.0 - 0.9 * self.anisotropic).sqrt();
        ((r2 / aspect).max(0.001), (r2 * aspect).max(0.001))
    }

    /// The specular, clearcoat and diffuse lobes' unnormalised sampling
    /// weights at a point of the given metallic and clearcoat: the
    /// specular rate, 0.25 clearcoat times the clearcoat rate, (1 -
    /// metallic) times the diffuse rate (Mitsuba's `sample` and `pdf` on
    /// the front side without transmission; the kernels compute the same
    /// at a hit where textures give the weights).
    fn lobe_weights(&self, metallic: f32, clearcoat: f32) -> [f32; 3] {
        let [specular, coat, diffuse] = self.sampling_rates;
        [
            specular,
            0.25 * clearcoat * coat,
            (1.0 - metallic) * diffuse,
        ]
    }

    /// The probabilities of sampling the diffuse lobe and the clearcoat
    /// (the specular lobe takes the rest), from the constant weights.
    pub fn lobe_probabilities(&self) -> (f32, f32) {
        let [ps, pc, pd] = self.lobe_weights(self.metallic, self.clearcoat);
        let rcp = 1.0 / (ps + pc + pd);
        (pd * rcp, pc * rcp)
    }

    /// Whether some point of the surface may have no lobe to sample: the
    /// lobes' sampling weights all 0, with a textured metallic taken as 1
    /// and a textured clearcoat as 0 (where the probabilities of
    /// [`Principled::lobe_probabilities`] are 0 / 0).
    pub fn may_sample_nothing(&self) -> bool {
        let textured = |name| self.weight_texture(name).is_some();
        let metallic = if textured("metallic") {
            1.0
        } else {
            self.metallic
        };
        let clearcoat = if textured("clearcoat") {
            0.0
        } else {
            self.clearcoat
        };
        let [ps, pc, pd] = self.lobe_weights(metallic, clearcoat);
        let total = ps + pc + pd;
        total.is_nan() || total <= 0.0
    }

    /// The clearcoat's GTR1 alpha, `lerp(0.1, 0.001, clearcoat_gloss)`.
    pub fn clearcoat_alpha(&self) -> f32 {
        0.1 + (0.001 - 0.1) * self.clearcoat_gloss
    }
}

impl MaterialKind {
    /// Whether light passes through the surface (a smooth, rough or thin
    /// dielectric): such a material takes its side from the geometric
    /// normal and ignores `sides`.
    pub const fn transmits(&self) -> bool {
        matches!(
            self,
            MaterialKind::Dielectric { .. }
                | MaterialKind::RoughDielectric { .. }
                | MaterialKind::ThinDielectric { .. }
        )
    }

    /// Whether the roughness differs along the tangent and the bitangent,
    /// so that the surface's tangent (dp/du) orients the response.
    pub fn is_anisotropic(&self) -> bool {
        matches!(
            self,
            MaterialKind::RoughConductor { alpha_u, alpha_v, alpha_textures, .. }
                | MaterialKind::RoughDielectric { alpha_u, alpha_v, alpha_textures, .. }
                if alpha_u != alpha_v
                    || alpha_textures.as_ref().is_some_and(|t| t.u != t.v)
        ) || matches!(self, MaterialKind::Principled(p)
            if p.anisotropic != 0.0 || p.weight_texture("anisotropic").is_some())
            || matches!(self, MaterialKind::Blend { components, .. }
            if components.iter().any(MaterialKind::is_anisotropic))
    }

    /// Whether the scene-format contract (TOML) has this material: those it
    /// has not come from Mitsuba XML only, and `lancer convert` cannot write them.
    pub const fn in_toml_format(&self) -> bool {
        !matches!(
            self,
            MaterialKind::RoughDielectric { .. }
                | MaterialKind::Plastic { .. }
                | MaterialKind::RoughPlastic { .. }
                | MaterialKind::ThinDielectric { .. }
                | MaterialKind::Blend { .. }
                | MaterialKind::Principled(_)
        )
    }

    /// Mitsuba's name of a material the TOML format has not.
    pub const fn mitsuba_name(&self) -> Option<&'static str> {
        match self {
            MaterialKind::RoughDielectric { .. } => Some("roughdielectric"),
            MaterialKind::Plastic { .. } => Some("plastic"),
            MaterialKind::RoughPlastic { .. } => Some("roughplastic"),
            MaterialKind::ThinDielectric { .. } => Some("thindielectric"),
            MaterialKind::Blend { .. } => Some("blendbsdf"),
            MaterialKind::Principled(_) => Some("principled"),
            _ => None,
        }
    }
}

/// The complex index of refraction `eta + i k` of a conductor, per RGB
/// channel. `eta = 0, k = 1` reflects everything at every angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplexIor {
    /// Real part.
    pub eta: Rgb,
    /// Imaginary part (absorption).
    pub k: Rgb,
}

impl ComplexIor {
    /// The perfect reflector: Mitsuba's material `none`.
    pub const PERFECT: ComplexIor = ComplexIor {
        eta: Vec3::ZERO,
        k: Vec3::ONE,
    };
}

/// A distribution of microfacet normals, as Mitsuba names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Microfacet {
    /// Beckmann: Gaussian random slopes (Mitsuba's default); alpha is the
    /// RMS slope.
    #[default]
    Beckmann,
    /// GGX (Trowbridge-Reitz): longer tails.
    Ggx,
}

impl Microfacet {
    /// The name scene files use: `beckmann` or `ggx`.
    pub const fn name(self) -> &'static str {
        match self {
            Microfacet::Beckmann => "beckmann",
            Microfacet::Ggx => "ggx",
        }
    }
}

/// A named material: how the surface scatters, and what it emits.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name in the scene file (or `file.mtl:name` for OBJ materials).
    pub name: String,
    /// Scattering model.
    pub kind: MaterialKind,
    /// Radiance leaving the front side.
    pub emission: Rgb,
    /// Which sides scatter light (dielectrics ignore it: they transmit).
    pub sides: Sides,
    /// Mitsuba's `mask`: the probability that light meets the surface at a
    /// point is this colour's one-channel value there, as Mitsuba reads it
    /// (a constant's mean, a bitmap's luminance); elsewhere light passes
    /// straight through. `None` for an opaque surface.
    pub opacity: Option<ColorSource>,
    /// Mitsuba's `normalmap`: the shading normal tilted by a texture.
    /// `None` without one.
    pub normal_map: Option<NormalMap>,
}

/// A normal map (Mitsuba's `normalmap`): each texel's `2 c - 1` is the
/// shading normal in the frame of the surface's own shading normal and
/// its tangent dp/du. Or a bump map (Mitsuba's `bumpmap`): the gradient
/// of a height texture moves the surface along its shading normal, and
/// the normal follows.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalMap {
    /// The texture (a bitmap, normally read `raw`): normals, or heights
    /// (their luminance) for a bump map.
    pub texture: ColorSource,
    /// `Some(scale)` for a bump map, whose height gradient is multiplied
    /// by `scale` (Mitsuba's `scale`); `None` for a normal map.
    pub bump_scale: Option<f32>,
    /// The map wraps a two-sided material (`normalmap` around `twosided`),
    /// so that seen from behind, the tilt is that of the front mirrored
    /// through the surface; `twosided` around the map tilts the same way
    /// on both sides.
    pub wraps_two_sided: bool,
    /// The response is weighed by Mitsuba's shadowing term for tilted
    /// normals (Estevez et al. 2019; `use_shadowing_function`).
    pub shadowing: bool,
}

impl Material {
    /// The texture file the material reads for its diffuse colour, if any.
    pub fn texture(&self) -> Option<&Path> {
        self.diffuse_source()?.file()
    }

    /// Every colour the material reads that may be a texture, each with
    /// whether it is read as one channel (Mitsuba's `eval_1`: a weight, a
    /// roughness, an opacity, a bump map's heights) or as a colour: its
    /// kind's ([`MaterialKind::colour_reads`]), its blend components', its
    /// opacity, its normal or bump map.
    pub fn colour_reads(&self) -> Vec<(&ColorSource, bool)> {
        let components: Vec<(&ColorSource, bool)> = match &self.kind {
            MaterialKind::Blend { components, .. } => components
                .iter()
                .flat_map(MaterialKind::colour_reads)
                .collect(),
            _ => Vec::new(),
        };
        (self.kind.colour_reads().into_iter())
            .chain(components)
            .chain(self.opacity.as_ref().map(|c| (c, true)))
            .chain((self.normal_map.as_ref()).map(|n| (&n.texture, n.bump_scale.is_some())))
            .collect()
    }

    /// Every image file the material reads: its diffuse colour's (a
    /// blend's weight's, then its components'), its roughness's, then its
    /// opacity's and its normal or bump map's.
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        (self.colour_reads().into_iter()).filter_map(|(c, _)| c.file())
    }

    /// The colour source of the material's diffuse part, for the materials
    /// that may be textured (none for a blend: see its components).
    pub fn diffuse_source(&self) -> Option<&ColorSource> {
        self.kind.diffuse_source()
    }

    /// The mesh attributes the material reads ([`Material::colour_reads`]
    /// that are [`ColorSource::Attribute`]), each with whether it is read
    /// as one channel (Mitsuba's `eval_1`, which takes one-channel
    /// attributes only) or as a colour.
    pub fn mesh_attribute_reads(&self) -> Vec<(&MeshAttribute, bool)> {
        (self.colour_reads().into_iter())
            .filter_map(|(c, one_channel)| match c {
                ColorSource::Attribute(a) => Some((a, one_channel)),
                _ => None,
            })
            .collect()
    }
}

impl MaterialKind {
    /// The textures of a rough conductor's or dielectric's roughness,
    /// where it varies over the surface.
    pub fn alpha_textures(&self) -> Option<&AlphaTextures> {
        match self {
            MaterialKind::RoughConductor { alpha_textures, .. }
            | MaterialKind::RoughDielectric { alpha_textures, .. } => alpha_textures.as_deref(),
            _ => None,
        }
    }

    /// Every colour the kind itself reads that may be a texture: its
    /// diffuse colour, a blend's weight (not its components'), a rough
    /// material's roughness along the tangent and the bitangent, a
    /// principled material's textured weights.
    pub fn colour_sources(&self) -> Vec<&ColorSource> {
        self.colour_reads().into_iter().map(|(c, _)| c).collect()
    }

    /// [`MaterialKind::colour_sources`], each with whether it is read as
    /// one channel (Mitsuba's `eval_1`: a blend's weight, a roughness, a
    /// principled weight) or as a colour (the diffuse colour).
    pub fn colour_reads(&self) -> Vec<(&ColorSource, bool)> {
        let mut reads: Vec<(&ColorSource, bool)> = self
            .diffuse_source()
            .into_iter()
            .map(|c| (c, false))
            .collect();
        if let MaterialKind::Blend { weight, .. } = self {
            reads.push((weight, true));
        }
        if let Some(t) = self.alpha_textures() {
            reads.extend(t.u.iter().chain(&t.v).map(|c| (c, true)));
        }
        if let MaterialKind::Principled(p) = self {
            reads.extend(
                p.weight_textures
                    .iter()
                    .flat_map(|t| t.iter().flatten())
                    .map(|c| (c, true)),
            );
        }
        reads
    }

    /// The colour source of the diffuse part, for the kinds that may be
    /// textured.
    pub fn diffuse_source(&self) -> Option<&ColorSource> {
        match self {
            MaterialKind::Lambert { albedo: c }
            | MaterialKind::Phong { diffuse: c, .. }
            | MaterialKind::Plastic {
                diffuse_reflectance: c,
                ..
            }
            | MaterialKind::RoughPlastic {
                diffuse_reflectance: c,
                ..
            } => Some(c),
            MaterialKind::Principled(p) => Some(&p.base_color),
            _ => None,
        }
    }
}

/// The components of the blends among `materials`, in the order of the
/// materials, two each: the device's material table holds them after the
/// materials, and a blend's `info.w` is the index of its first.
pub fn blend_components(materials: &[Material]) -> Vec<&MaterialKind> {
    materials
        .iter()
        .filter_map(|m| match &m.kind {
            MaterialKind::Blend { components, .. } => Some(components.iter()),
            _ => None,
        })
        .flatten()
        .collect()
}

/// Which sides of a surface a material scatters light on, and which normal
/// decides the side a viewer is on. A shading normal (a mesh's vertex
/// normals) can disagree with the geometric normal near a silhouette.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sides {
    /// Both sides, the same way (lancer's rule): the geometric normal gives
    /// the side, and a shading normal that faces away from the viewer gives
    /// way to the geometric one. TOML `sides = "both"`, the default.
    #[default]
    Both,
    /// Both sides, the side given by the shading normal, as Mitsuba's
    /// `twosided` does: where the viewer is on one side of the geometric
    /// normal and on the other of the shading normal, nothing is scattered
    /// (in Mitsuba, the light leaves through the surface and is mostly
    /// blocked; lancer never lets it through). TOML `sides = "shading"`.
    Shading,
    /// The front side of the shading normal only, black from behind, as
    /// Mitsuba's `diffuse` and `conductor` outside `twosided`. TOML
    /// `sides = "front"`.
    Front,
}

impl Sides {
    /// Every value, the default first.
    pub const ALL: [Sides; 3] = [Sides::Both, Sides::Shading, Sides::Front];

    /// The value's name in a TOML scene (`sides = "..."`).
    pub const fn name(self) -> &'static str {
        match self {
            Sides::Both => "both",
            Sides::Shading => "shading",
            Sides::Front => "front",
        }
    }
}

/// One triangle of a mesh, in world space, after the object's transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    /// Vertex positions, counter-clockwise seen from the front.
    pub p: [Vec3; 3],
    /// Shading normals at the vertices, if the OBJ has them (unit length).
    pub n: Option<[Vec3; 3]>,
    /// Texture coordinates at the vertices, if any.
    pub uv: Option<[glam::Vec2; 3]>,
    /// Index into `Scene::materials`.
    pub material: u32,
    /// Index into `Scene::mesh_attributes` of the values at its vertices
    /// of the mesh attribute its material reads, if it reads one.
    pub attribute: Option<u32>,
}

/// A sphere in world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius (> 0).
    pub radius: f32,
    /// Index into `Scene::materials`.
    pub material: u32,
    /// A Mitsuba sphere's local axes x, y and z in the world (the rotation
    /// of its `to_world`, orthonormal, a mirror included): its texture
    /// coordinates and tangent are then Mitsuba's, taken in that frame
    /// (u the angle about local z from local x over 2π, v = 1 - θ/π with
    /// θ from local +z, in lancer's texture orientation). `None`: lancer's
    /// own (docs/scene-format.md).
    pub mitsuba_frame: Option<[Vec3; 3]>,
}

/// A light with no area: no ray hits it, so only next-event estimation
/// finds it. Mitsuba's `point`, `spot` and `directional`, or TOML's
/// `[[lights]]`; Mitsuba's `projector` too (XML only).
#[derive(Debug, Clone, PartialEq)]
pub enum DeltaLight {
    /// Light from one point, equal in every direction.
    Point {
        /// Position.
        position: Vec3,
        /// Radiant intensity (power per steradian).
        intensity: Rgb,
    },
    /// A point light shining in a cone: full intensity within `beam_width_deg`
    /// of its axis, falling linearly in angle to zero at `cutoff_deg`.
    Spot {
        /// Position.
        position: Vec3,
        /// World to light space (the inverse of the linear part of
        /// Mitsuba's `to_world`); the light shines along local +z.
        to_local: glam::Mat3,
        /// Radiant intensity on the axis.
        intensity: Rgb,
        /// Angle from the axis where the light ends, degrees, in (0, 180).
        cutoff_deg: f32,
        /// Angle from the axis of the full-intensity beam, degrees, in [0, cutoff_deg].
        beam_width_deg: f32,
        /// An image the light projects, which scales its intensity (Mitsuba's
        /// `texture`, XML only): the direction with light-space unit vector
        /// d reads it at Mitsuba's uv = 1/2 + d.xy / (2 d.z tan(cutoff)), v = 0
        /// at the image's top row.
        texture: Option<ColorSource>,
    },
    /// A pinhole projecting an image (Mitsuba's `projector`, XML only): the
    /// reciprocal of a perspective camera. A point p at light-space position
    /// q (`to_local` of p - `position`, q.z > 0) receives from it
    /// `pi scale E(uv) / (q.z^2 cos)`, where uv = 1/2 - (q.x, q.y) (cot_x,
    /// cot_y) / (2 q.z) must lie in [0, 1]^2, E is the irradiance image and
    /// cos the cosine between the light's axis (Mitsuba's `to_world`
    /// applied to +z, `to_local`'s inverse times +z) and the direction to p.
    Projector {
        /// Position of the pinhole.
        position: Vec3,
        /// World to light space (the inverse of the linear part of
        /// Mitsuba's `to_world`); the light shines along local +z.
        to_local: glam::Mat3,
        /// The irradiance on the image plane at distance 1 (Mitsuba's
        /// `irradiance`): a colour or an image, v = 0 at the top row.
        irradiance: ColorSource,
        /// Factor on the irradiance (Mitsuba's `scale`), >= 0.
        scale: f32,
        /// Cotangent of half the horizontal field of view.
        cot_x: f32,
        /// Cotangent of half the vertical field of view: `cot_x` times the
        /// irradiance image's width over its height (1 for a colour).
        cot_y: f32,
    },
    /// Light from infinitely far away, arriving along one direction.
    Directional {
        /// Unit direction the light travels in.
        direction: Vec3,
        /// Irradiance on a surface facing the light.
        irradiance: Rgb,
    },
}

impl DeltaLight {
    /// Whether the scene-format contract (TOML) has this light: a
    /// projector and a textured spot come from Mitsuba XML only, and
    /// `lancer convert` cannot write them.
    pub const fn in_toml_format(&self) -> bool {
        !matches!(
            self,
            DeltaLight::Projector { .. }
                | DeltaLight::Spot {
                    texture: Some(_),
                    ..
                }
        )
    }

    /// The image or pattern the light reads, if any: a spot's texture or a
    /// projector's irradiance when it is not a constant colour.
    pub fn texture(&self) -> Option<&ColorSource> {
        match self {
            DeltaLight::Spot { texture, .. } => texture.as_ref(),
            DeltaLight::Projector { irradiance, .. } => {
                Some(irradiance).filter(|c| c.is_textured())
            }
            _ => None,
        }
    }
}

/// An environment map: radiance from every direction, read from a
/// latitude-longitude image as Mitsuba 3's `envmap` emitter maps it
/// (`src/emitters/envmap.cpp`): in the map's own frame, +y is up
/// (v = 0, the image's top row, is straight up; v = 1, its bottom row,
/// straight down, rows evenly spaced in angle from pole to pole), and u runs
/// around the y axis from -z (u = 0) towards +x (u = 1/4); texel centres
/// sit at u = (i + 1/2) / width; lookups are bilinear and wrap around in u.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvMap {
    /// The image file (EXR or HDR, linear; an integer image is sRGB-decoded).
    pub file: PathBuf,
    /// Factor on every texel (Mitsuba's `scale`), >= 0.
    pub scale: f32,
    /// World to map space: the inverse of the rotation Mitsuba's `to_world`
    /// gives (orthogonal).
    pub to_local: glam::Mat3,
}

/// A whole scene, ready to be packed for the GPU.
///
/// Quads become two triangles; meshes are loaded, transformed and
/// triangulated. Every index is valid.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Render settings from `[render]`.
    pub render: RenderSettings,
    /// The camera.
    pub camera: Camera,
    /// Constant environment radiance (black by default).
    pub environment: Rgb,
    /// An environment map (Mitsuba's `envmap`); never with a non-black
    /// `environment`.
    pub envmap: Option<EnvMap>,
    /// All materials; objects refer to them by index.
    pub materials: Vec<Material>,
    /// All spheres.
    pub spheres: Vec<Sphere>,
    /// All triangles (quads and meshes).
    pub triangles: Vec<Triangle>,
    /// The mesh attribute values of the triangles whose material reads one
    /// ([`ColorSource::Attribute`]), at their three vertices, in linear
    /// RGB (a face attribute's value three times, a one-channel one in
    /// all three channels); [`Triangle::attribute`] indexes them.
    pub mesh_attributes: Vec<[Vec3; 3]>,
    /// Lights with no area (point, spot, directional).
    pub lights: Vec<DeltaLight>,
    /// Where the scene came from, for messages.
    pub source: PathBuf,
    /// The XML files a Mitsuba scene file `<include>`s, recursively, in
    /// the order read (none for a TOML scene).
    pub includes: Vec<PathBuf>,
    /// The other files the loader read, in the order read: OBJ and PLY
    /// meshes and `.mtl` material libraries (textures are named by the
    /// materials; [`Scene::input_files`] lists every file).
    pub files: Vec<PathBuf>,
    /// Things the loader fixed or dropped that the user may want to know
    /// about (degenerate or non-finite mesh triangles, bad normals, ...),
    /// one line each, naming the file and key.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Every file the scene reads, each with what it is to the user: the
    /// scene file, the files it includes, its meshes and material libraries, and the texture of
    /// each material (a file named twice is listed once).
    pub fn input_files(&self) -> Vec<(PathBuf, String)> {
        let mut files = vec![(self.source.clone(), "the scene file".to_string())];
        files.extend(
            (self.includes.iter()).map(|p| (p.clone(), "a file the scene includes".to_string())),
        );
        files.extend(self.files.iter().map(|p| {
            let mtl = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("mtl"));
            let what = if mtl { "a material library" } else { "a mesh" };
            (p.clone(), format!("{what} of the scene"))
        }));
        files.extend(self.materials.iter().flat_map(|m| {
            let name = crate::util::text::cut(&m.name);
            let opacity = m.opacity.as_ref().and_then(ColorSource::file);
            let normals = m.normal_map.as_ref().and_then(|n| n.texture.file());
            (m.texture()
                .map(|p| (p, format!("the texture of material \"{name}\""))))
            .into_iter()
            .chain(opacity.map(|p| (p, format!("the opacity texture of material \"{name}\""))))
            .chain(normals.map(|p| (p, format!("the normal map of material \"{name}\""))))
            .map(|(p, what)| (p.to_path_buf(), what))
        }));
        if let Some(env) = &self.envmap {
            files.push((env.file.clone(), "the environment map".to_string()));
        }
        let mut seen = std::collections::HashSet::new();
        files.retain(|(p, _)| seen.insert(p.clone()));
        files
    }
}
