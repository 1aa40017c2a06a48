//! Materials for scenes built in code, and the exact Fresnel term the
//! dielectric tests check the kernels against.

use glam::Vec3;
use lancer::scene::{ColorSource, Material, MaterialKind, Sides};

/// A material named `name` of the given kind that emits nothing.
pub fn material(name: &str, kind: MaterialKind) -> Material {
    Material {
        name: name.into(),
        kind,
        emission: Vec3::ZERO,
        sides: Sides::Both,
    }
}

/// Lambert of a constant `albedo`.
pub fn lambert(albedo: Vec3) -> MaterialKind {
    MaterialKind::Lambert {
        albedo: ColorSource::Constant(albedo),
    }
}

/// Phong of a constant `diffuse` colour, a grey `specular` of that value in
/// every channel, and the given `exponent`.
pub fn phong(diffuse: Vec3, specular: f32, exponent: f32) -> MaterialKind {
    MaterialKind::Phong {
        diffuse: ColorSource::Constant(diffuse),
        specular: Vec3::splat(specular),
        exponent,
    }
}

/// Glossy of the given `reflectance` and cone angle in degrees.
pub fn glossy(reflectance: Vec3, cone_angle_deg: f32) -> MaterialKind {
    MaterialKind::Glossy {
        reflectance,
        cone_angle_deg,
    }
}

/// Fresnel reflectance of a smooth dielectric for unpolarised light at
/// `cos_i`, eta = eta_t / eta_i (1 beyond the critical angle).
pub fn fresnel(cos_i: f64, eta: f64) -> f64 {
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (r_s * r_s + r_p * r_p)
}
