//! What the device can represent: the limits a scene is checked against
//! when it is read, and again when it is packed for the device (the command
//! line may change the image size after reading).
//!
//! The device works in 32-bit floats and 32-bit integers. A value that is
//! valid in the scene file's 64-bit numbers can collapse there (a camera
//! basis built from vectors of length 1e-30) or overflow (a pixel count of
//! 65536 x 65536). Every check here says what the device would get and why
//! it cannot use it; `docs/scene-format.md` states the same limits.

use super::types::Camera;
use glam::{DVec3, Vec3};

/// Most pixels per side. Pixel positions are f32 on the device; below 2^20
/// they keep 1/16 pixel of sub-pixel jitter, so every sample stays in its
/// own stratum of its own pixel.
pub const MAX_IMAGE_SIDE: u32 = 1 << 20;

/// Most pixels in an image. The kernels index pixels and path slots in
/// 32-bit integers (`pixel + slot`, `slot + pixel_count`), so the pixel
/// count plus the paths in flight (at most 2^28, the widest binding) must
/// stay below 2^32.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 31;

/// Most texels in one texture (4096 x 4096, or any shape of that area).
/// Checked from the file's header, before its pixels are decoded, so that
/// a small file claiming a huge image costs nothing: a texture's decoded
/// pixels take up to 16 bytes each (RGBA in 32-bit floats) before they are
/// packed into the device's buffer as 4-byte sRGB texels.
pub const MAX_TEXTURE_TEXELS: u64 = 1 << 24;

/// Largest emission or environment radiance component. Radiance, its square
/// (the film's variance) and their sums over the samples of a pixel are
/// 32-bit floats on the device (largest 3.4e38). 1e12 squared and summed
/// over a million samples per pixel gives 1e30, leaving eight orders of
/// magnitude for the factors that multiply emission along a path (area over
/// squared distance in light sampling, Russian roulette, eta^2).
pub const MAX_RADIANCE: f64 = 1e12;

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
                 {MAX_IMAGE_PIXELS} pixels (2^31); lower the width or height"
            ),
        ));
    }
    // `pixels` <= 2^31 fits.
    Ok(pixels as u32)
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
