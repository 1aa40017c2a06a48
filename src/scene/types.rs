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
    /// Which sides scatter light (dielectrics ignore it: they transmit).
    pub sides: Sides,
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
    /// Where the scene came from, for messages.
    pub source: PathBuf,
    /// Things the loader fixed or dropped that the user may want to know
    /// about (degenerate or non-finite mesh triangles, bad normals, ...),
    /// one line each, naming the file and key.
    pub warnings: Vec<String>,
}
