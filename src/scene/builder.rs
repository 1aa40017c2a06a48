//! [`SceneBuilder`]: a scene built in code, checked as a scene file is.
//!
//! The builder fills the same plain types that [`load`](super::load) returns.
//! A scene built with it renders the same image, bit for bit, as the TOML
//! file that says the same thing (quads are split into triangles by the
//! function the file reader uses). [`SceneBuilder::build`] checks what
//! [`load`](super::load) checks on the values themselves (image size,
//! camera, colour and radiance ranges, material parameters, object sizes,
//! material names) and names the key at fault in the same dotted form,
//! e.g. `objects[2].material`.

use super::limits::{self, MAX_RADIANCE};
use super::types::*;
use super::SceneError;
use glam::{DVec3, Vec2, Vec3};
use std::collections::HashMap;
use std::path::PathBuf;

/// What [`Scene::source`] holds for a scene built in code; errors name it
/// in place of a file.
pub const BUILT_SOURCE: &str = "(scene built in code)";

/// Slack for `diffuse + specular <= 1` in Phong materials, so that
/// 0.6 + 0.4 passes.
pub(crate) const ENERGY_SLACK: f64 = 1e-6;

/// Builds a [`Scene`] in code. Every setter takes the builder by value and
/// returns it; [`build`](Self::build) checks the whole scene.
///
/// Defaults are the scene format's: `max_depth` 8, seed 0, a black
/// environment, `up` = +y, a pinhole camera focused at `look_at`.
///
/// ```no_run
/// use lancer::scene::{MaterialKind, SceneBuilder};
/// use lancer::Vec3;
///
/// let scene = SceneBuilder::new(64, 64, 16)
///     .camera(Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 1.0, 0.0), 40.0)
///     .material("grey", MaterialKind::lambert(Vec3::splat(0.5)))
///     .sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, "grey")
///     .build()?;
/// # Ok::<(), lancer::scene::SceneError>(())
/// ```
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    render: RenderSettings,
    camera: Option<Camera>,
    environment: Rgb,
    materials: Vec<Material>,
    objects: Vec<Object>,
    lights: Vec<DeltaLight>,
}

/// An object as given, with its material still a name.
#[derive(Debug, Clone)]
enum Object {
    Sphere {
        center: Vec3,
        radius: f32,
        material: String,
    },
    Quad {
        origin: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
        material: String,
    },
    Triangle {
        p: [Vec3; 3],
        material: String,
    },
}

impl MaterialKind {
    /// A Lambertian material of constant albedo.
    pub fn lambert(albedo: Rgb) -> MaterialKind {
        MaterialKind::Lambert {
            albedo: ColorSource::Constant(albedo),
        }
    }

    /// A normalised Phong material of constant diffuse colour.
    pub fn phong(diffuse: Rgb, specular: Rgb, exponent: f32) -> MaterialKind {
        MaterialKind::Phong {
            diffuse: ColorSource::Constant(diffuse),
            specular,
            exponent,
        }
    }

    /// A perfect mirror.
    pub fn mirror(reflectance: Rgb) -> MaterialKind {
        MaterialKind::Mirror { reflectance }
    }

    /// Glossy reflection in a cone of `cone_angle_deg` degrees.
    pub fn glossy(reflectance: Rgb, cone_angle_deg: f32) -> MaterialKind {
        MaterialKind::Glossy {
            reflectance,
            cone_angle_deg,
        }
    }

    /// A smooth conductor of complex index of refraction `ior`.
    pub fn conductor(ior: ComplexIor) -> MaterialKind {
        MaterialKind::Conductor {
            ior,
            specular_reflectance: Vec3::ONE,
        }
    }

    /// A rough conductor of complex index of refraction `ior` with the
    /// roughness `alpha_u` along the tangent and `alpha_v` along the bitangent.
    pub fn rough_conductor(
        distribution: Microfacet,
        alpha_u: f32,
        alpha_v: f32,
        ior: ComplexIor,
    ) -> MaterialKind {
        MaterialKind::RoughConductor {
            distribution,
            alpha_u,
            alpha_v,
            alpha_textures: None,
            ior,
            specular_reflectance: Vec3::ONE,
        }
    }

    /// A clear dielectric (tint 1) of index of refraction `ior`.
    pub fn dielectric(ior: f32) -> MaterialKind {
        MaterialKind::Dielectric {
            ior,
            tint: Vec3::ONE,
        }
    }
}

impl SceneBuilder {
    /// A scene of `width` x `height` pixels at `spp` samples per pixel,
    /// with nothing in it yet. A camera must be set before
    /// [`build`](Self::build).
    pub fn new(width: u32, height: u32, spp: u32) -> SceneBuilder {
        SceneBuilder {
            render: RenderSettings {
                width,
                height,
                spp,
                max_depth: 8,
                seed: 0,
                rr_depth: DEFAULT_RR_DEPTH,
                filter: PixelFilter::Box,
                filter_inside_film: false,
                hide_emitters: false,
                emitter_sampling_only: false,
                bsdf_sampling_only: false,
                delta_light_gain: 1,
            },
            camera: None,
            environment: Vec3::ZERO,
            materials: Vec::new(),
            objects: Vec::new(),
            lights: Vec::new(),
        }
    }

    /// Longest path in segments from the camera (`render.max_depth`).
    pub fn max_depth(mut self, max_depth: u32) -> Self {
        self.render.max_depth = max_depth;
        self
    }

    /// The pixel reconstruction filter (`render.filter`; box by default).
    pub fn filter(mut self, filter: PixelFilter) -> Self {
        self.render.filter = filter;
        self
    }

    /// Seed of every random number (`render.seed`).
    pub fn seed(mut self, seed: u32) -> Self {
        self.render.seed = seed;
        self
    }

    /// A pinhole camera at `eye` looking at `look_at`, with a vertical field
    /// of view of `vfov_deg` degrees and +y up.
    pub fn camera(mut self, eye: Vec3, look_at: Vec3, vfov_deg: f32) -> Self {
        self.camera = Some(Camera {
            eye,
            look_at,
            up: Vec3::Y,
            vfov_deg,
            aperture_radius: 0.0,
            focus_distance: (look_at.as_dvec3() - eye.as_dvec3()).length() as f32,
            near_clip: 0.0,
            far_clip: f32::INFINITY,
            shift: [0.0; 2],
            orthographic: None,
        });
        self
    }

    /// The camera, with every field given (`up`, thin lens).
    pub fn camera_full(mut self, camera: Camera) -> Self {
        self.camera = Some(camera);
        self
    }

    /// Constant radiance of every ray that escapes (`environment.radiance`).
    pub fn environment(mut self, radiance: Rgb) -> Self {
        self.environment = radiance;
        self
    }

    /// A light with no area (point, spot or directional).
    pub fn light(mut self, light: DeltaLight) -> Self {
        self.lights.push(light);
        self
    }

    /// A material that does not emit, named for the objects to use.
    pub fn material(self, name: &str, kind: MaterialKind) -> Self {
        self.emitter(name, kind, Vec3::ZERO)
    }

    /// A material that emits `emission` from its front side.
    pub fn emitter(mut self, name: &str, kind: MaterialKind, emission: Rgb) -> Self {
        self.materials.push(Material {
            name: name.to_string(),
            kind,
            emission,
            sides: Sides::Both,
            opacity: None,
            normal_map: None,
        });
        self
    }

    /// A sphere.
    pub fn sphere(mut self, center: Vec3, radius: f32, material: &str) -> Self {
        self.objects.push(Object::Sphere {
            center,
            radius,
            material: material.to_string(),
        });
        self
    }

    /// A parallelogram with corners `origin`, `origin + edge_u`,
    /// `origin + edge_u + edge_v` and `origin + edge_v`; its front side is
    /// the one `edge_u x edge_v` points to.
    pub fn quad(mut self, origin: Vec3, edge_u: Vec3, edge_v: Vec3, material: &str) -> Self {
        self.objects.push(Object::Quad {
            origin,
            edge_u,
            edge_v,
            material: material.to_string(),
        });
        self
    }

    /// A triangle, counter-clockwise seen from its front side, without
    /// shading normals or texture coordinates.
    pub fn triangle(mut self, p: [Vec3; 3], material: &str) -> Self {
        self.objects.push(Object::Triangle {
            p,
            material: material.to_string(),
        });
        self
    }

    /// Checks the scene and returns it. The error names the key at fault
    /// (`render.width`, `camera.up`, `materials.glass.ior`,
    /// `objects[3].material`, ...) and says what to change.
    pub fn build(self) -> Result<Scene, SceneError> {
        self.render
            .check()
            .map_err(|(key, reason)| invalid(&render_key(key), reason))?;
        let camera = self.camera.clone().ok_or_else(|| {
            invalid(
                "camera",
                "no camera; call .camera(eye, look_at, vfov) before .build()",
            )
        })?;
        check_camera(&camera)?;
        check_radiance("environment.radiance", self.environment)?;

        let mut by_name = HashMap::new();
        for (i, m) in self.materials.iter().enumerate() {
            check_material(m)?;
            if by_name.insert(m.name.clone(), i as u32).is_some() {
                return Err(invalid(
                    &format!("materials.{}", m.name),
                    "is defined twice; give each material its own name",
                ));
            }
        }
        let mut spheres = Vec::new();
        let mut triangles = Vec::new();
        for (i, object) in self.objects.iter().enumerate() {
            let key = |field: &str| format!("objects[{i}].{field}");
            let (Object::Sphere { material, .. }
            | Object::Quad { material, .. }
            | Object::Triangle { material, .. }) = object;
            let index = *by_name
                .get(material)
                .ok_or_else(|| invalid(&key("material"), unknown_material(material, &by_name)))?;
            match *object {
                Object::Sphere { center, radius, .. } => {
                    check_finite(&key("center"), center)?;
                    check_positive(&key("radius"), radius)?;
                    let (c, r) = (center.as_dvec3(), f64::from(radius));
                    limits::check_coordinates("the sphere", [c - r, c + r])
                        .map_err(|reason| invalid(&key("radius"), reason))?;
                    limits::check_sphere_clearance(camera.eye.as_dvec3(), c, r)
                        .map_err(|reason| invalid(&key("radius"), reason))?;
                    spheres.push(Sphere {
                        center,
                        radius,
                        material: index,
                        mitsuba_frame: None,
                    });
                }
                Object::Quad {
                    origin,
                    edge_u,
                    edge_v,
                    ..
                } => {
                    for (field, v) in [("origin", origin), ("edge_u", edge_u), ("edge_v", edge_v)] {
                        check_finite(&key(field), v)?;
                    }
                    let (o, u, v) = (origin.as_dvec3(), edge_u.as_dvec3(), edge_v.as_dvec3());
                    limits::check_coordinates("the quad", [o, o + u, o + u + v, o + v])
                        .map_err(|reason| invalid(&key("origin"), reason))?;
                    let pair = quad_triangles(
                        origin.as_dvec3(),
                        edge_u.as_dvec3(),
                        edge_v.as_dvec3(),
                        index,
                    )
                    .ok_or_else(|| invalid(&key("edge_v"), ZERO_AREA_QUAD))?;
                    triangles.extend(pair);
                }
                Object::Triangle { p, .. } => {
                    check_finite(&key("p"), p[0])?;
                    check_finite(&key("p"), p[1])?;
                    check_finite(&key("p"), p[2])?;
                    limits::check_coordinates("the triangle", p.map(|v| v.as_dvec3()))
                        .map_err(|reason| invalid(&key("p"), reason))?;
                    triangles.push(Triangle {
                        p,
                        n: None,
                        uv: None,
                        material: index,
                        attribute: None,
                    });
                }
            }
        }
        for (i, light) in self.lights.iter().enumerate() {
            limits::check_light(light)
                .map_err(|(key, reason)| invalid(&format!("lights[{i}].{key}"), reason))?;
        }
        limits::check_path_gain(&self.materials, self.environment, self.render.max_depth)
            .map_err(|e| invalid(&e.key(&self.materials), e.reason))?;
        Ok(Scene {
            render: self.render,
            camera,
            environment: self.environment,
            envmap: None,
            materials: self.materials,
            spheres,
            triangles,
            mesh_attributes: Vec::new(),
            lights: self.lights,
            source: PathBuf::from(BUILT_SOURCE),
            includes: Vec::new(),
            files: Vec::new(),
            warnings: Vec::new(),
        })
    }
}

/// Why a quad is refused when its edges span no area.
pub(crate) const ZERO_AREA_QUAD: &str =
    "the quad has zero area: edge_u and edge_v must be non-zero and not parallel";

/// The two triangles of a quad (corners `a = origin`, `b = a + edge_u`,
/// `c = b + edge_v`, `d = a + edge_v`), with texture coordinates running
/// 0 to 1 along the edges; `None` when the quad has no area. The one place
/// a quad becomes triangles, for scene files and for the builder alike.
pub(crate) fn quad_triangles(
    origin: DVec3,
    edge_u: DVec3,
    edge_v: DVec3,
    material: u32,
) -> Option<[Triangle; 2]> {
    let (a, b, c, d) = (
        origin.as_vec3(),
        (origin + edge_u).as_vec3(),
        (origin + edge_u + edge_v).as_vec3(),
        (origin + edge_v).as_vec3(),
    );
    let area = (b.as_dvec3() - a.as_dvec3())
        .cross(d.as_dvec3() - a.as_dvec3())
        .length();
    let scale = edge_u.length() * edge_v.length();
    if area <= 1e-9 * scale || !area.is_finite() {
        return None;
    }
    let uv = |u: f32, v: f32| Vec2::new(u, v);
    Some([
        Triangle {
            p: [a, b, c],
            n: None,
            uv: Some([uv(0.0, 0.0), uv(1.0, 0.0), uv(1.0, 1.0)]),
            material,
            attribute: None,
        },
        Triangle {
            p: [a, c, d],
            n: None,
            uv: Some([uv(0.0, 0.0), uv(1.0, 1.0), uv(0.0, 1.0)]),
            material,
            attribute: None,
        },
    ])
}

/// An error about `key` in a scene built in code.
fn invalid(key: &str, reason: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        path: PathBuf::from(BUILT_SOURCE),
        line: None,
        key: key.to_string(),
        reason: reason.into(),
    }
}

/// `render.KEY`.
fn render_key(key: &str) -> String {
    format!("render.{key}")
}

/// The reason for a material name that no material has.
fn unknown_material(name: &str, by_name: &HashMap<String, u32>) -> String {
    let mut names: Vec<&str> = by_name.keys().map(String::as_str).collect();
    names.sort_unstable();
    if names.is_empty() {
        format!("no material named `{name}`: add one with .material(\"{name}\", ...) first")
    } else {
        format!(
            "no material named `{name}`; defined materials: {}",
            names.join(", ")
        )
    }
}

fn check_finite(key: &str, v: Vec3) -> Result<(), SceneError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(invalid(key, format!("must be finite, got {v}")))
    }
}

/// Finite, every component >= 0.
/// Checks that `v` is above 0 and finite (a radius, an index of
/// refraction, a roughness, a distance), naming `key`.
fn check_positive(key: &str, v: f32) -> Result<(), SceneError> {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err(invalid(key, format!("must be > 0 and finite, got {v}")))
    }
}

/// Checks that a plastic's diffuse and specular reflectances are not both
/// black (a constant diffuse only: a texture may hold colour).
fn check_plastic_not_black(
    key: &str,
    diffuse_reflectance: &ColorSource,
    specular_reflectance: Rgb,
) -> Result<(), SceneError> {
    if let ColorSource::Constant(d) = diffuse_reflectance {
        if (*d + specular_reflectance).max_element() <= 0.0 {
            return Err(invalid(
                key,
                "and specular_reflectance are both black; give one a colour (or use a black diffuse)",
            ));
        }
    }
    Ok(())
}

fn check_color(key: &str, c: Rgb) -> Result<(), SceneError> {
    check_finite(key, c)?;
    if c.min_element() < 0.0 {
        return Err(invalid(
            key,
            format!("colour components must be >= 0, got {c}"),
        ));
    }
    Ok(())
}

/// A colour whose components are at most [`MAX_RADIANCE`].
fn check_radiance(key: &str, c: Rgb) -> Result<(), SceneError> {
    check_color(key, c)?;
    if c.max_element() as f64 > MAX_RADIANCE {
        return Err(invalid(
            key,
            format!(
                "radiance components must be <= {MAX_RADIANCE:e} (sums of radiance and its \
                 square must stay inside 32-bit floats), got {c}; scale every emission and \
                 the environment down by the same factor"
            ),
        ));
    }
    Ok(())
}

/// The camera's ranges and its basis as the device builds it.
fn check_camera(c: &Camera) -> Result<(), SceneError> {
    for (key, v) in [
        ("camera.eye", c.eye),
        ("camera.look_at", c.look_at),
        ("camera.up", c.up),
    ] {
        check_finite(key, v)?;
    }
    if !(c.vfov_deg > 0.0 && c.vfov_deg < 180.0) {
        return Err(invalid(
            "camera.vfov",
            format!("must be > 0 and < 180 (degrees), got {}", c.vfov_deg),
        ));
    }
    c.basis()
        .map_err(|(key, reason)| invalid(&format!("camera.{key}"), reason))?;
    if !(c.aperture_radius >= 0.0 && c.aperture_radius.is_finite()) {
        return Err(invalid(
            "camera.aperture_radius",
            format!("must be >= 0 and finite, got {}", c.aperture_radius),
        ));
    }
    check_positive("camera.focus_distance", c.focus_distance)?;
    if !(c.near_clip >= 0.0 && c.near_clip.is_finite() && c.far_clip > c.near_clip) {
        return Err(invalid(
            "camera.near_clip",
            format!(
                "must be >= 0, finite and below camera.far_clip, got {} and {}",
                c.near_clip, c.far_clip
            ),
        ));
    }
    Ok(())
}

/// A material's colours and parameters, in the ranges of the scene format.
fn check_material(m: &Material) -> Result<(), SceneError> {
    check_radiance(&format!("materials.{}.emission", m.name), m.emission)?;
    check_kind(&m.name, &m.kind)
}

/// Checks the scattering part of material `name` (a blend's components
/// as `name.bsdf0` and `name.bsdf1`).
fn check_kind(name: &str, kind: &MaterialKind) -> Result<(), SceneError> {
    let key = |field: &str| format!("materials.{name}.{field}");
    match kind {
        MaterialKind::Blend { weight, components } => {
            check_source(&key("weight"), weight)?;
            for (k, c) in components.iter().enumerate() {
                if matches!(c, MaterialKind::Blend { .. } | MaterialKind::Glossy { .. })
                    || c.transmits()
                {
                    return Err(invalid(
                        &key(&format!("bsdf{k}")),
                        "a blend's components are not glossy cones, do not transmit and are not \
                         blends",
                    ));
                }
                check_kind(&format!("{name}.bsdf{k}"), c)?;
            }
            Ok(())
        }
        MaterialKind::Lambert { albedo } => check_source(&key("albedo"), albedo),
        MaterialKind::Principled(p) => {
            check_source(&key("base_color"), &p.base_color)?;
            for (field, v) in Principled::WEIGHT_NAMES.into_iter().zip(p.weights()) {
                match p.weight_texture(field) {
                    Some(t) => check_source(&key(field), t)?,
                    None if !(0.0..=1.0).contains(&v) => {
                        return Err(invalid(&key(field), format!("must lie in [0, 1], got {v}")))
                    }
                    None => {}
                }
            }
            check_positive(&key("eta"), p.eta)?;
            let rates = p.sampling_rates;
            if !rates.iter().all(|r| *r >= 0.0 && r.is_finite()) || p.may_sample_nothing() {
                return Err(invalid(
                    &key("sampling_rates"),
                    format!(
                        "the lobes' sampling rates must be >= 0 and finite, and give some lobe \
                         a chance, got {rates:?}"
                    ),
                ));
            }
            Ok(())
        }
        MaterialKind::Phong {
            diffuse,
            specular,
            exponent,
        } => {
            check_source(&key("diffuse"), diffuse)?;
            check_color(&key("specular"), *specular)?;
            if !(*exponent >= 0.0 && exponent.is_finite()) {
                return Err(invalid(
                    &key("exponent"),
                    format!("must be >= 0 and finite, got {exponent}"),
                ));
            }
            let d = match diffuse {
                ColorSource::Constant(d) => *d,
                ColorSource::Texture(_) | ColorSource::Mapped(_) | ColorSource::Attribute(_) => {
                    Vec3::ZERO
                }
            };
            let sum = d.as_dvec3() + specular.as_dvec3();
            if sum.max_element() > 1.0 + ENERGY_SLACK {
                return Err(invalid(
                    &key("specular"),
                    format!(
                        "diffuse + specular must be <= 1 in every channel (the material would \
                         create energy), got {d} + {specular}; lower diffuse or specular"
                    ),
                ));
            }
            Ok(())
        }
        MaterialKind::Mirror { reflectance } => check_color(&key("reflectance"), *reflectance),
        MaterialKind::Glossy {
            reflectance,
            cone_angle_deg,
        } => {
            check_color(&key("reflectance"), *reflectance)?;
            if !(0.0..90.0).contains(cone_angle_deg) {
                return Err(invalid(
                    &key("cone_angle"),
                    format!("must be >= 0 and < 90 (degrees), got {cone_angle_deg}"),
                ));
            }
            Ok(())
        }
        MaterialKind::Dielectric { ior, tint } => {
            check_color(&key("tint"), *tint)?;
            check_positive(&key("ior"), *ior)?;
            Ok(())
        }
        MaterialKind::ThinDielectric {
            ior,
            specular_reflectance,
            specular_transmittance,
        } => {
            check_color(&key("specular_reflectance"), *specular_reflectance)?;
            check_color(&key("specular_transmittance"), *specular_transmittance)?;
            check_positive(&key("ior"), *ior)?;
            Ok(())
        }
        MaterialKind::Conductor {
            ior,
            specular_reflectance,
        } => {
            check_color(&key("eta"), ior.eta)?;
            check_color(&key("k"), ior.k)?;
            check_color(&key("specular_reflectance"), *specular_reflectance)
        }
        MaterialKind::RoughConductor {
            alpha_u,
            alpha_v,
            ior,
            specular_reflectance,
            ..
        } => {
            check_color(&key("eta"), ior.eta)?;
            check_color(&key("k"), ior.k)?;
            check_color(&key("specular_reflectance"), *specular_reflectance)?;
            for (field, a) in [("alpha_u", alpha_u), ("alpha_v", alpha_v)] {
                if !(*a >= 0.0 && a.is_finite()) {
                    return Err(invalid(
                        &key(field),
                        format!("must be >= 0 and finite, got {a}"),
                    ));
                }
            }
            Ok(())
        }
        MaterialKind::RoughDielectric {
            alpha_u,
            alpha_v,
            ior,
            specular_reflectance,
            specular_transmittance,
            ..
        } => {
            check_color(&key("specular_reflectance"), *specular_reflectance)?;
            check_color(&key("specular_transmittance"), *specular_transmittance)?;
            for (field, a) in [("alpha_u", alpha_u), ("alpha_v", alpha_v)] {
                if !(*a >= 0.0 && a.is_finite()) {
                    return Err(invalid(
                        &key(field),
                        format!("must be >= 0 and finite, got {a}"),
                    ));
                }
            }
            if !(*ior > 0.0 && ior.is_finite() && *ior != 1.0) {
                return Err(invalid(
                    &key("ior"),
                    format!(
                        "must be > 0, finite and not 1 (the half vector of a refraction is \
                         undefined at 1; Mitsuba refuses equal indices too), got {ior}"
                    ),
                ));
            }
            Ok(())
        }
        MaterialKind::Plastic {
            diffuse_reflectance,
            specular_reflectance,
            ior,
            ..
        } => {
            check_source(&key("diffuse_reflectance"), diffuse_reflectance)?;
            check_color(&key("specular_reflectance"), *specular_reflectance)?;
            check_plastic_not_black(
                &key("diffuse_reflectance"),
                diffuse_reflectance,
                *specular_reflectance,
            )?;
            check_positive(&key("ior"), *ior)?;
            Ok(())
        }
        MaterialKind::RoughPlastic {
            alpha,
            diffuse_reflectance,
            specular_reflectance,
            ior,
            ..
        } => {
            check_source(&key("diffuse_reflectance"), diffuse_reflectance)?;
            check_color(&key("specular_reflectance"), *specular_reflectance)?;
            check_plastic_not_black(
                &key("diffuse_reflectance"),
                diffuse_reflectance,
                *specular_reflectance,
            )?;
            check_positive(&key("alpha"), *alpha)?;
            if !(*ior > 0.0 && ior.is_finite() && *ior != 1.0) {
                return Err(invalid(
                    &key("ior"),
                    format!(
                        "must be > 0, finite and not 1 (Mitsuba refuses equal indices), got {ior}"
                    ),
                ));
            }
            Ok(())
        }
    }
}

/// A constant colour, or a texture file that exists.
fn check_source(key: &str, source: &ColorSource) -> Result<(), SceneError> {
    match source {
        ColorSource::Constant(c) => check_color(key, *c),
        ColorSource::Texture(path) if path.is_file() => Ok(()),
        ColorSource::Texture(path) => Err(invalid(
            &format!("{key}_texture"),
            format!(
                "{}: no such texture file",
                crate::util::text::cut_path(path)
            ),
        )),
        ColorSource::Mapped(m) => {
            if let TexturePattern::Checkerboard { color0, color1 } = &m.pattern {
                check_color(&format!("{key}.color0"), *color0)?;
                check_color(&format!("{key}.color1"), *color1)?;
            }
            if !m.to_uv.iter().all(|x| x.is_finite()) {
                return Err(invalid(
                    &format!("{key}.to_uv"),
                    format!("must be finite, got {:?}", m.to_uv),
                ));
            }
            match &m.pattern {
                TexturePattern::Bitmap(path) if !path.is_file() => Err(invalid(
                    &format!("{key}_texture"),
                    format!(
                        "{}: no such texture file",
                        crate::util::text::cut_path(path)
                    ),
                )),
                _ => Ok(()),
            }
        }
        ColorSource::Attribute(a) if a.scale.is_finite() => Ok(()),
        ColorSource::Attribute(a) => Err(invalid(
            &format!("{key}.scale"),
            format!("must be finite, got {}", a.scale),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A builder with a camera and one material, ready for objects.
    fn base() -> SceneBuilder {
        SceneBuilder::new(8, 8, 1)
            .camera(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 40.0)
            .material("grey", MaterialKind::lambert(Vec3::splat(0.5)))
    }

    fn key_of(result: Result<Scene, SceneError>) -> String {
        match result {
            Err(e) => e.key().unwrap_or("").to_string(),
            Ok(_) => panic!("the scene was accepted"),
        }
    }

    #[test]
    fn a_quad_becomes_the_two_triangles_the_file_reader_makes() {
        let scene = base()
            .quad(Vec3::ZERO, Vec3::X, Vec3::Y, "grey")
            .build()
            .unwrap();
        assert_eq!(scene.triangles.len(), 2);
        assert_eq!(
            scene.triangles[0].p,
            [Vec3::ZERO, Vec3::X, Vec3::ONE.with_z(0.0)]
        );
        assert_eq!(
            scene.triangles[1].p,
            [Vec3::ZERO, Vec3::ONE.with_z(0.0), Vec3::Y]
        );
        assert_eq!(scene.source, PathBuf::from(BUILT_SOURCE));
    }

    #[test]
    fn every_mistake_names_its_key() {
        let cases: Vec<(SceneBuilder, &str)> = vec![
            (
                base().sphere(Vec3::ZERO, 1.0, "gray"),
                "objects[0].material",
            ),
            (base().sphere(Vec3::ZERO, 0.0, "grey"), "objects[0].radius"),
            (
                base().quad(Vec3::ZERO, Vec3::X, Vec3::X * 2.0, "grey"),
                "objects[0].edge_v",
            ),
            (
                base().material("glass", MaterialKind::dielectric(0.0)),
                "materials.glass.ior",
            ),
            (
                base().material("g", MaterialKind::glossy(Vec3::ONE, 90.0)),
                "materials.g.cone_angle",
            ),
            (
                base().material(
                    "p",
                    MaterialKind::phong(Vec3::splat(0.6), Vec3::splat(0.5), 10.0),
                ),
                "materials.p.specular",
            ),
            (
                base().emitter("lamp", MaterialKind::lambert(Vec3::ZERO), Vec3::splat(1e13)),
                "materials.lamp.emission",
            ),
            (
                base().material("grey", MaterialKind::mirror(Vec3::ONE)),
                "materials.grey",
            ),
            (
                base().camera(Vec3::ZERO, Vec3::ZERO, 40.0),
                "camera.look_at",
            ),
            (base().camera(Vec3::ZERO, Vec3::Z, 180.0), "camera.vfov"),
            (SceneBuilder::new(8, 8, 1), "camera"),
            (SceneBuilder::new(0, 8, 1), "render.width"),
            (SceneBuilder::new(8, 8, 0), "render.spp"),
            (
                base().environment(Vec3::new(-1.0, 0.0, 0.0)),
                "environment.radiance",
            ),
            // Past the coordinate limit of 1e11.
            (
                base().sphere(Vec3::new(2e11, 0.0, 0.0), 1.0, "grey"),
                "objects[0].radius",
            ),
            (
                base().quad(Vec3::ZERO, Vec3::X * 2e11, Vec3::Y, "grey"),
                "objects[0].origin",
            ),
            (
                base().triangle([Vec3::ZERO, Vec3::X, Vec3::Y * -3e11], "grey"),
                "objects[0].p",
            ),
            // The eye on the surface of a sphere, as the device places it.
            (
                base().sphere(Vec3::new(0.0, 0.0, -1e7), 1e7 + 5.0, "grey"),
                "objects[0].radius",
            ),
            // Light that grows past the limit along a path.
            (
                base()
                    .environment(Vec3::ONE)
                    .material("hot", MaterialKind::lambert(Vec3::splat(1e3))),
                "materials.hot.albedo",
            ),
        ];
        for (i, (builder, key)) in cases.into_iter().enumerate() {
            assert_eq!(key_of(builder.build()), key, "case {i}");
        }
    }

    #[test]
    fn an_unknown_material_lists_the_defined_ones() {
        let err = base()
            .sphere(Vec3::ZERO, 1.0, "gray")
            .build()
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("no material named `gray`; defined materials: grey"),
            "{err}"
        );
        assert!(err.starts_with(BUILT_SOURCE), "{err}");
    }
}
