//! The device interface, declared once: one row per buffer the kernels
//! bind, with its binding number, its Rust item type, how GLSL declares
//! it, what its size grows with and its allocation label.
//!
//! The `device_interface!` macro (in `src/gpu/mod.rs`) turns this table into the
//! `BINDING_*` constants and [`BUFFERS`] for the renderer's buffer table;
//! `build.rs` includes the same file with its own macro and turns it into
//! the `BINDING_*` shader macros and the GLSL declarations that
//! `shaders/common/bindings.glsl` includes (`generated/buffers.glsl`). The
//! struct types named in GLSL mirror [`crate::gpu::structs`].
//!
//! This file holds nothing but the table: `build.rs` compiles it without
//! the crate, so it must have no `use` items (the Rust types are written as
//! full paths, which only the crate's macro reads).
//!
//! Access: `readonly` and `buffer` are std430 storage buffers; `texels` is
//! an RGBA32UI texel buffer (on llvmpipe a per-lane `texelFetch` is a
//! gather, where a storage-buffer load of a per-lane address is a loop over
//! the lanes). Path state is written through its storage binding and read
//! through a second, texel binding of the same buffer (`+ texels`).

device_interface! {
    /// Per-render constants (`Frame`).
    BINDING_FRAME = 0: crate::gpu::structs::GpuFrame,
        readonly "Frame frame", grows Scene, "scene.frame";
    /// The BVH's quantisation grid, then its node pairs.
    BINDING_BVH_NODES = 1: crate::gpu::structs::GpuBvhPair,
        texels "bvh_texels", grows Scene, "scene.bvh";
    /// Primitives in BVH leaf order.
    BINDING_PRIMITIVES = 2: crate::gpu::structs::GpuPrimitive,
        texels "primitive_texels", grows Scene, "scene.primitives";
    /// Per-triangle shading data (normals, uvs).
    BINDING_TRI_SHADING = 3: crate::gpu::structs::GpuTriShading,
        texels "tri_shading_texels", grows Scene, "scene.tri_shading";
    /// Materials.
    BINDING_MATERIALS = 4: crate::gpu::structs::GpuMaterial,
        texels "material_texels", grows Scene, "scene.materials";
    /// Emitter primitive indices and CDF.
    BINDING_EMITTERS = 5: crate::gpu::structs::GpuEmitter,
        texels "emitter_texels", grows Scene, "scene.emitters";
    /// Queue headers: counts and indirect dispatch arguments.
    BINDING_QUEUE_HEADERS = 6: crate::gpu::structs::GpuQueueHeader,
        buffer "QueueHeader queue_headers[]", grows Fixed(crate::interface::QUEUE_HEADER_COUNT),
        "queues.headers";
    /// Ray queue items, `RAY_QUEUE_COUNT` queues of one wave each.
    BINDING_RAY_QUEUES = 7: u32,
        buffer "uint ray_queues[]", grows Wave(crate::interface::RAY_QUEUE_COUNT), "queues.rays";
    /// Shadow queue items.
    BINDING_SHADOW_QUEUE = 8: u32,
        buffer "uint shadow_queue[]", grows Wave(1), "queues.shadow";
    /// Path state: ray origins and tmax.
    BINDING_RAY_ORIGIN = 9: glam::Vec4,
        buffer "vec4 ray_origin[]" + texels BINDING_RAY_ORIGIN_TEXELS = 21 "ray_origin_texels",
        grows Wave(1), "generate.ray_origin";
    /// Path state: ray directions.
    BINDING_RAY_DIR = 10: glam::Vec4,
        buffer "vec4 ray_dir[]" + texels BINDING_RAY_DIR_TEXELS = 22 "ray_dir_texels",
        grows Wave(1), "generate.ray_dir";
    /// Path state: throughput and last BSDF pdf.
    BINDING_THROUGHPUT = 11: glam::Vec4,
        buffer "vec4 path_throughput[]" + texels BINDING_THROUGHPUT_TEXELS = 23 "throughput_texels",
        grows Wave(1), "shade.throughput";
    /// Path state: radiance gathered so far.
    BINDING_RADIANCE = 12: glam::Vec4,
        buffer "vec4 path_radiance[]" + texels BINDING_RADIANCE_TEXELS = 24 "radiance_texels",
        grows Wave(1), "shade.radiance";
    /// Hit records.
    BINDING_HITS = 13: crate::gpu::structs::GpuHit,
        buffer "Hit hits[]" + texels BINDING_HITS_TEXELS = 25 "hit_texels",
        grows Wave(1), "intersect.hits";
    /// Shadow ray origins and tmax.
    BINDING_SHADOW_ORIGIN = 14: glam::Vec4,
        buffer "vec4 shadow_origin[]" + texels BINDING_SHADOW_ORIGIN_TEXELS = 26 "shadow_origin_texels",
        grows Wave(1), "shade.shadow_origin";
    /// Shadow ray directions.
    BINDING_SHADOW_DIR = 15: glam::Vec4,
        buffer "vec4 shadow_dir[]" + texels BINDING_SHADOW_DIR_TEXELS = 27 "shadow_dir_texels",
        grows Wave(1), "shade.shadow_dir";
    /// Radiance a shadow ray adds when unoccluded.
    BINDING_SHADOW_RADIANCE = 16: glam::Vec4,
        buffer "vec4 shadow_radiance[]" + texels BINDING_SHADOW_RADIANCE_TEXELS = 28 "shadow_radiance_texels",
        grows Wave(1), "shade.shadow_radiance";
    /// Film sums (f64, or compensated f32).
    BINDING_FILM = 17: crate::gpu::structs::GpuFilmPixel,
        buffer "FilmPixel film[]", grows Film, "accumulate.film";
    /// Textures: all texels of all textures, behind their headers.
    BINDING_TEXELS = 18: u32,
        readonly "uint texels[]", grows Textures, "scene.texels";
    /// Counters the passes keep (non-finite samples, ...).
    BINDING_COUNTERS = 19: u32,
        buffer "uint counters[]", grows Fixed(crate::interface::COUNTER_COUNT), "accumulate.counters";
    /// Film sums of squares.
    BINDING_FILM_SQ = 20: crate::gpu::structs::GpuFilmPixel,
        buffer "FilmPixel film_sq[]", grows Film, "accumulate.film_sq";
    /// The environment map: its header (`EnvmapHeader`), texels, sampling
    /// CDFs and cell densities (`crate::gpu::envmap`); a zero header when
    /// the scene has none.
    BINDING_ENVMAP = 30: u32,
        readonly "uint envmap_words[]", grows Textures, "scene.envmap";
    /// The pixels an adaptive render samples (`SPEC_PIXEL_LIST`): per
    /// entry, the row-major image index of a pixel of the band that is
    /// still sampled (ascending), and the samples it holds, from which its
    /// samples of this call go on; a wave takes a run of entries
    /// (`crate::render::adaptive`).
    BINDING_PIXEL_LIST = 31: glam::UVec2,
        readonly "uvec2 pixel_list[]", grows Film, "generate.pixel_list";
    /// Film sums of the odd-numbered samples only: with the whole sums,
    /// the two half films of the error estimate (`crate::render::film`).
    BINDING_FILM_ODD = 29: crate::gpu::structs::GpuFilmPixel,
        buffer "FilmPixel film_odd[]", grows Film, "accumulate.film_odd";
}
