//! The one home of every constant shared between Rust and GLSL.
//!
//! `build.rs` includes this file and passes each entry of [`SHADER_DEFINES`]
//! to shaderc as a macro, so kernels never repeat a number written here.
//! This file must stay free of `use` items and crate paths: `build.rs`
//! compiles it as a module of its own.

/// Threads per workgroup of every 1-D kernel. Kernels get it as a
/// specialisation constant (`SPEC_WORKGROUP_SIZE`) when their pipeline is
/// built, so the local size and the Rust dispatch sizes cannot disagree.
pub const WORKGROUP_SIZE: u32 = 64;

/// Depth of the per-thread BVH traversal stack.
pub const BVH_STACK_SIZE: u32 = 32;

/// Primitives per BVH leaf at most.
pub const BVH_MAX_LEAF_PRIMS: u32 = 4;

/// Most samples of one pixel in one wave. The accumulate kernel runs one
/// thread per pixel that loops over them, and that loop must stay short:
/// llvmpipe stops any shader loop after 65,535 iterations, and a GPU
/// watchdog dislikes long-running threads.
pub const MAX_WAVE_SAMPLES_PER_PIXEL: u32 = 1024;

/// Primitive kind tag: sphere.
pub const PRIM_SPHERE: u32 = 0;
/// Primitive kind tag: triangle.
pub const PRIM_TRIANGLE: u32 = 1;

/// Index of the shadow queue among the queue headers (after the ray queues).
pub const SHADOW_QUEUE: u32 = 2;
/// Number of queue headers: the ray queues and the shadow queue.
pub const QUEUE_HEADER_COUNT: u32 = 3;
/// Random dimensions that the generate kernel uses (pixel jitter, lens).
pub const RNG_DIMS_CAMERA: u32 = 4;
/// Random dimensions each bounce of the shade kernel uses.
pub const RNG_DIMS_PER_BOUNCE: u32 = 8;
/// Russian roulette may end a path once it has this many segments (the
/// camera ray is segment 1).
pub const RR_MIN_SEGMENTS: u32 = 3;
/// Texture index meaning "no texture".
pub const NO_TEXTURE: u32 = 0xFFFF_FFFF;

/// Hit record value of `prim` for a ray that escaped the scene.
pub const NO_HIT: u32 = 0xFFFF_FFFF;

/// Material type tag: Lambertian.
pub const MAT_LAMBERT: u32 = 0;
/// Material type tag: normalised Phong.
pub const MAT_PHONG: u32 = 1;
/// Material type tag: mirror.
pub const MAT_MIRROR: u32 = 2;
/// Material type tag: glossy cone reflection.
pub const MAT_GLOSSY: u32 = 3;
/// Material type tag: dielectric.
pub const MAT_DIELECTRIC: u32 = 4;

/// Number of ray queues (current and next bounce).
pub const RAY_QUEUE_COUNT: u32 = 2;

/// Descriptor binding: `GpuFrame` uniform-like storage buffer.
pub const BINDING_FRAME: u32 = 0;
/// Descriptor binding: flattened BVH nodes.
pub const BINDING_BVH_NODES: u32 = 1;
/// Descriptor binding: primitives in BVH leaf order.
pub const BINDING_PRIMITIVES: u32 = 2;
/// Descriptor binding: per-triangle shading data (normals, uvs).
pub const BINDING_TRI_SHADING: u32 = 3;
/// Descriptor binding: materials.
pub const BINDING_MATERIALS: u32 = 4;
/// Descriptor binding: emitter primitive indices and CDF.
pub const BINDING_EMITTERS: u32 = 5;
/// Descriptor binding: queue headers (counts and indirect dispatch args).
pub const BINDING_QUEUE_HEADERS: u32 = 6;
/// Descriptor binding: ray queue items, `RAY_QUEUE_COUNT` x wave size.
pub const BINDING_RAY_QUEUES: u32 = 7;
/// Descriptor binding: shadow queue items.
pub const BINDING_SHADOW_QUEUE: u32 = 8;
/// Descriptor binding: path state, ray origins.
pub const BINDING_RAY_ORIGIN: u32 = 9;
/// Descriptor binding: path state, ray directions.
pub const BINDING_RAY_DIR: u32 = 10;
/// Descriptor binding: path state, throughput and last BSDF pdf.
pub const BINDING_THROUGHPUT: u32 = 11;
/// Descriptor binding: path state, radiance gathered so far.
pub const BINDING_RADIANCE: u32 = 12;
/// Descriptor binding: hit records.
pub const BINDING_HITS: u32 = 13;
/// Descriptor binding: shadow ray origins and tmax.
pub const BINDING_SHADOW_ORIGIN: u32 = 14;
/// Descriptor binding: shadow ray directions.
pub const BINDING_SHADOW_DIR: u32 = 15;
/// Descriptor binding: radiance a shadow ray adds when unoccluded.
pub const BINDING_SHADOW_RADIANCE: u32 = 16;
/// Descriptor binding: film sums (compensated).
pub const BINDING_FILM: u32 = 17;
/// Descriptor binding: textures, all texels of all textures.
pub const BINDING_TEXELS: u32 = 18;
/// Descriptor binding: counters the passes keep (non-finite samples, ...).
pub const BINDING_COUNTERS: u32 = 19;
/// Descriptor binding: film sums of squares (compensated).
pub const BINDING_FILM_SQ: u32 = 20;
/// Number of descriptor bindings.
pub const BINDING_COUNT: u32 = 21;

/// Specialisation constant id: scene has spheres.
pub const SPEC_HAS_SPHERES: u32 = 0;
/// Specialisation constant id: scene has triangles.
pub const SPEC_HAS_TRIANGLES: u32 = 1;
/// Specialisation constant id: next-event estimation is on (scene has emitters).
pub const SPEC_NEE: u32 = 2;
/// Specialisation constant id: environment is not black.
pub const SPEC_HAS_ENVIRONMENT: u32 = 3;
/// Specialisation constant id: bit mask of material types present (1 << MAT_*).
pub const SPEC_MATERIAL_MASK: u32 = 4;
/// Specialisation constant id: textures are used.
pub const SPEC_HAS_TEXTURES: u32 = 5;
/// Specialisation constant id: thin-lens depth of field.
pub const SPEC_HAS_DOF: u32 = 6;
/// Specialisation constant id: the shadow kernel runs in occlusion mode.
pub const SPEC_OCCLUSION: u32 = 7;
/// Specialisation constant id: emission anywhere (MIS weights needed).
pub const SPEC_HAS_EMISSION: u32 = 8;

/// Specialisation constant id: threads per workgroup (`WORKGROUP_SIZE`).
pub const SPEC_WORKGROUP_SIZE: u32 = 11;
/// Specialisation constant id: the one material type a shade dispatch
/// handles, or `ALL_MATERIALS` for the single shade dispatch.
pub const SPEC_SHADE_MATERIAL: u32 = 9;
/// Specialisation constant id: this shade dispatch also handles misses.
pub const SPEC_SHADE_MISSES: u32 = 10;
/// `SPEC_SHADE_MATERIAL` value: one shade dispatch handles every material.
pub const ALL_MATERIALS: u32 = 0xFFFF_FFFF;

/// Counter slot: samples dropped because their radiance was NaN or infinite.
pub const COUNTER_NONFINITE: u32 = 0;
/// Number of counter slots.
pub const COUNTER_COUNT: u32 = 4;

/// Every constant above, as `(macro name, value)` for the shader compiler.
pub const SHADER_DEFINES: &[(&str, u32)] = &[
    ("MAX_WAVE_SAMPLES_PER_PIXEL", MAX_WAVE_SAMPLES_PER_PIXEL),
    ("BVH_STACK_SIZE", BVH_STACK_SIZE),
    ("BVH_MAX_LEAF_PRIMS", BVH_MAX_LEAF_PRIMS),
    ("PRIM_SPHERE", PRIM_SPHERE),
    ("PRIM_TRIANGLE", PRIM_TRIANGLE),
    ("NO_HIT", NO_HIT),
    ("SHADOW_QUEUE", SHADOW_QUEUE),
    ("QUEUE_HEADER_COUNT", QUEUE_HEADER_COUNT),
    ("RNG_DIMS_CAMERA", RNG_DIMS_CAMERA),
    ("RNG_DIMS_PER_BOUNCE", RNG_DIMS_PER_BOUNCE),
    ("RR_MIN_SEGMENTS", RR_MIN_SEGMENTS),
    ("NO_TEXTURE", NO_TEXTURE),
    ("MAT_LAMBERT", MAT_LAMBERT),
    ("MAT_PHONG", MAT_PHONG),
    ("MAT_MIRROR", MAT_MIRROR),
    ("MAT_GLOSSY", MAT_GLOSSY),
    ("MAT_DIELECTRIC", MAT_DIELECTRIC),
    ("RAY_QUEUE_COUNT", RAY_QUEUE_COUNT),
    ("BINDING_FRAME", BINDING_FRAME),
    ("BINDING_BVH_NODES", BINDING_BVH_NODES),
    ("BINDING_PRIMITIVES", BINDING_PRIMITIVES),
    ("BINDING_TRI_SHADING", BINDING_TRI_SHADING),
    ("BINDING_MATERIALS", BINDING_MATERIALS),
    ("BINDING_EMITTERS", BINDING_EMITTERS),
    ("BINDING_QUEUE_HEADERS", BINDING_QUEUE_HEADERS),
    ("BINDING_RAY_QUEUES", BINDING_RAY_QUEUES),
    ("BINDING_SHADOW_QUEUE", BINDING_SHADOW_QUEUE),
    ("BINDING_RAY_ORIGIN", BINDING_RAY_ORIGIN),
    ("BINDING_RAY_DIR", BINDING_RAY_DIR),
    ("BINDING_THROUGHPUT", BINDING_THROUGHPUT),
    ("BINDING_RADIANCE", BINDING_RADIANCE),
    ("BINDING_HITS", BINDING_HITS),
    ("BINDING_SHADOW_ORIGIN", BINDING_SHADOW_ORIGIN),
    ("BINDING_SHADOW_DIR", BINDING_SHADOW_DIR),
    ("BINDING_SHADOW_RADIANCE", BINDING_SHADOW_RADIANCE),
    ("BINDING_FILM", BINDING_FILM),
    ("BINDING_TEXELS", BINDING_TEXELS),
    ("BINDING_COUNTERS", BINDING_COUNTERS),
    ("BINDING_FILM_SQ", BINDING_FILM_SQ),
    ("SPEC_HAS_SPHERES", SPEC_HAS_SPHERES),
    ("SPEC_HAS_TRIANGLES", SPEC_HAS_TRIANGLES),
    ("SPEC_NEE", SPEC_NEE),
    ("SPEC_HAS_ENVIRONMENT", SPEC_HAS_ENVIRONMENT),
    ("SPEC_MATERIAL_MASK", SPEC_MATERIAL_MASK),
    ("SPEC_HAS_TEXTURES", SPEC_HAS_TEXTURES),
    ("SPEC_HAS_DOF", SPEC_HAS_DOF),
    ("SPEC_OCCLUSION", SPEC_OCCLUSION),
    ("SPEC_HAS_EMISSION", SPEC_HAS_EMISSION),
    ("SPEC_WORKGROUP_SIZE", SPEC_WORKGROUP_SIZE),
    ("SPEC_SHADE_MATERIAL", SPEC_SHADE_MATERIAL),
    ("SPEC_SHADE_MISSES", SPEC_SHADE_MISSES),
    ("ALL_MATERIALS", ALL_MATERIALS),
    ("COUNTER_NONFINITE", COUNTER_NONFINITE),
    ("COUNTER_COUNT", COUNTER_COUNT),
];
