//! Packed GPU structs (`#[repr(C)]`, bytemuck `Pod`) and the one conversion
//! from the CPU [`Scene`](crate::scene::Scene) to them.
//!
//! Every struct mirrors a GLSL struct in `shaders/common/bindings.glsl`
//! under std430; the tests at the bottom check each size and offset. None
//! holds a bare `Vec3`: positions are `Vec4` or explicit `[f32; 3]` plus a
//! 4-byte field.

use bytemuck::{Pod, Zeroable};
use glam::{UVec4, Vec3, Vec4};

use crate::bvh::Bvh;
use crate::geometry::{plane_offset, triangle_area, Aabb};
use crate::scene::{ColorSource, MaterialKind, Scene, SceneError};
use crate::shader_interface::*;

/// Per-render constants: camera, image, sampling (`Frame` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuFrame {
    /// xyz: eye; w: thin-lens radius.
    pub eye: Vec4,
    /// xyz: unit right vector; w: tan(vfov / 2) * aspect.
    pub cam_u: Vec4,
    /// xyz: unit up vector; w: tan(vfov / 2).
    pub cam_v: Vec4,
    /// xyz: unit vector pointing backwards (eye - look_at); w: focus distance.
    pub cam_w: Vec4,
    /// rgb: environment radiance; w: unused.
    pub environment: Vec4,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Longest path, in segments from the camera.
    pub max_depth: u32,
    /// Seed of the random numbers.
    pub seed: u32,
    /// N when spp = N * N (stratified jitter), else 0.
    pub strata: u32,
    /// Number of entries in the emitter table.
    pub emitter_count: u32,
    /// Paths in flight per wave: the capacity of every queue.
    pub wave_capacity: u32,
    /// width * height.
    pub pixel_count: u32,
    /// Number of primitives; 0 means no ray hits anything.
    pub primitive_count: u32,
    /// Padding to a 16-byte multiple.
    pub pad0: u32,
    /// Padding to a 16-byte multiple.
    pub pad1: u32,
}

/// Header of the device BVH (`BvhGrid` in GLSL): the grid its boxes are
/// quantised on and the root's reference (see `src/bvh_grid.rs`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuBvhGrid {
    /// Grid origin: the scene box's lower corner.
    pub origin: [f32; 3],
    /// Reference of the root node.
    pub root_ref: u32,
    /// Grid step per axis.
    pub scale: [f32; 3],
    /// Padding to a 16-byte multiple.
    pub pad: u32,
}

/// Two sibling BVH nodes (`BvhPair` in GLSL), one texel each: a box
/// quantised to 16 bits per corner coordinate, and the node's reference
/// (leaf: first primitive and count; interior: its children's pair and 0).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuBvhPair {
    /// Left box: min.x | min.y, min.z | max.x, max.y | max.z (16-bit halves).
    pub left: [u32; 3],
    /// Left node's reference.
    pub left_ref: u32,
    /// Right box, packed likewise.
    pub right: [u32; 3],
    /// Right node's reference.
    pub right_ref: u32,
}

const _: () = {
    assert!(BVH_MAX_LEAF_PRIMS < 1 << BVH_REF_COUNT_BITS);
    assert!(std::mem::size_of::<GpuBvhGrid>() == std::mem::size_of::<GpuBvhPair>());
};

/// A sphere or a triangle, in BVH leaf order (`Primitive` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuPrimitive {
    /// Sphere: centre and radius; triangle: vertex 0 and the plane offset
    /// ([`crate::geometry::plane_offset`]).
    pub a: Vec4,
    /// Triangle: vertex 1.
    pub b: Vec4,
    /// Triangle: vertex 2.
    pub c: Vec4,
    /// x: kind (`PRIM_*`) and flags (`PRIM_FLAG_*`), packed by
    /// [`pack_prim_kind`]; y: material; z: triangle shading index; w: emitter
    /// pick probability (f32 bits), 0 if none.
    pub meta: UVec4,
}

/// Shading data of one triangle (`TriShading` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuTriShading {
    /// xyz: normal at vertex 0; w: u at vertex 0.
    pub n0: Vec4,
    /// xyz: normal at vertex 1; w: u at vertex 1.
    pub n1: Vec4,
    /// xyz: normal at vertex 2; w: u at vertex 2.
    pub n2: Vec4,
    /// xyz: v at vertices 0, 1, 2; w: unused.
    pub v: Vec4,
}

/// A material (`Material` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuMaterial {
    /// rgb: albedo, diffuse, reflectance or tint; w: ior (dielectric) or
    /// sin(cone angle) (glossy).
    pub color: Vec4,
    /// rgb: Phong specular; w: Phong exponent.
    pub specular: Vec4,
    /// rgb: emitted radiance (front side); w: 1 when emissive.
    pub emission: Vec4,
    /// x: type (`MAT_*`); y: texture index or `NO_TEXTURE`; z, w: unused.
    pub info: UVec4,
}

/// One entry of the emitter table (`Emitter` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuEmitter {
    /// Primitive index (BVH leaf order).
    pub prim: u32,
    /// Cumulative pick probability up to and including this entry.
    pub cdf: f32,
    /// Pick probability of this entry.
    pub pmf: f32,
    /// Surface area of the primitive.
    pub area: f32,
}

/// The closest hit the intersect pass found for one path (`Hit` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuHit {
    /// Distance along the unit ray direction.
    pub t: f32,
    /// Primitive index in BVH leaf order; `NO_HIT` for a ray that escaped.
    pub prim: u32,
    /// Triangle barycentrics of vertices 1 and 2.
    pub bary: [f32; 2],
}

/// Counter and indirect-dispatch arguments of one queue (`QueueHeader` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq, Eq)]
pub struct GpuQueueHeader {
    /// Workgroups to dispatch: ceil(count / WORKGROUP_SIZE).
    pub groups_x: u32,
    /// Workgroups to dispatch in y: 1.
    pub groups_y: u32,
    /// Workgroups to dispatch in z: 1.
    pub groups_z: u32,
    /// Items in the queue.
    pub count: u32,
}

impl GpuQueueHeader {
    /// A header for a queue holding `count` items.
    pub fn with_count(count: u32) -> Self {
        Self {
            groups_x: count.div_ceil(WORKGROUP_SIZE),
            groups_y: 1,
            groups_z: 1,
            count,
        }
    }
}

/// A running sum of RGB values (`FilmPixel` in GLSL), in one of two
/// encodings: three f64 (on devices with `shaderFloat64`), or an f32 sum
/// with an f32 Neumaier compensation.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuFilmPixel {
    /// f64 film: bits of r (xy) and g (zw); f32 film: bits of the rgb sum.
    pub lo: UVec4,
    /// f64 film: bits of b (xy); f32 film: bits of the rgb compensation.
    pub hi: UVec4,
}

impl GpuFilmPixel {
    /// The total, in double precision.
    pub fn total(&self, fp64: bool) -> [f64; 3] {
        if fp64 {
            let d = |lo: u32, hi: u32| f64::from_bits(((hi as u64) << 32) | lo as u64);
            [
                d(self.lo.x, self.lo.y),
                d(self.lo.z, self.lo.w),
                d(self.hi.x, self.hi.y),
            ]
        } else {
            [0, 1, 2].map(|i| f32::from_bits(self.lo[i]) as f64 + f32::from_bits(self.hi[i]) as f64)
        }
    }
}

/// Push constants of every kernel (`Push` in GLSL).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable, PartialEq, Eq)]
pub struct GpuPush {
    /// First sample of every pixel of the wave.
    pub sample_base: u32,
    /// First pixel of the wave (row-major index in the whole image).
    pub pixel_base: u32,
    /// Paths in this wave: `wave_pixels` times the samples per pixel.
    pub path_count: u32,
    /// Bounce index: 0 for the camera ray's segment.
    pub bounce: u32,
    /// Pixels of the wave; path slot `s` renders pixel
    /// `pixel_base + s % wave_pixels`, sample `sample_base + s / wave_pixels`.
    pub wave_pixels: u32,
    /// First pixel of the band of rows whose film the device holds.
    pub film_base: u32,
}

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

/// The texture file of a material, if it has one, and the key that names it.
fn texture_path(m: &crate::scene::Material) -> Option<(&std::path::Path, &'static str)> {
    let key = |toml_key| {
        // OBJ materials are named `file.mtl:name` and take `map_Kd`
        if m.name.contains(".mtl:") {
            "map_Kd"
        } else {
            toml_key
        }
    };
    match &m.kind {
        MaterialKind::Lambert {
            albedo: ColorSource::Texture(p),
        } => Some((p, key("albedo_texture"))),
        MaterialKind::Phong {
            diffuse: ColorSource::Texture(p),
            ..
        } => Some((p, key("diffuse_texture"))),
        _ => None,
    }
}

/// Textures packed into one `uint` buffer: a header of four words per
/// texture (first texel, width, height, 0), then every texel as sRGB RGBA8.
#[derive(Debug, Clone, Default)]
pub struct GpuTextures {
    /// Headers then texels.
    pub words: Vec<u32>,
    /// Texture index of each material, or `NO_TEXTURE`.
    pub material_texture: Vec<u32>,
    /// One line per texture shrunk to fit the binding, naming it, the
    /// material key, both sizes and the limit.
    pub warnings: Vec<String>,
}

/// Decodes one texture file (the format by its extension) to sRGB RGBA8.
///
/// The size in the file's header is checked against
/// [`MAX_TEXTURE_TEXELS`](crate::scene::MAX_TEXTURE_TEXELS) before any pixel
/// is decoded, and the decoder may allocate no more than such a texture
/// needs, so a small file claiming a huge image is refused at once.
pub fn load_texture(path: &std::path::Path) -> anyhow::Result<image::RgbaImage> {
    use crate::scene::MAX_TEXTURE_TEXELS;
    use anyhow::Context as _;
    let open = || {
        image::ImageReader::open(path)
            .with_context(|| format!("cannot read texture {}", path.display()))
    };
    let (width, height) = open()?
        .into_dimensions()
        .with_context(|| format!("cannot read texture {}", path.display()))?;
    let texels = width as u64 * height as u64;
    anyhow::ensure!(
        texels <= MAX_TEXTURE_TEXELS,
        "texture {} is {width} x {height} = {texels} texels; lancer reads textures of at \
         most {MAX_TEXTURE_TEXELS} texels (4096 x 4096): downscale it",
        path.display()
    );
    // Decoded pixels take at most 16 bytes each (RGBA, 32-bit floats).
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_TEXTURE_TEXELS * 16);
    let mut reader = open()?;
    reader.limits(limits);
    let decoded = reader
        .decode()
        .with_context(|| format!("cannot read texture {}", path.display()))?;
    Ok(decoded.to_rgba8())
}

/// Loads every texture the materials use, each file once, into at most
/// `max_bytes` bytes (the device binding's limit): when they do not fit,
/// the largest are shrunk to fit (by an area-weighted box filter in linear
/// light), each with a warning.
pub fn pack_textures(scene: &Scene, max_bytes: u64) -> anyhow::Result<GpuTextures> {
    use crate::texture_fit::{downscale, fitted_size, texel_cap, HEADER_WORDS, TEXEL_BYTES};
    use anyhow::Context as _;
    // Each file once, with the first material (and key) that uses it
    let mut used: Vec<(&std::path::Path, String)> = Vec::new();
    let material_texture = scene
        .materials
        .iter()
        .map(|m| match texture_path(m) {
            Some((p, key)) => match used.iter().position(|q| q.0 == p) {
                Some(i) => i as u32,
                None => {
                    used.push((p, format!("material {:?}, {key}", m.name)));
                    used.len() as u32 - 1
                }
            },
            None => NO_TEXTURE,
        })
        .collect();
    let sizes = used
        .iter()
        .map(|(path, _)| {
            image::image_dimensions(path)
                .with_context(|| format!("cannot read texture {}", path.display()))
        })
        .collect::<anyhow::Result<Vec<(u32, u32)>>>()?;
    let texels: Vec<u64> = sizes
        .iter()
        .map(|&(w, h)| u64::from(w) * u64::from(h))
        .collect();
    // Texels are addressed by 32-bit word offsets on the device
    let max_words = (max_bytes / TEXEL_BYTES).min(u64::from(u32::MAX));
    let header_words = used.len() as u64 * HEADER_WORDS;
    let room = max_words.saturating_sub(header_words);
    let cap = texel_cap(&texels, room);
    let total_bytes = (header_words + texels.iter().sum::<u64>()) * TEXEL_BYTES;
    anyhow::ensure!(
        cap != Some(0),
        "the scene's {} textures cannot fit in {max_bytes} bytes, the most one device binding \
         holds, even at one texel each: use fewer textures",
        used.len()
    );
    let mut words = vec![0u32; header_words as usize];
    let mut warnings = Vec::new();
    for (i, ((path, key), &(width, height))) in used.iter().zip(&sizes).enumerate() {
        let mut img = load_texture(path)?;
        if let Some(cap) = cap {
            let (w, h) = fitted_size(width, height, cap);
            if (w, h) != (width, height) {
                img = downscale(&img, w, h);
                warnings.push(format!(
                    "texture {} ({key}) downscaled from {width} x {height} to {w} x {h} texels, \
                     keeping its mean colour: the scene's textures need {total_bytes} bytes, more \
                     than the {max_bytes} bytes one device binding holds; give a smaller image \
                     to choose the filtering yourself",
                    path.display()
                ));
            }
        }
        words[i * 4] = words.len() as u32;
        words[i * 4 + 1] = img.width();
        words[i * 4 + 2] = img.height();
        words.extend(img.pixels().map(|p| u32::from_le_bytes(p.0)));
    }
    Ok(GpuTextures {
        words,
        material_texture,
        warnings,
    })
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
        info: UVec4::new(ty, NO_TEXTURE, 0, 0),
    }
}

impl GpuScene {
    /// Builds the BVH, loads the textures (shrunk, with a warning, where
    /// they exceed `max_texture_bytes`, the device's binding limit) and
    /// packs `scene` for the device.
    pub fn pack(scene: &Scene, max_texture_bytes: u64) -> anyhow::Result<GpuScene> {
        let textures = pack_textures(scene, max_texture_bytes)?;
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
        let mut bvh: Bvh = crate::bvh::build(&boxes);
        let bvh_seconds = started.elapsed().as_secs_f64();
        let bvh_depth = bvh.depth();
        let bvh_sah_cost = bvh.sah_cost();
        if bvh.nodes.is_empty() {
            // No primitives: a placeholder root that the kernels never
            // visit, since `GpuFrame::primitive_count` is 0.
            bvh.nodes.push(crate::bvh::BvhNode {
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
            crate::bvh_grid::pack(&bvh)?
        };
        let gpu_bvh: Vec<GpuBvhPair> = std::iter::once(bytemuck::cast(grid)).chain(pairs).collect();

        Ok(GpuScene {
            frame: pack_frame(scene, emitters.len() as u32)?,
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
fn pack_frame(scene: &Scene, emitter_count: u32) -> Result<GpuFrame, SceneError> {
    let cam = &scene.camera;
    let r = &scene.render;
    let invalid = |key: &str, reason: String| SceneError::Invalid {
        path: scene.source.clone(),
        line: None,
        key: key.to_string(),
        reason,
    };
    let pixel_count = crate::scene::image_pixels(r.width, r.height).map_err(|(key, reason)| {
        invalid(
            &format!("render.{key}"),
            format!("{reason} (in the scene, or --width / --height)"),
        )
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
    let strata = if strata * strata == r.spp as u64 {
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
        wave_capacity: 0,
        pixel_count,
        primitive_count,
        pad0: 0,
        pad1: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// std430 (size, alignment) of the GLSL member types the structs use.
    fn std430(ty: &str) -> (usize, usize) {
        match ty {
            "float" | "uint" | "int" => (4, 4),
            "vec2" | "uvec2" => (8, 8),
            "vec3" | "uvec3" => (12, 16),
            "vec4" | "uvec4" => (16, 16),
            other => panic!("layout test does not know GLSL type {other}"),
        }
    }

    /// Member offsets and the size of GLSL struct `name`, under std430,
    /// read from shaders/common/bindings.glsl.
    fn glsl_layout(name: &str) -> (Vec<(String, usize)>, usize) {
        let src = include_str!("../shaders/common/bindings.glsl");
        let head = format!("struct {name} {{");
        let body = &src[src
            .find(&head)
            .unwrap_or_else(|| panic!("no struct {name}"))
            + head.len()..];
        let body = &body[..body.find("};").expect("struct end")];
        let (mut offset, mut align) = (0usize, 0usize);
        let mut members = Vec::new();
        for line in body.lines() {
            let decl = line.split("//").next().unwrap().trim();
            if decl.is_empty() {
                continue;
            }
            let mut words = decl.trim_end_matches(';').split_whitespace();
            let (ty, member) = (words.next().unwrap(), words.next().unwrap());
            let (size, a) = std430(ty);
            offset = offset.next_multiple_of(a);
            members.push((member.to_string(), offset));
            offset += size;
            align = align.max(a);
        }
        (members, offset.next_multiple_of(align))
    }

    /// `(field name, offset)` of each named field of a Rust struct, in the
    /// order given, for comparison with the GLSL declaration.
    macro_rules! fields {
        ($ty:ty: $($field:ident),* $(,)?) => {
            [$((stringify!($field), offset_of!($ty, $field))),*]
        };
    }

    /// Asserts that the Rust fields (in declaration order) have the names
    /// and offsets of the GLSL members, and that the sizes match.
    fn check(name: &str, rust_size: usize, rust_fields: &[(&str, usize)]) {
        let (members, size) = glsl_layout(name);
        let rust: Vec<(String, usize)> = rust_fields
            .iter()
            .map(|&(n, o)| (n.to_string(), o))
            .collect();
        assert_eq!(members, rust, "{name}: member names and offsets");
        assert_eq!(size, rust_size, "{name}: size");
    }

    #[test]
    fn frame_layout_matches_glsl() {
        let f = fields!(GpuFrame: eye, cam_u, cam_v, cam_w, environment, width, height, spp,
            max_depth, seed, strata, emitter_count, wave_capacity, pixel_count,
            primitive_count, pad0, pad1);
        check("Frame", size_of::<GpuFrame>(), &f);
        assert_eq!(size_of::<GpuFrame>(), 128);
    }

    #[test]
    fn bvh_layouts_match_glsl() {
        let f = fields!(GpuBvhGrid: origin, root_ref, scale, pad);
        check("BvhGrid", size_of::<GpuBvhGrid>(), &f);
        assert_eq!(f.map(|f| f.1), [0, 12, 16, 28]);
        let f = fields!(GpuBvhPair: left, left_ref, right, right_ref);
        check("BvhPair", size_of::<GpuBvhPair>(), &f);
        assert_eq!(f.map(|f| f.1), [0, 12, 16, 28]);
    }

    #[test]
    fn primitive_layout_matches_glsl() {
        let f = fields!(GpuPrimitive: a, b, c, meta);
        check("Primitive", size_of::<GpuPrimitive>(), &f);
    }

    #[test]
    fn tri_shading_layout_matches_glsl() {
        let f = fields!(GpuTriShading: n0, n1, n2, v);
        check("TriShading", size_of::<GpuTriShading>(), &f);
    }

    #[test]
    fn material_layout_matches_glsl() {
        let f = fields!(GpuMaterial: color, specular, emission, info);
        check("Material", size_of::<GpuMaterial>(), &f);
    }

    #[test]
    fn small_struct_layouts_match_glsl() {
        let f = fields!(GpuEmitter: prim, cdf, pmf, area);
        check("Emitter", size_of::<GpuEmitter>(), &f);
        let f = fields!(GpuHit: t, prim, bary);
        check("Hit", size_of::<GpuHit>(), &f);
        assert_eq!(size_of::<GpuHit>(), 16);
        let f = fields!(GpuQueueHeader: groups_x, groups_y, groups_z, count);
        check("QueueHeader", size_of::<GpuQueueHeader>(), &f);
        let f = fields!(GpuFilmPixel: lo, hi);
        check("FilmPixel", size_of::<GpuFilmPixel>(), &f);
    }

    #[test]
    fn primitive_kind_and_flags_round_trip() {
        let packed = pack_prim_kind(PRIM_TRIANGLE, PRIM_FLAG_NORMALS | PRIM_FLAG_UVS);
        // What prim_kind() and prim_flags() in bindings.glsl compute.
        assert_eq!(packed & ((1 << PRIM_KIND_BITS) - 1), PRIM_TRIANGLE);
        assert_eq!(packed >> PRIM_KIND_BITS, PRIM_FLAG_NORMALS | PRIM_FLAG_UVS);
        let glsl = include_str!("../shaders/common/bindings.glsl");
        assert!(glsl.contains("p.meta.x & ((1u << PRIM_KIND_BITS) - 1u)"));
        assert!(glsl.contains("p.meta.x >> PRIM_KIND_BITS"));
    }

    #[test]
    fn push_constants_match_glsl() {
        let src = include_str!("../shaders/common/bindings.glsl");
        let block = &src[src.find("uniform Push {").expect("push block")..];
        let block = &block[..block.find('}').unwrap()];
        let members: Vec<&str> = block
            .lines()
            .skip(1)
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .collect();
        assert_eq!(
            members,
            [
                "uint sample_base;",
                "uint pixel_base;",
                "uint path_count;",
                "uint bounce;",
                "uint wave_pixels;",
                "uint film_base;"
            ]
        );
        assert_eq!(offset_of!(GpuPush, bounce), 12);
        assert_eq!(offset_of!(GpuPush, film_base), 20);
        assert_eq!(size_of::<GpuPush>(), 24);
    }

    #[test]
    fn queue_header_rounds_groups_up() {
        let groups = |n| {
            let h = GpuQueueHeader::with_count(n);
            [h.groups_x, h.groups_y, h.groups_z]
        };
        assert_eq!(groups(0), [0, 1, 1]);
        assert_eq!(groups(1), [1, 1, 1]);
        assert_eq!(groups(WORKGROUP_SIZE), [1, 1, 1]);
        assert_eq!(groups(WORKGROUP_SIZE + 1), [2, 1, 1]);
    }
}
