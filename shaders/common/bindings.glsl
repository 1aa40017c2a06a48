// Buffers, structs, push constants and specialisation constants shared by
// every kernel. Constants are macros from src/interface/mod.rs, binding
// numbers and buffer declarations come from src/gpu/bindings.rs; struct
// layouts mirror src/gpu/structs.rs (std430).
#ifndef BINDINGS_GLSL
#define BINDINGS_GLSL

#extension GL_EXT_control_flow_attributes : enable
#extension GL_EXT_samplerless_texture_functions : require

layout(local_size_x_id = SPEC_WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;
// Threads per workgroup, as set from Rust when the pipeline is built
#define WORKGROUP_SIZE gl_WorkGroupSize.x

// Features of the scene, as specialisation constants
layout(constant_id = SPEC_HAS_SPHERES) const bool HAS_SPHERES = true;
layout(constant_id = SPEC_HAS_TRIANGLES) const bool HAS_TRIANGLES = true;
layout(constant_id = SPEC_NEE) const bool NEE = true;
layout(constant_id = SPEC_HAS_ENVIRONMENT) const bool HAS_ENVIRONMENT = true;
layout(constant_id = SPEC_MATERIAL_MASK) const uint MATERIAL_MASK = 0xFFFFFFFFu;
layout(constant_id = SPEC_HAS_TEXTURES) const bool HAS_TEXTURES = true;
layout(constant_id = SPEC_HAS_DOF) const bool HAS_DOF = true;
layout(constant_id = SPEC_OCCLUSION) const bool OCCLUSION = false;
layout(constant_id = SPEC_HAS_EMISSION) const bool HAS_EMISSION = true;
layout(constant_id = SPEC_HAS_DELTA_LIGHTS) const bool HAS_DELTA_LIGHTS = true;
layout(constant_id = SPEC_HAS_PATH_FLAGS) const bool HAS_PATH_FLAGS = true;
layout(constant_id = SPEC_HAS_SHADING_SIDES) const bool HAS_SHADING_SIDES = true;
layout(constant_id = SPEC_HAS_ENVMAP) const bool HAS_ENVMAP = true;
// The sampler the kernels draw with (SAMPLER_*), a renderer option
layout(constant_id = SPEC_SAMPLER) const uint SAMPLER = SAMPLER_INDEPENDENT;
layout(constant_id = SPEC_HAS_FILTER) const bool HAS_FILTER = true;
layout(constant_id = SPEC_HAS_CLIP) const bool HAS_CLIP = true;
// Film positions stay inside the image (Mitsuba's sample_border false)
layout(constant_id = SPEC_HAS_FILM_EDGE) const bool HAS_FILM_EDGE = true;
// The image's centre is off the optical axis (a crop window, a principal point)
layout(constant_id = SPEC_HAS_CAM_SHIFT) const bool HAS_CAM_SHIFT = true;
// A texture has Mitsuba lookup rules of its own (to_uv, wrap, nearest, a checkerboard)
layout(constant_id = SPEC_HAS_TEX_MAPPING) const bool HAS_TEX_MAPPING = true;
layout(constant_id = SPEC_HAS_MASK) const bool HAS_MASK = true;
layout(constant_id = SPEC_HAS_NORMAL_MAP) const bool HAS_NORMAL_MAP = true;
layout(constant_id = SPEC_HAS_MESH_ATTRIBUTES) const bool HAS_MESH_ATTRIBUTES = true;
// The camera is orthographic (Mitsuba's orthographic sensor)
layout(constant_id = SPEC_HAS_ORTHO) const bool HAS_ORTHO = true;
// The wave's pixels come from pixel_list (an adaptive render), a render option
layout(constant_id = SPEC_PIXEL_LIST) const bool PIXEL_LIST = false;

// Tell whether material type `t` may occur in this scene
bool material_present(uint t) { return (MATERIAL_MASK & (1u << t)) != 0u; }

struct Frame {
    vec4 eye;          // xyz eye, w lens radius
    vec4 cam_u;        // xyz right, w tan(vfov/2) * aspect
    vec4 cam_v;        // xyz up, w tan(vfov/2)
    vec4 cam_w;        // xyz backwards, w focus distance
    vec4 environment;  // rgb radiance
    uint width;
    uint height;
    uint spp;
    uint max_depth;
    uint seed;
    uint strata;
    uint emitter_count;
    uint wave_capacity;
    uint pixel_count;
    uint primitive_count;
    uint filter_kind;  // FILTER_*
    uint path_flags;   // PATH_FLAG_*
    float delta_light_gain;
    uint rr_depth;     // Russian roulette from the hit that ends this segment on
    uint halves;       // 1: the Sobol sampler draws even and odd samples as two sequences
    uint pad2;
    vec4 filter_params;  // x radius, yz parameters, w 1 / integral
    vec4 clip;         // x near, y far (along the optical axis), z 1 when clipping
    vec4 filter_table[FILTER_TABLE_VEC4S];  // inverse CDF of |filter|
    vec4 filter_edge[FILTER_EDGE_ENTRIES];  // the filter cut at the image's edge
    vec4 cam_shift;    // xyz added to camera ray directions (Camera::shift)
};

// Header of the BVH texels: the grid boxes are quantised on
struct BvhGrid {
    vec3 origin;    // scene box's lower corner
    uint root_ref;  // the root's node reference
    vec3 scale;     // grid step per axis
    uint pad;
};

// Two sibling nodes, one texel each: box corners quantised to 16 bits
// (min.x|min.y, min.z|max.x, max.y|max.z) and the node reference: for a leaf
// first primitive << BVH_REF_COUNT_BITS | count, for an interior node its
// children's pair << BVH_REF_COUNT_BITS
struct BvhPair {
    uvec3 left;
    uint left_ref;
    uvec3 right;
    uint right_ref;
};

struct Primitive {
    vec4 a;     // sphere: centre, radius; triangle: vertex 0, plane offset
    vec4 b;     // triangle: vertex 1; sphere (PRIM_FLAG_MITSUBA_FRAME): local x, handedness
    vec4 c;     // triangle: vertex 2; sphere (PRIM_FLAG_MITSUBA_FRAME): local y
    uvec4 meta; // prim_kind | prim_flags, material, shading index, emitter pmf bits
};

// Read the kind tag (PRIM_*) of a primitive
uint prim_kind(Primitive p) { return p.meta.x & ((1u << PRIM_KIND_BITS) - 1u); }

// Read the flags (PRIM_FLAG_*) of a primitive
uint prim_flags(Primitive p) { return p.meta.x >> PRIM_KIND_BITS; }

struct TriShading {
    vec4 n0;  // normal 0, u0
    vec4 n1;  // normal 1, u1
    vec4 n2;  // normal 2, u2
    vec4 v;   // v0, v1, v2
};

struct Material {
    vec4 color;     // rgb albedo / reflectance / tint, w ior or sin(cone) or alpha_u
    vec4 specular;  // rgb phong specular or conductor eta, w exponent or alpha_v
    vec4 emission;  // rgb emitted radiance, w 1 if emissive
    uvec4 info;     // type, texture index, flags (MAT_FLAG_*)
    vec4 params;    // rgb conductor k, w microfacet distribution id
    uvec4 layers;   // x a mask's constant opacity (f32 bits), y its texture, z a normal or bump map's texture, w bump scale
};

struct Emitter {
    uint prim;
    float cdf;
    float pmf;
    float area;
};

// A light with no area, after the emitter table (DELTA_LIGHT_TEXELS texels)
struct DeltaLight {
    vec4 p;          // xyz position or direction of travel, w kind (LIGHT_*) bits
    vec4 intensity;  // rgb intensity or irradiance (projector: pi scale E), w spot cos(cutoff), projector cot_x / 2
    vec4 local_x;    // spot, projector: world-to-light row 0, w spot cos(beam width), projector cot_y / 2
    vec4 local_y;    // spot, projector: world-to-light row 1, w spot sin(cutoff)
    vec4 local_z;    // spot, projector: world-to-light row 2, w spot 1 / (cutoff - beam width)
    vec4 extra;      // projector: xyz its axis; w texture index bits or NO_TEXTURE
};

// The environment map's header, at the start of its buffer (ENVMAP_HEADER_WORDS words)
struct EnvmapHeader {
    vec4 to_local_x;  // xyz world-to-map row 0, w the map's pick probability
    vec4 to_local_y;  // xyz world-to-map row 1
    vec4 to_local_z;  // xyz world-to-map row 2
    uvec4 grid;       // width (0: no map), height, first word of the marginal CDF, of the conditional CDFs
    uvec4 tables;     // first word of the cell densities
};

struct Hit {
    float t;     // distance along the unit ray direction
    uint prim;   // primitive index, NO_HIT for a ray that escaped
    vec2 bary;   // triangle barycentrics of vertices 1 and 2
};

struct QueueHeader {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
};

struct FilmPixel {
    uvec4 lo;  // f64 film: r, g bits; f32 film: sum bits
    uvec4 hi;  // f64 film: b bits; f32 film: compensation bits
};

const float FLT_MAX = 3.402823466e38;
const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;

// Declare every buffer the kernels bind, from the device interface table
// (src/gpu/bindings.rs, turned into GLSL by build.rs): std430 storage
// buffers, and RGBA32UI texel buffers for scene data and for reading path
// state, since on llvmpipe a per-lane texelFetch is a gather where a
// storage-buffer load of a per-lane address is a loop over the lanes.
#include "generated/buffers.glsl"

// Read the BVH's grid header: texel 0
BvhGrid bvh_grid() {
    uvec4 o = texelFetch(bvh_texels, 0);
    uvec4 s = texelFetch(bvh_texels, 1);
    return BvhGrid(uintBitsToFloat(o.xyz), o.w, uintBitsToFloat(s.xyz), s.w);
}

// Read the quantised box and reference of child `side` (0 left, 1 right)
// of node pair `pair`: one texel
uvec4 bvh_child(uint pair, uint side) {
    return texelFetch(bvh_texels, int(2u + 2u * pair + side));
}

// Read primitive `i`: four texels, floats stored as their bits
Primitive primitive(uint i) {
    int base = int(4u * i);
    return Primitive(uintBitsToFloat(texelFetch(primitive_texels, base)),
                     uintBitsToFloat(texelFetch(primitive_texels, base + 1)),
                     uintBitsToFloat(texelFetch(primitive_texels, base + 2)),
                     texelFetch(primitive_texels, base + 3));
}

// Read the shading data of triangle `i`: four texels
TriShading tri_shading(uint i) {
    int base = int(4u * i);
    return TriShading(uintBitsToFloat(texelFetch(tri_shading_texels, base)),
                      uintBitsToFloat(texelFetch(tri_shading_texels, base + 1)),
                      uintBitsToFloat(texelFetch(tri_shading_texels, base + 2)),
                      uintBitsToFloat(texelFetch(tri_shading_texels, base + 3)));
}

// Read material `i`: MATERIAL_TEXELS texels
Material material(uint i) {
    int base = int(MATERIAL_TEXELS * i);
    return Material(uintBitsToFloat(texelFetch(material_texels, base)),
                    uintBitsToFloat(texelFetch(material_texels, base + 1)),
                    uintBitsToFloat(texelFetch(material_texels, base + 2)),
                    texelFetch(material_texels, base + 3),
                    uintBitsToFloat(texelFetch(material_texels, base + 4)),
                    texelFetch(material_texels, base + 5));
}

// Read the vec4 of path slot `slot` from a texel view of path state
vec4 read_state(utextureBuffer view, uint slot) {
    return uintBitsToFloat(texelFetch(view, int(slot)));
}

// Read the hit record of path slot `slot`
Hit read_hit(uint slot) {
    uvec4 h = texelFetch(hit_texels, int(slot));
    return Hit(uintBitsToFloat(h.x), h.y, uintBitsToFloat(h.zw));
}

// Read emitter `i`: one texel
Emitter emitter(uint i) {
    uvec4 e = texelFetch(emitter_texels, int(i));
    return Emitter(e.x, uintBitsToFloat(e.y), uintBitsToFloat(e.z), uintBitsToFloat(e.w));
}

// Read delta light `k`: DELTA_LIGHT_TEXELS texels after the emitter table
DeltaLight delta_light(uint k) {
    int base = int(frame.emitter_count + DELTA_LIGHT_TEXELS * k);
    return DeltaLight(uintBitsToFloat(texelFetch(emitter_texels, base)),
                      uintBitsToFloat(texelFetch(emitter_texels, base + 1)),
                      uintBitsToFloat(texelFetch(emitter_texels, base + 2)),
                      uintBitsToFloat(texelFetch(emitter_texels, base + 3)),
                      uintBitsToFloat(texelFetch(emitter_texels, base + 4)),
                      uintBitsToFloat(texelFetch(emitter_texels, base + 5)));
}

// Tell whether path flag `f` (PATH_FLAG_*) is set for this render
bool path_flag(uint f) { return HAS_PATH_FLAGS && (frame.path_flags & f) != 0u; }

layout(push_constant) uniform Push {
    uint sample_base;
    uint pixel_base;
    uint path_count;
    uint bounce;
    uint wave_pixels;
    uint film_base;
} pc;

// Append `slot` to queue `q` and keep its indirect dispatch size current
void queue_push(uint q, uint slot) {
    uint i = atomicAdd(queue_headers[q].count, 1u);
    if (i % WORKGROUP_SIZE == 0u) {
        atomicAdd(queue_headers[q].groups_x, 1u);
    }
    if (q == SHADOW_QUEUE) {
        shadow_queue[i] = slot;
    } else {
        ray_queues[q * frame.wave_capacity + i] = slot;
    }
}

// Name the ray queue that bounce `bounce` reads; the next bounce reads the next one
uint ray_queue_of(uint bounce) { return bounce % RAY_QUEUE_COUNT; }

// Take this thread's item of queue `q`: the path slot; false when it has none
bool queue_item(uint q, out uint slot) {
    uint i = gl_GlobalInvocationID.x;
    if (i >= queue_headers[q].count) {
        return false;
    }
    slot = q == SHADOW_QUEUE ? shadow_queue[i] : ray_queues[q * frame.wave_capacity + i];
    return true;
}

// Find the image pixel of the wave's pixel `t` and the first sample of it
// the wave renders: pixel pixel_base + t from sample_base, or, with a pixel
// list, the pixel of entry pixel_base + t from its samples so far plus
// sample_base
uvec2 wave_pixel_sample(uint t) {
    if (PIXEL_LIST) {
        uvec2 entry = pixel_list[pc.pixel_base + t];
        return uvec2(entry.x, entry.y + pc.sample_base);
    }
    return uvec2(pc.pixel_base + t, pc.sample_base);
}

// Find the pixel and sample of wave slot `slot`: a wave renders samples
// of its wave_pixels pixels, pixel fastest
uvec2 path_pixel_sample(uint slot) {
    uvec2 first = wave_pixel_sample(slot % pc.wave_pixels);
    return uvec2(first.x, first.y + slot / pc.wave_pixels);
}

#endif
