//! The one conversion from the CPU [`Scene`] to what the device reads:
//! the BVH and its primitives, materials, emitters and the frame constants.

use bytemuck::Zeroable;
use glam::{UVec4, Vec3, Vec4};

use super::structs::*;
use super::textures::{pack_textures, GpuTextures};
use crate::accel::bvh::Bvh;
use crate::accel::geometry::{plane_offset, triangle_area, Aabb};
use crate::interface::*;
use crate::scene::{ColorSource, MaterialKind, Scene, SceneError, Sides};

/// Everything the scene contributes to the device, packed.
#[derive(Debug, Clone)]
pub struct GpuScene {
    /// Frame constants, less the wave capacity the renderer fills in.
    pub frame: GpuFrame,
    /// The device BVH: element 0 is the [`GpuBvhGrid`] header (cast), then
    /// the node pairs.
    pub bvh: Vec<GpuBvhPair>,
    /// Nodes of the BVH, for `lancer info`.
    pub bvh_nodes: usize,
    /// Primitives in BVH leaf order.
    pub primitives: Vec<GpuPrimitive>,
    /// Triangle shading data, indexed by `GpuPrimitive::meta.z`.
    pub tri_shading: Vec<GpuTriShading>,
    /// Materials, in scene order.
    pub materials: Vec<GpuMaterial>,
    /// Emitter table, sorted by primitive index.
    pub emitters: Vec<GpuEmitter>,
    /// Depth of the BVH (root = 1).
    pub bvh_depth: u32,
    /// SAH cost of the BVH ([`Bvh::sah_cost`]).
    pub bvh_sah_cost: f64,
    /// Wall-clock seconds the BVH build took.
    pub bvh_seconds: f64,
    /// Original primitive index (spheres, then triangles) of each leaf slot.
    pub prim_order: Vec<u32>,
    /// Every texture, packed.
    pub textures: GpuTextures,
}

/// Rec. 709 luminance, used to weigh emitters by power.
fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The constant part of a colour source (white under a texture).
fn constant(c: &ColorSource) -> Vec3 {
    match c {
        ColorSource::Constant(c) => *c,
        ColorSource::Texture(_) => Vec3::ONE,
    }
}

/// Packs one material.
fn pack_material(m: &crate::scene::Material) -> GpuMaterial {
    let (ty, color, specular) = match &m.kind {
        MaterialKind::Lambert { albedo } => (MAT_LAMBERT, constant(albedo).extend(0.0), Vec4::ZERO),
        MaterialKind::Phong {
            diffuse,
            specular,
            exponent,
        } => (
            MAT_PHONG,
            constant(diffuse).extend(0.0),
            specular.extend(*exponent),
        ),
        MaterialKind::Mirror { reflectance } => (MAT_MIRROR, reflectance.extend(0.0), Vec4::ZERO),
        MaterialKind::Glossy {
            reflectance,
            cone_angle_deg,
        } => (
            MAT_GLOSSY,
            reflectance.extend(cone_angle_deg.to_radians().sin()),
            Vec4::ZERO,
        ),
        MaterialKind::Dielectric { ior, tint } => (MAT_DIELECTRIC, tint.extend(*ior), Vec4::ZERO),
    };
    let emissive = m.emission.max_element() > 0.0;
    GpuMaterial {
        color,
        specular,
        emission: m.emission.extend(if emissive { 1.0 } else { 0.0 }),
        info: UVec4::new(
            ty,
            NO_TEXTURE,
            match m.sides {
                Sides::Both => 0,
                Sides::Shading => MAT_FLAG_SHADING_SIDE,
                Sides::Front => MAT_FLAG_SHADING_SIDE | MAT_FLAG_FRONT_ONLY,
            },
            0,
        ),
    }
}

/// What packing needs to know beyond the scene: the device's limits and
/// the renderer's choices, which the frame constants record.
#[derive(Debug, Clone, Copy)]
pub struct PackOptions {
    /// Bytes the one texel binding may hold; larger textures are shrunk.
    pub max_texture_bytes: u64,
    /// Paths per wave (`GpuFrame::wave_capacity`).
    pub wave_capacity: u32,
    /// Samples are read at counts not known in advance: no stratification
    /// by the scene's spp (`GpuFrame::strata` is 0).
    pub progressive: bool,
}

impl Default for PackOptions {
    /// No texture limit, one path per wave, stratified samples.
    fn default() -> Self {
        PackOptions {
            max_texture_bytes: u64::MAX,
            wave_capacity: 1,
            progressive: false,
        }
    }
}

impl GpuScene {
    /// Builds the BVH, loads the textures (shrunk, with a warning, where
    /// they exceed `options.max_texture_bytes`, the device's binding limit)
    /// and packs `scene` for the device. The frame constants are final:
    /// nothing changes them afterwards.
    pub fn pack(scene: &Scene, options: &PackOptions) -> anyhow::Result<GpuScene> {
        let textures = pack_textures(scene, options.max_texture_bytes)?;
        let n_sph = scene.spheres.len();
        // Bound every primitive: spheres first, then triangles.
        let mut boxes: Vec<Aabb> = Vec::with_capacity(n_sph + scene.triangles.len());
        boxes.extend(
            scene
                .spheres
                .iter()
                .map(|s| Aabb::of_sphere(s.center, s.radius)),
        );
        boxes.extend(
            scene
                .triangles
                .iter()
                .map(|t| Aabb::of_triangle(t.p[0], t.p[1], t.p[2])),
        );
        let started = std::time::Instant::now();
        let mut bvh: Bvh = crate::accel::bvh::build(&boxes);
        let bvh_seconds = started.elapsed().as_secs_f64();
        let bvh_depth = bvh.depth();
        let bvh_sah_cost = bvh.sah_cost();
        if bvh.nodes.is_empty() {
            // No primitives: a placeholder root that the kernels never
            // visit, since `GpuFrame::primitive_count` is 0.
            bvh.nodes.push(crate::accel::bvh::BvhNode {
                min: Vec3::splat(1.0),
                max: Vec3::splat(-1.0),
                left_or_first: 0,
                count: 0,
            });
        }

        let materials: Vec<GpuMaterial> = scene
            .materials
            .iter()
            .zip(&textures.material_texture)
            .map(|(m, &tex)| {
                let mut g = pack_material(m);
                g.info.y = tex;
                g
            })
            .collect();
        let tri_shading: Vec<GpuTriShading> = scene
            .triangles
            .iter()
            .map(|t| {
                let n = t.n.unwrap_or([Vec3::ZERO; 3]);
                let uv = t.uv.unwrap_or([glam::Vec2::ZERO; 3]);
                GpuTriShading {
                    n0: n[0].extend(uv[0].x),
                    n1: n[1].extend(uv[1].x),
                    n2: n[2].extend(uv[2].x),
                    v: Vec4::new(uv[0].y, uv[1].y, uv[2].y, 0.0),
                }
            })
            .collect();

        // Lay primitives out in leaf order, and weigh emitters by power.
        let mut primitives = Vec::with_capacity(bvh.prim_order.len());
        let mut emitters = Vec::new();
        for (slot, &orig) in bvh.prim_order.iter().enumerate() {
            let orig = orig as usize;
            let (prim, area, material) = if orig < n_sph {
                let s = &scene.spheres[orig];
                let p = GpuPrimitive {
                    a: s.center.extend(s.radius),
                    b: Vec4::ZERO,
                    c: Vec4::ZERO,
                    meta: UVec4::new(pack_prim_kind(PRIM_SPHERE, 0), s.material, 0, 0),
                };
                (
                    p,
                    4.0 * std::f32::consts::PI * s.radius * s.radius,
                    s.material,
                )
            } else {
                let ti = orig - n_sph;
                let t = &scene.triangles[ti];
                let flags = if t.n.is_some() { PRIM_FLAG_NORMALS } else { 0 }
                    | if t.uv.is_some() { PRIM_FLAG_UVS } else { 0 };
                let p = GpuPrimitive {
                    a: t.p[0].extend(plane_offset(t.p[0], t.p[1], t.p[2])),
                    b: t.p[1].extend(0.0),
                    c: t.p[2].extend(0.0),
                    meta: UVec4::new(
                        pack_prim_kind(PRIM_TRIANGLE, flags),
                        t.material,
                        ti as u32,
                        0,
                    ),
                };
                let area = triangle_area(t.p[0], t.p[1], t.p[2]);
                (p, area, t.material)
            };
            let power = luminance(scene.materials[material as usize].emission) * area;
            if power > 0.0 && power.is_finite() {
                emitters.push((slot as u32, power, area));
            }
            primitives.push(prim);
        }
        let total: f64 = emitters.iter().map(|e| e.1 as f64).sum();
        let mut acc = 0.0f64;
        let emitters: Vec<GpuEmitter> = emitters
            .iter()
            .map(|&(prim, power, area)| {
                acc += power as f64;
                let pmf = (power as f64 / total) as f32;
                primitives[prim as usize].meta.w = pmf.to_bits();
                GpuEmitter {
                    prim,
                    cdf: (acc / total) as f32,
                    pmf,
                    area,
                }
            })
            .collect();
        let mut emitters = emitters;
        if let Some(last) = emitters.last_mut() {
            last.cdf = 1.0;
        }

        let (grid, pairs) = if scene.spheres.is_empty() && scene.triangles.is_empty() {
            (GpuBvhGrid::zeroed(), Vec::new())
        } else {
            crate::gpu::bvh_grid::pack(&bvh)?
        };
        let gpu_bvh: Vec<GpuBvhPair> = std::iter::once(bytemuck::cast(grid)).chain(pairs).collect();

        Ok(GpuScene {
            frame: pack_frame(scene, emitters.len() as u32, options)?,
            bvh: gpu_bvh,
            bvh_nodes: bvh.nodes.len(),
            primitives,
            tri_shading,
            materials,
            emitters,
            bvh_depth,
            bvh_sah_cost,
            bvh_seconds,
            prim_order: bvh.prim_order.clone(),
            textures,
        })
    }
}

/// Camera basis and render settings, checked as the device will use them:
/// the basis is built in f64 ([`Camera::basis`](crate::scene::Camera::basis))
/// and the pixel count in u64, so neither can collapse or wrap. The image
/// size is checked again here because the command line may change it after
/// the scene was read.
fn pack_frame(
    scene: &Scene,
    emitter_count: u32,
    options: &PackOptions,
) -> Result<GpuFrame, SceneError> {
    let cam = &scene.camera;
    let r = &scene.render;
    let invalid = |key: &str, reason: String| SceneError::Invalid {
        path: scene.source.clone(),
        line: None,
        key: key.to_string(),
        reason,
    };
    let pixel_count = r.check().map_err(|(key, reason)| {
        let keys = if key == "width" || key == "height" {
            " (render.width, render.height)"
        } else {
            ""
        };
        invalid(&format!("render.{key}"), format!("{reason}{keys}"))
    })?;
    crate::scene::limits::check_path_gain(&scene.materials, scene.environment, r.max_depth)
        .map_err(|e| invalid(&e.key(&scene.materials), e.reason))?;
    let basis = cam
        .basis()
        .map_err(|(key, reason)| invalid(&format!("camera.{key}"), reason))?;
    let tan_half = (cam.vfov_deg as f64).to_radians() * 0.5;
    let tan_half = tan_half.tan();
    let aspect = r.width as f64 / r.height as f64;
    let (tan_v, tan_u) = (tan_half as f32, (tan_half * aspect) as f32);
    if !(cam.vfov_deg > 0.0 && cam.vfov_deg < 180.0 && tan_v > 0.0 && tan_u.is_finite()) {
        return Err(invalid(
            "camera.vfov",
            format!(
                "must be > 0 and < 180 (degrees) with a finite field of view at a {} x {} \
                 image, got {}",
                r.width, r.height, cam.vfov_deg
            ),
        ));
    }
    let strata = (r.spp as f64).sqrt().round() as u64;
    let strata = if strata * strata == r.spp as u64 && !options.progressive {
        strata as u32
    } else {
        0
    };
    let primitive_count =
        u32::try_from(scene.spheres.len() + scene.triangles.len()).map_err(|_| {
            invalid(
                "objects",
                format!(
                    "{} spheres and {} triangles are more primitives than 32-bit indices \
                     address",
                    scene.spheres.len(),
                    scene.triangles.len()
                ),
            )
        })?;
    Ok(GpuFrame {
        eye: cam.eye.extend(cam.aperture_radius),
        cam_u: basis.u.extend(tan_u),
        cam_v: basis.v.extend(tan_v),
        cam_w: basis.w.extend(cam.focus_distance),
        environment: scene.environment.extend(0.0),
        width: r.width,
        height: r.height,
        spp: r.spp,
        max_depth: r.max_depth,
        seed: r.seed,
        strata,
        emitter_count,
        wave_capacity: options.wave_capacity,
        pixel_count,
        primitive_count,
        pad0: 0,
        pad1: 0,
    })
}
