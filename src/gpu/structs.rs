//! Packed GPU structs (`#[repr(C)]`, bytemuck `Pod`), one per GLSL struct
//! of `shaders/common/bindings.glsl` under std430; the tests at the bottom
//! check each size and offset against the GLSL. None holds a bare `Vec3`:
//! positions are `Vec4` or explicit `[f32; 3]` plus a 4-byte field.

use bytemuck::{Pod, Zeroable};
use glam::{UVec4, Vec4};

use crate::interface::*;

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
    /// The pixel filter (`FILTER_*`); `FILTER_BOX` jitters in the pixel.
    pub filter_kind: u32,
    /// Path flags (`PATH_FLAG_*`): hidden emitters, emitter sampling only.
    pub path_flags: u32,
    /// Weight of each delta light sample (`RenderSettings::delta_light_gain`).
    pub delta_light_gain: f32,
    /// Russian roulette runs from the hit that ends this segment on
    /// (`RenderSettings::rr_depth`).
    pub rr_depth: u32,
    /// 1 when the Sobol sampler draws a pixel's even and odd samples as two
    /// independent sequences (a progressive render, whose film's error
    /// estimate needs them); 0: one sequence per pixel.
    pub halves: u32,
    /// Padding to a 16-byte multiple.
    pub pad2: u32,
    /// The pixel filter: x radius in pixels, y and z its parameters (see
    /// `FILTER_*`), w 1 / its integral.
    pub filter_params: Vec4,
    /// Camera clip planes: x near and y far distance along the optical
    /// axis, z 1 when clipping (`SPEC_HAS_CLIP`), w 1 when the camera is
    /// orthographic (`SPEC_HAS_ORTHO`: `eye` is then the near plane's
    /// centre, `cam_u` and `cam_v` its half extents with tangent 1, and
    /// -`cam_w` the rays' direction).
    pub clip: Vec4,
    /// The pixel filter's inverse-CDF table: `FILTER_TABLE_SEGMENTS + 1`
    /// offsets in pixels, then zeros.
    pub filter_table: [Vec4; FILTER_TABLE_VEC4S as usize],
    /// The pixel filter cut at the image's edge (`SPEC_HAS_FILM_EDGE`): per
    /// pixel 0 to 15 whole pixels from the edge, (CDF, ∫ f) at the cut below
    /// and above; the last entry is the uncut filter's (0, 0, 1, ∫ f)
    /// (`PixelFilter::edge_table`).
    pub filter_edge: [Vec4; FILTER_EDGE_ENTRIES as usize],
    /// xyz: added to every camera ray's direction before it is normalised
    /// (`Camera::shift` times the image's tangents along u and v;
    /// `SPEC_HAS_CAM_SHIFT`); w: unused.
    pub cam_shift: Vec4,
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
    /// ([`crate::accel::geometry::plane_offset`]).
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
    /// rgb: albedo, diffuse, reflectance, tint, a conductor's specular
    /// reflectance, a rough dielectric's specular transmittance or a
    /// principled material's base colour; w: ior (dielectric, principled),
    /// sin(cone angle) (glossy) or alpha_u (rough conductor and dielectric).
    pub color: Vec4,
    /// rgb: Phong specular, a conductor's eta or a rough dielectric's
    /// specular reflectance; w: Phong exponent or alpha_v (rough conductor
    /// and dielectric). A principled material's GGX alpha_u and alpha_v,
    /// metallic and specular tint.
    pub specular: Vec4,
    /// rgb: emitted radiance (front side); w: 1 when emissive.
    pub emission: Vec4,
    /// x: type (`MAT_*`); y: texture index or `NO_TEXTURE` (a rough
    /// conductor's or dielectric's roughness along the tangent); z: flags
    /// (`MAT_FLAG_*`); w: a rough plastic's first coating-table texel, a
    /// principled material's parameter texel, a blend's first component, or
    /// the texture index of a rough conductor's or dielectric's roughness
    /// along the bitangent (`NO_TEXTURE` where constant).
    pub info: UVec4,
    /// rgb: a conductor's k, or x: a rough dielectric's ior (inside over
    /// outside); w: microfacet distribution (`MICROFACET_*`). A principled
    /// material's sheen, sheen tint, clearcoat and clearcoat GTR1 alpha.
    pub params: Vec4,
    /// Layers over the material: x: a `mask`'s opacity (f32 bits) where it
    /// is constant (`MAT_FLAG_MASKED`); y: the opacity's texture index, or
    /// `NO_TEXTURE`; z: a normal or bump map's texture index
    /// (`MAT_FLAG_NORMAL_MAP`), or `NO_TEXTURE`; w: a bump map's scale (f32
    /// bits, `MAT_FLAG_BUMP_MAP`).
    pub layers: UVec4,
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

/// One delta light (`DeltaLight` in GLSL), stored in the emitter texels
/// after the emitter table ([`DELTA_LIGHT_TEXELS`] texels each).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuDeltaLight {
    /// xyz: position (point, spot, projector) or unit direction of travel
    /// (directional); w: kind (`LIGHT_*`, as u32 bits).
    pub p: Vec4,
    /// rgb: intensity (point, spot), irradiance (directional) or pi times
    /// scale times the irradiance (projector; its colour when constant);
    /// w: spot's cosine of the cutoff angle, projector's cot_x / 2.
    pub intensity: Vec4,
    /// Spot, projector: xyz row 0 of world to light space; w: spot's
    /// cosine of the beam width, projector's cot_y / 2.
    pub local_x: Vec4,
    /// Spot, projector: xyz row 1 of world to light space; w: spot's sine
    /// of the cutoff angle.
    pub local_y: Vec4,
    /// Spot, projector: xyz row 2 of world to light space; w: spot's 1 /
    /// (cutoff - beam width), radians (0 when they are equal).
    pub local_z: Vec4,
    /// Projector: xyz its axis (`to_world` applied to +z). w: the index of
    /// the spot's texture or the projector's irradiance image (u32 bits),
    /// or `NO_TEXTURE`.
    pub extra: Vec4,
}

const _: () = assert!(std::mem::size_of::<GpuDeltaLight>() == 16 * DELTA_LIGHT_TEXELS as usize);
const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 16 * MATERIAL_TEXELS as usize);

/// The header of the environment map's buffer (`EnvmapHeader` in GLSL):
/// its frame, its pick probability, its size and where its tables start
/// (word offsets in the buffer). The texels follow the header, three f32
/// words (linear RGB, scale applied) per texel, rows from the top.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub struct GpuEnvmap {
    /// xyz: row 0 of world to map space; w: the map's pick probability in
    /// the emitter table (0 when it is not there).
    pub to_local_x: Vec4,
    /// xyz: row 1 of world to map space; w: unused.
    pub to_local_y: Vec4,
    /// xyz: row 2 of world to map space; w: unused.
    pub to_local_z: Vec4,
    /// x: width W in texels (0: no map); y: height H; z: first word of the
    /// marginal CDF over the H - 1 rows of cells; w: first word of the
    /// conditional CDFs (W per row of cells).
    pub grid: UVec4,
    /// x: first word of the cell densities (W per row of cells), each the
    /// cell's probability per unit (u, v) area over 2 pi^2; yzw: unused.
    pub tables: UVec4,
}

const _: () = assert!(std::mem::size_of::<GpuEnvmap>() == 4 * ENVMAP_HEADER_WORDS as usize);

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
    /// First sample of every pixel of the wave; with a pixel list, the
    /// first past the samples each entry says its pixel holds.
    pub sample_base: u32,
    /// First pixel of the wave (row-major index in the whole image), or,
    /// when the kernels read a pixel list (`SPEC_PIXEL_LIST`), the wave's
    /// first entry of it.
    pub pixel_base: u32,
    /// Paths in this wave: `wave_pixels` times the samples per pixel.
    pub path_count: u32,
    /// Bounce index: 0 for the camera ray's segment.
    pub bounce: u32,
    /// Pixels of the wave; path slot `s` renders the wave's pixel
    /// `s % wave_pixels` (pixel `pixel_base + s % wave_pixels`, or that
    /// entry of the pixel list), sample `sample_base + s / wave_pixels`
    /// (counted, with a pixel list, from the samples the entry says the
    /// pixel holds).
    pub wave_pixels: u32,
    /// First pixel of the band of rows whose film the device holds.
    pub film_base: u32,
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
            array if array.starts_with("vec4[") => {
                // A length is a number or a constant of src/interface
                let len = &array["vec4[".len()..array.len() - 1];
                let n: usize = len.parse().unwrap_or_else(|_| {
                    SHADER_DEFINES
                        .iter()
                        .find(|(name, _)| *name == len)
                        .map(|&(_, v)| v as usize)
                        .expect("array length")
                });
                (16 * n, 16)
            }
            other => panic!("layout test does not know GLSL type {other}"),
        }
    }

    /// Member offsets and the size of GLSL struct `name`, under std430,
    /// read from shaders/common/bindings.glsl.
    fn glsl_layout(name: &str) -> (Vec<(String, usize)>, usize) {
        let src = include_str!("../../shaders/common/bindings.glsl");
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
            // An array member `vec4 name[N]` counts as the type `vec4[N]`
            let (ty, member) = match member.split_once('[') {
                Some((name, len)) => (format!("{ty}[{len}"), name),
                None => (ty.to_string(), member),
            };
            let (size, a) = std430(&ty);
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
            primitive_count, filter_kind, path_flags, delta_light_gain, rr_depth, halves, pad2, filter_params, clip,
            filter_table, filter_edge, cam_shift);
        check("Frame", size_of::<GpuFrame>(), &f);
        assert_eq!(
            size_of::<GpuFrame>(),
            192 + 16 * (FILTER_TABLE_VEC4S + FILTER_EDGE_ENTRIES) as usize
        );
        assert_eq!(FILTER_TABLE_VEC4S, (FILTER_TABLE_SEGMENTS + 1).div_ceil(4));
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
        let f = fields!(GpuMaterial: color, specular, emission, info, params, layers);
        check("Material", size_of::<GpuMaterial>(), &f);
        assert_eq!(size_of::<GpuMaterial>(), 96);
    }

    #[test]
    fn small_struct_layouts_match_glsl() {
        let f = fields!(GpuEmitter: prim, cdf, pmf, area);
        check("Emitter", size_of::<GpuEmitter>(), &f);
        let f = fields!(GpuDeltaLight: p, intensity, local_x, local_y, local_z, extra);
        check("DeltaLight", size_of::<GpuDeltaLight>(), &f);
        let f = fields!(GpuEnvmap: to_local_x, to_local_y, to_local_z, grid, tables);
        check("EnvmapHeader", size_of::<GpuEnvmap>(), &f);
        assert_eq!(f.map(|f| f.1), [0, 16, 32, 48, 64]);
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
        let glsl = include_str!("../../shaders/common/bindings.glsl");
        assert!(glsl.contains("p.meta.x & ((1u << PRIM_KIND_BITS) - 1u)"));
        assert!(glsl.contains("p.meta.x >> PRIM_KIND_BITS"));
    }

    #[test]
    fn push_constants_match_glsl() {
        let src = include_str!("../../shaders/common/bindings.glsl");
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
