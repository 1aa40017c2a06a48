//! Plain CPU scene types: what a scene file says, after validation.
//!
//! These are kept apart from the packed `Gpu*` structs in `crate::gpu`; the
//! one conversion between them lives in `crate::gpu::pack`.

use glam::Vec3;
use std::path::PathBuf;

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
    /// How many times each delta light's sample counts: 1, but for
    /// Mitsuba's `direct` integrator, which weighs each of its
    /// `emitter_samples` samples of a delta light by 1 rather than by 1 /
    /// `emitter_samples` (`src/integrators/direct.cpp`), so its point, spot
    /// and directional lights come out `emitter_samples` times brighter;
    /// lancer reproduces that to render what Mitsuba renders.
    pub delta_light_gain: u32,
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
}

/// A colour given either as a constant or as a texture file.
#[derive(Debug, Clone, PartialEq)]
pub enum ColorSource {
    /// A constant linear RGB colour.
    Constant(Rgb),
    /// An sRGB-encoded image file, resolved to an absolute or scene-relative path.
    Texture(PathBuf),
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
}

/// A light with no area: no ray hits it, so only next-event estimation
/// finds it. Mitsuba's `point`, `spot` and `directional`, or TOML's
/// `[[lights]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
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
    },
    /// Light from infinitely far away, arriving along one direction.
    Directional {
        /// Unit direction the light travels in.
        direction: Vec3,
        /// Irradiance on a surface facing the light.
        irradiance: Rgb,
    },
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
    /// All materials; objects refer to them by index.
    pub materials: Vec<Material>,
    /// All spheres.
    pub spheres: Vec<Sphere>,
    /// All triangles (quads and meshes).
    pub triangles: Vec<Triangle>,
    /// Lights with no area (point, spot, directional).
    pub lights: Vec<DeltaLight>,
    /// Where the scene came from, for messages.
    pub source: PathBuf,
    /// Things the loader fixed or dropped that the user may want to know
    /// about (degenerate or non-finite mesh triangles, bad normals, ...),
    /// one line each, naming the file and key.
    pub warnings: Vec<String>,
}
