//! What the device can represent: the limits a scene is checked against
//! when it is read, and again when it is packed for the device (the command
//! line may change the image size after reading).
//!
//! The device works in 32-bit floats and 32-bit integers. A value that is
//! valid in the scene file's 64-bit numbers can collapse there (a camera
//! basis built from vectors of length 1e-30) or overflow (a pixel count of
//! 65536 x 65536). Every check here says what the device would get and why
//! it cannot use it; `docs/scene-format.md` states the same limits.

use super::types::{
    Camera, ColorSource, DeltaLight, Material, MaterialKind, RenderSettings, TexturePattern,
};
use glam::{DVec3, Vec3};

/// Most pixels per side. Pixel positions are f32 on the device; below 2^20
/// they keep 1/16 pixel of sub-pixel jitter, so every sample stays in its
/// own stratum of its own pixel.
pub const MAX_IMAGE_SIDE: u32 = 1 << 20;

/// Most pixels in an image. The kernels index pixels in 32-bit integers
/// (a wave's `pixel_base + slot % wave_pixels`, the film's `pixel -
/// film_base`), so every pixel index must fit a u32; 2^31 leaves a factor
/// of two. The film is no limit: the device holds one band of rows of it
/// at a time (`crate::render::tiles`), and the host the whole film, 64 bytes per
/// pixel (128 GiB at this limit, which the host must have).
pub const MAX_IMAGE_PIXELS: u64 = 1 << 31;

/// Most texels in one texture (4096 x 4096, or any shape of that area).
/// Checked from the file's header, before its pixels are decoded, so that
/// a small file claiming a huge image costs nothing: a texture's decoded
/// pixels take up to 16 bytes each (RGBA in 32-bit floats) before they are
/// packed into the device's buffer as 4-byte sRGB texels.
pub const MAX_TEXTURE_TEXELS: u64 = 1 << 24;

/// Most entries of one element of a PLY file (vertices, faces, or any
/// other element, which is read past). Checked from the header, with the
/// bytes the file has after it, before anything is read: 2^28 vertices
/// and faces take about 30 GB of host memory once loaded, and an element
/// whose entries hold no bytes would otherwise be bounded by nothing.
pub const MAX_PLY_ELEMENTS: u64 = 1 << 28;

/// Most vertices, and most triangles, of one mesh of a Mitsuba `serialized`
/// file: the same 2^28 as [`MAX_PLY_ELEMENTS`], for the same reason (about
/// 30 GB of host memory once loaded). Checked from the counts at the head of
/// the mesh's compressed stream, before anything is read for them; the
/// bytes the counts need are also checked against the most the file's
/// compressed bytes can inflate to.
pub const MAX_SERIALIZED_ELEMENTS: u64 = MAX_PLY_ELEMENTS;

/// Largest emission or environment radiance component. Radiance, its square
/// (the film's variance) and their sums over the samples of a pixel are
/// 32-bit floats on the device (largest 3.4e38). 1e12 squared and summed
/// over a million samples per pixel gives 1e30, leaving eight orders of
/// magnitude for the factors that multiply emission along a path (area over
/// squared distance in light sampling, Russian roulette, eta^2).
pub const MAX_RADIANCE: f64 = 1e12;

/// Most wavelength:value pairs of one Mitsuba `<spectrum>`: measured
/// spectra come at 1 nm or coarser over a few hundred nm.
pub const MAX_SPECTRUM_PAIRS: usize = 10_000;

/// The pixel count of a `width` x `height` image, computed without
/// wrapping and checked against [`MAX_IMAGE_SIDE`] and
/// [`MAX_IMAGE_PIXELS`]. On error: the key at fault (`"width"` or
/// `"height"`) and the reason, with the real figures.
pub fn image_pixels(width: u32, height: u32) -> Result<u32, (&'static str, String)> {
    for (key, side) in [("width", width), ("height", height)] {
        if side == 0 {
            return Err((key, format!("must be >= 1, got {side}")));
        }
        if side > MAX_IMAGE_SIDE {
            return Err((
                key,
                format!(
                    "{side} pixels is above the limit of {MAX_IMAGE_SIDE} per side \
                     (pixel positions are 32-bit floats on the device); lower the {key}"
                ),
            ));
        }
    }
    let pixels = width as u64 * height as u64;
    if pixels > MAX_IMAGE_PIXELS {
        return Err((
            "width",
            format!(
                "{width} x {height} = {pixels} pixels; lancer renders at most \
                 {MAX_IMAGE_PIXELS} pixels (2^31: the kernels index pixels in 32-bit \
                 integers); lower the width or height"
            ),
        ));
    }
    // `pixels` <= 2^31 fits.
    Ok(pixels as u32)
}

impl RenderSettings {
    /// The one check of render settings, run once they are final (after
    /// any [`super::RenderOverrides`]) by every loader, the builder and
    /// packing: the image size ([`image_pixels`]), at least one sample
    /// and one segment, a roulette start of at least 1, and the pixel filter's
    /// parameters. Returns the pixel count; on error the key of
    /// `[render]` at fault and the reason.
    pub fn check(&self) -> Result<u32, (&'static str, String)> {
        let pixels = image_pixels(self.width, self.height)?;
        for (key, value) in [
            ("spp", self.spp),
            ("max_depth", self.max_depth),
            ("rr_depth", self.rr_depth),
        ] {
            if value == 0 {
                return Err((key, String::from("must be >= 1, got 0")));
            }
        }
        self.filter
            .validate()
            .map_err(|reason| ("filter", reason))?;
        Ok(pixels)
    }
}

/// An orthonormal camera basis as the device gets it (`GpuFrame::cam_*`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraBasis {
    /// Unit vector to the right in the image.
    pub u: Vec3,
    /// Unit vector up in the image.
    pub v: Vec3,
    /// Unit vector pointing backwards, from `look_at` to `eye`.
    pub w: Vec3,
}

/// Smallest sine of the angle between `up` and the view direction.
pub(crate) const MIN_UP_SINE: f64 = 1e-6;

/// Why a camera has no basis: the key at fault and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum BasisError {
    /// `look_at - eye` is zero.
    SamePoint,
    /// `up` is zero.
    ZeroUp,
    /// `up` is parallel to the view direction.
    UpParallel,
    /// A vector is NaN or infinite.
    NonFinite(&'static str),
}

/// The camera basis in f64: (u, v, w). Normalising in f64 keeps vectors as
/// short as 1e-300 exact, where f32 would underflow to a NaN basis.
pub(crate) fn basis_f64(eye: DVec3, look_at: DVec3, up: DVec3) -> Result<[DVec3; 3], BasisError> {
    for (key, v) in [("eye", eye), ("look_at", look_at), ("up", up)] {
        if !v.is_finite() {
            return Err(BasisError::NonFinite(key));
        }
    }
    // Finite from here on, so no comparison below meets a NaN.
    let back = eye - look_at;
    let len = back.length();
    if len <= 0.0 {
        return Err(BasisError::SamePoint);
    }
    let w = back / len;
    let up_len = up.length();
    if up_len <= 0.0 {
        return Err(BasisError::ZeroUp);
    }
    let side = (up / up_len).cross(w);
    let sine = side.length();
    if sine <= MIN_UP_SINE {
        return Err(BasisError::UpParallel);
    }
    let u = side / sine;
    let v = w.cross(u);
    Ok([u, v, w])
}

impl Camera {
    /// Whether the camera clips its rays (a near plane above 0 or a finite
    /// far plane).
    pub fn has_clip(&self) -> bool {
        self.near_clip > 0.0 || self.far_clip.is_finite()
    }

    /// The basis the device uses: built in f64 from the camera's f32
    /// fields, then rounded to f32 unit vectors. Fails when the camera has
    /// none (`look_at` equal to `eye`, `up` zero or parallel to the view).
    pub fn basis(&self) -> Result<CameraBasis, (&'static str, String)> {
        let [u, v, w] = basis_f64(
            self.eye.as_dvec3(),
            self.look_at.as_dvec3(),
            self.up.as_dvec3(),
        )
        .map_err(|e| match e {
            BasisError::SamePoint => (
                "look_at",
                String::from(
                    "is the same point as camera.eye in 32-bit floats, so the camera has \
                     no direction to look in; move look_at away from eye",
                ),
            ),
            BasisError::ZeroUp => (
                "up",
                String::from(
                    "is [0, 0, 0] in 32-bit floats; give the direction that should point \
                     up in the image, with a length of about 1",
                ),
            ),
            BasisError::UpParallel => (
                "up",
                String::from(
                    "is parallel to the view direction (look_at - eye); set camera.up to \
                     a direction that is not",
                ),
            ),
            BasisError::NonFinite(key) => (key, String::from("must be finite")),
        })?;
        let basis = CameraBasis {
            u: u.as_vec3(),
            v: v.as_vec3(),
            w: w.as_vec3(),
        };
        // Rounding a unit f64 vector to f32 keeps it unit to ~1e-7.
        for (key, x) in [("up", basis.u), ("up", basis.v), ("look_at", basis.w)] {
            if !(x.is_finite() && (x.length() - 1.0).abs() < 1e-5) {
                return Err((key, format!("gives a camera vector {x} that is not unit")));
            }
        }
        Ok(basis)
    }
}

/// Angle in radians between two unit vectors, accurate for tiny angles.
pub(crate) fn angle(a: DVec3, b: DVec3) -> f64 {
    2.0 * ((a - b).length() * 0.5).min(1.0).asin()
}

/// Largest magnitude of a coordinate: sphere extents, quad corners, mesh
/// vertices after their transform, and the camera's eye with its lens. The
/// watertight triangle test multiplies three coordinate differences in
/// 32-bit floats; at 1e11 the largest product is about 3e35, three orders
/// of magnitude below the float limit of 3.4e38 (at 1e12 it would reach it).
pub const MAX_COORDINATE: f64 = 1e11;

/// Least distance between the eye and a sphere's surface, as a fraction of
/// the sphere's magnitude (largest centre coordinate plus radius). The
/// device places a sphere's surface to within a few units in the last
/// place of that magnitude (2^-23 of it); 2^-16 keeps the eye's distance
/// to the surface known to better than 1%. Closer, the eye can land on the
/// wrong side: a ground sphere of radius 3e7 seen from 1 above rendered
/// black.
pub const SPHERE_EYE_CLEARANCE: f64 = 1.0 / 65536.0;

/// Checks that every point lies within [`MAX_COORDINATE`]; on error, what
/// to say after the key: `what` (e.g. "the quad") and the coordinate at fault.
pub(crate) fn check_coordinates(
    what: &str,
    points: impl IntoIterator<Item = DVec3>,
) -> Result<(), String> {
    for p in points {
        let largest = p.abs().max_element();
        if largest > MAX_COORDINATE {
            return Err(format!(
                "{what} reaches [{:e}, {:e}, {:e}], a coordinate of magnitude {largest:e}; \
                 lancer renders coordinates up to {MAX_COORDINATE:e} (its triangle test \
                 multiplies three coordinate differences in 32-bit floats, which would \
                 overflow); scale the scene down, every position, edge, radius and the \
                 camera by one factor",
                p.x, p.y, p.z
            ));
        }
    }
    Ok(())
}

/// Checks that `eye` lies clear of a sphere's surface by
/// [`SPHERE_EYE_CLEARANCE`] of the sphere's magnitude; on error, the reason.
pub(crate) fn check_sphere_clearance(eye: DVec3, center: DVec3, radius: f64) -> Result<(), String> {
    let magnitude = center.abs().max_element() + radius;
    let gap = ((eye - center).length() - radius).abs();
    let least = SPHERE_EYE_CLEARANCE * magnitude;
    if gap < least {
        return Err(format!(
            "camera.eye is {gap:e} from the surface of this sphere; the device places the \
             surface of a sphere of radius {radius:e} centred {:e} from the origin only to \
             within about {:e} (32-bit floats), so the eye must be at least {least:e} from it \
             (2^-16 of |centre| + radius); move the eye away from the surface, or use a \
             smaller sphere (a quad makes an exact ground plane)",
            center.abs().max_element(),
            magnitude * f64::from(f32::EPSILON)
        ));
    }
    Ok(())
}

/// Largest radiance a path may carry: an emission (at most
/// [`MAX_RADIANCE`]) times what the bounces before it multiply it by. Its
/// square summed over a million samples of a pixel is 1e34, four orders of
/// magnitude below the 32-bit float limit, which covers the factors no
/// scene value bounds (area over squared distance in light sampling,
/// Russian roulette's 1/q).
pub const MAX_PATH_RADIANCE: f64 = 1e14;

/// Where a scene's light can grow along a path, for [`check_path_gain`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GainError {
    /// Index of the material at fault.
    pub material: usize,
    /// Its key to change (`albedo`, `specular`, `reflectance`, `tint`, `ior`).
    pub field: &'static str,
    /// Why, with the figures and the largest value that would pass.
    pub reason: String,
}

impl GainError {
    /// The dotted scene key, `materials.<name>.<field>`.
    pub fn key(&self, materials: &[Material]) -> String {
        format!("materials.{}.{}", materials[self.material].name, self.field)
    }
}

/// Checks that no path can carry radiance above [`MAX_PATH_RADIANCE`].
///
/// A path's radiance is an emission (or the environment) times the weights
/// of the bounces before it. Each weight averages at most the material's
/// albedo (`albedo`, `diffuse + specular`, `reflectance`, or `tint` at a
/// refraction), so a scene whose albedos are all at most 1 is bounded by
/// its brightest emission at any depth. An albedo `g` above 1 multiplies
/// light by up to `g` at every bounce: `g^max_depth` overflows the film's
/// 32-bit sums long before a deep path ends (albedo 2 at depth 1000 rendered
/// 7.8e33 and an infinite variance). Refraction scales radiance by the
/// squared ratio of the indices on either side; along a path these factors
/// telescope (in by 1/ior², out by ior²), so they add at most the largest
/// `max(ior, 1/ior)²` once. The bound, brightest emission × that factor ×
/// `g^max_depth`, must stay within [`MAX_PATH_RADIANCE`].
///
/// On error, the material and key to change, and the reason with the
/// figures and the largest value that would pass.
pub(crate) fn check_path_gain(
    materials: &[Material],
    environment: Vec3,
    max_depth: u32,
) -> Result<(), GainError> {
    // Find the brightest emission, the strongest albedo and the widest index ratio
    let mut emission = (
        f64::from(environment.max_element()),
        String::from("environment.radiance"),
    );
    let mut gain = (1.0f64, 0, "albedo");
    let mut index = (1.0f64, 0);
    for (i, m) in materials.iter().enumerate() {
        let e = f64::from(m.emission.max_element());
        if e > emission.0 {
            emission = (e, format!("materials.{}.emission", m.name));
        }
        let (g, field) = kind_gain(&m.kind, i, &mut index);
        if g > gain.0 {
            gain = (g, i, field);
        }
    }
    if emission.0 <= 0.0 {
        return Ok(());
    }

    // Bound the radiance of the brightest path, in logarithms (it can overflow f64)
    let ln_limit = MAX_PATH_RADIANCE.ln();
    let ln_emission = emission.0.ln();
    let ln_index = 2.0 * index.0.ln();
    let ln_gain = gain.0.ln();
    let ln_bound = ln_emission + ln_index + f64::from(max_depth) * ln_gain;
    if ln_bound <= ln_limit {
        return Ok(());
    }
    let bound = format_exp(ln_bound);
    let source = format!(
        "with the brightest emission {} ({})",
        emission.0 as f32, emission.1
    );
    if gain.0 > 1.0 {
        // The albedo compounds with depth: say how deep it may go, or how strong it may be
        let depth = ((ln_limit - ln_emission - ln_index) / ln_gain).floor();
        let fix = if depth >= 1.0 {
            format!("lower it to at most 1, or render.max_depth to at most {depth}")
        } else {
            String::from("lower it to at most 1")
        };
        return Err(GainError {
            material: gain.1,
            field: gain.2,
            reason: format!(
                "a component of {} amplifies light at every bounce: over max_depth {max_depth} \
                 bounces, {source}, a path could carry radiance up to {bound}, above lancer's \
                 limit of {MAX_PATH_RADIANCE:e} for a path (radiance and its square are summed in \
                 32-bit floats; see \"Light that grows along a path\" in docs/scene-format.md); \
                 {fix}",
                gain.0 as f32
            ),
        });
    }
    // Only the index ratio (and the emission) remain
    let most = ((ln_limit - ln_emission) / 2.0).exp();
    Err(GainError {
        material: index.1,
        field: "ior",
        reason: format!(
            "a path crossing this dielectric's surface has its radiance scaled by up to \
             max(ior, 1/ior)^2 = {}; {source}, a path could carry radiance up to {bound}, above \
             lancer's limit of {MAX_PATH_RADIANCE:e} for a path; keep max(ior, 1/ior) at most {}, or lower the \
             emission",
            format_exp(ln_index),
            format_exp(most.ln())
        ),
    })
}

/// The largest factor material `i`'s scattering part puts on a path, and
/// the field that sets it; a dielectric's index ratio widens `index`.
fn kind_gain(kind: &MaterialKind, i: usize, index: &mut (f64, usize)) -> (f64, &'static str) {
    match kind {
        // A mixture is at most its stronger component
        MaterialKind::Blend { components, .. } => {
            let [a, b] = &**components;
            larger(kind_gain(a, i, index), kind_gain(b, i, index))
        }
        MaterialKind::Lambert { albedo } => (color_gain(albedo), "albedo"),
        // The stronger of the base colour (diffuse, metal) and the
        // dielectric Fresnel term (at most 1), as for a plastic. Disney's
        // diffuse lobe is not darkened by the specular one's Fresnel term,
        // so the albedo can pass this by a few percent at grazing angles:
        // well inside the limit's margin
        MaterialKind::Principled(p) => {
            larger((color_gain(&p.base_color), "base_color"), (1.0, "specular"))
        }
        MaterialKind::Phong {
            diffuse, specular, ..
        } => match diffuse {
            ColorSource::Constant(d) => (f64::from((*d + *specular).max_element()), "specular"),
            // Textures are 8-bit sRGB: at most 1.
            ColorSource::Texture(_) | ColorSource::Mapped(_) | ColorSource::Attribute(_) => (
                color_gain(diffuse) + f64::from(specular.max_element()),
                "specular",
            ),
        },
        MaterialKind::Mirror { reflectance } | MaterialKind::Glossy { reflectance, .. } => {
            (f64::from(reflectance.max_element()), "reflectance")
        }
        // The Fresnel term is at most 1
        MaterialKind::Conductor {
            specular_reflectance,
            ..
        }
        | MaterialKind::RoughConductor {
            specular_reflectance,
            ..
        } => (
            f64::from(specular_reflectance.max_element()),
            "specular_reflectance",
        ),
        MaterialKind::Dielectric { ior, tint } => {
            let ior = f64::from(*ior);
            let ratio = ior.max(1.0 / ior);
            if ratio > index.0 {
                *index = (ratio, i);
            }
            (f64::from(tint.max_element()), "tint")
        }
        // Reflection and refraction share the light (F and 1 - F), and
        // the microfacets lose some: at most the larger factor
        MaterialKind::RoughDielectric {
            ior,
            specular_reflectance,
            specular_transmittance,
            ..
        } => {
            let ior = f64::from(*ior);
            let ratio = ior.max(1.0 / ior);
            if ratio > index.0 {
                *index = (ratio, i);
            }
            larger(
                (
                    f64::from(specular_reflectance.max_element()),
                    "specular_reflectance",
                ),
                (
                    f64::from(specular_transmittance.max_element()),
                    "specular_transmittance",
                ),
            )
        }
        // Reflection and transmission share the light (R' and 1 - R'),
        // and the direction is unchanged: no 1 / ior^2
        MaterialKind::ThinDielectric {
            specular_reflectance,
            specular_transmittance,
            ..
        } => larger(
            (
                f64::from(specular_reflectance.max_element()),
                "specular_reflectance",
            ),
            (
                f64::from(specular_transmittance.max_element()),
                "specular_transmittance",
            ),
        ),
        // The coating's Fresnel term shares the light between the layers
        MaterialKind::Plastic {
            diffuse_reflectance,
            specular_reflectance,
            ..
        }
        | MaterialKind::RoughPlastic {
            diffuse_reflectance,
            specular_reflectance,
            ..
        } => larger(
            (color_gain(diffuse_reflectance), "diffuse_reflectance"),
            (
                f64::from(specular_reflectance.max_element()),
                "specular_reflectance",
            ),
        ),
    }
}

/// The larger of two (factor, field name) pairs, the first on a tie.
fn larger(a: (f64, &'static str), b: (f64, &'static str)) -> (f64, &'static str) {
    if a.0 >= b.0 {
        a
    } else {
        b
    }
}

/// Largest component a colour (or an 8-bit sRGB texture, at most 1) can have.
fn color_gain(c: &ColorSource) -> f64 {
    match c {
        ColorSource::Constant(c) => f64::from(c.max_element()),
        ColorSource::Texture(_) => 1.0,
        ColorSource::Mapped(m) => match &m.pattern {
            TexturePattern::Bitmap(_) => 1.0,
            TexturePattern::Checkerboard { color0, color1 } => {
                f64::from(color0.max(*color1).max_element())
            }
        },
        // The XML loader refuses attribute colours (times their scale)
        // above 1 where they are read as colours
        ColorSource::Attribute(_) => 1.0,
    }
}

/// `e^ln` written as `m.mmme±x`, also where it overflows an f64.
fn format_exp(ln: f64) -> String {
    let log10 = ln / std::f64::consts::LN_10;
    let mut exponent = log10.floor();
    let mut mantissa = (10f64.powf(log10 - exponent) * 100.0).round() / 100.0;
    if mantissa >= 10.0 {
        mantissa /= 10.0;
        exponent += 1.0;
    }
    format!("{mantissa:.2}e{exponent}")
}

/// Checks one delta light as every loader must: finite coordinates, a unit
/// (non-zero) direction, colours finite, >= 0 and within [`MAX_RADIANCE`],
/// spot angles with 0 < cutoff < 180 and 0 <= beam width <= cutoff (degrees).
///
/// On error, the key at fault (`position`, `direction`, `intensity`,
/// `irradiance`, `cutoff_angle`, `beam_width`, `to_world`, and a
/// projector's `scale` and `fov`) and the reason.
pub(crate) fn check_light(light: &DeltaLight) -> Result<(), (&'static str, String)> {
    let color = |key: &'static str, c: Vec3| {
        if !c.is_finite() || c.min_element() < 0.0 {
            Err((key, format!("must be finite and >= 0, got {c}")))
        } else if f64::from(c.max_element()) > MAX_RADIANCE {
            Err((key, format!("must be at most {MAX_RADIANCE:e}, got {c}")))
        } else {
            Ok(())
        }
    };
    let point = |p: Vec3| {
        if p.is_finite() {
            check_coordinates("the light", [p.as_dvec3()]).map_err(|r| ("position", r))
        } else {
            Err(("position", format!("must be finite, got {p}")))
        }
    };
    match *light {
        DeltaLight::Point {
            position,
            intensity,
        } => {
            point(position)?;
            color("intensity", intensity)
        }
        DeltaLight::Projector {
            position,
            to_local,
            ref irradiance,
            scale,
            cot_x,
            cot_y,
        } => {
            point(position)?;
            if let ColorSource::Constant(c) = irradiance {
                color("irradiance", *c)?;
            }
            if !(scale.is_finite() && scale >= 0.0) || f64::from(scale) > MAX_RADIANCE {
                return Err((
                    "scale",
                    format!("must be finite, >= 0 and at most {MAX_RADIANCE:e}, got {scale}"),
                ));
            }
            if !(to_local.is_finite() && to_local.determinant() != 0.0) {
                return Err(("to_world", String::from("must be invertible and finite")));
            }
            if !(cot_x.is_finite() && cot_x > 0.0 && cot_y.is_finite() && cot_y > 0.0) {
                return Err((
                    "fov",
                    String::from("must be > 0 and < 180 degrees on both axes"),
                ));
            }
            Ok(())
        }
        DeltaLight::Spot {
            position,
            to_local,
            intensity,
            cutoff_deg,
            beam_width_deg,
            ..
        } => {
            point(position)?;
            color("intensity", intensity)?;
            if !(to_local.is_finite() && to_local.determinant() != 0.0) {
                return Err(("to_world", String::from("must be invertible and finite")));
            }
            if !(cutoff_deg > 0.0 && cutoff_deg < 180.0) {
                return Err((
                    "cutoff_angle",
                    format!("must be > 0 and < 180 degrees, got {cutoff_deg}"),
                ));
            }
            if !(beam_width_deg >= 0.0 && beam_width_deg <= cutoff_deg) {
                return Err((
                    "beam_width",
                    format!(
                        "must be >= 0 and at most cutoff_angle ({cutoff_deg} degrees), got \
                         {beam_width_deg}"
                    ),
                ));
            }
            Ok(())
        }
        DeltaLight::Directional {
            direction,
            irradiance,
        } => {
            if !(direction.is_finite() && (direction.length() - 1.0).abs() < 1e-4) {
                return Err((
                    "direction",
                    format!("must be a finite non-zero vector, got {direction}"),
                ));
            }
            color("irradiance", irradiance)
        }
    }
}
