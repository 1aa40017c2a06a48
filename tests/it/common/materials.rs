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
        opacity: None,
        normal_map: None,
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

/// Fresnel reflectance of a conductor of complex index `eta + i k` for
/// unpolarised light at `cos_i`, from the complex amplitudes of the s and
/// p waves (a separate derivation from the kernels' closed form).
pub fn fresnel_conductor(cos_i: f64, eta: f64, k: f64) -> f64 {
    // Complex numbers as (re, im)
    let mul = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let norm2 = |a: (f64, f64)| a.0 * a.0 + a.1 * a.1;
    let sqrt = |a: (f64, f64)| {
        let r = norm2(a).sqrt().sqrt();
        let phi = a.1.atan2(a.0) / 2.0;
        (r * phi.cos(), r * phi.sin())
    };
    let n2 = mul((eta, k), (eta, k));
    let sin2 = 1.0 - cos_i * cos_i;
    // n cos(theta_t) = sqrt(n^2 - sin^2)
    let nct = sqrt((n2.0 - sin2, n2.1));
    let ratio = |num: (f64, f64), den: (f64, f64)| norm2(num) / norm2(den);
    let r_s = ratio((cos_i - nct.0, -nct.1), (cos_i + nct.0, nct.1));
    let n2c = (n2.0 * cos_i, n2.1 * cos_i);
    let r_p = ratio(
        (n2c.0 - nct.0, n2c.1 - nct.1),
        (n2c.0 + nct.0, n2c.1 + nct.1),
    );
    0.5 * (r_s + r_p)
}
