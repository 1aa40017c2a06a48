#version 450
// intersect: one thread per ray of the current queue. Find the closest hit
// through the BVH and write the hit record of its path slot.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"
#include "common/traverse.glsl"

void main() {
    uint slot;
    if (!queue_item(ray_queue_of(pc.bounce), slot)) {
        return;
    }

    // Find the closest hit
    vec4 o = read_state(ray_origin_texels, slot);
    vec3 d = read_state(ray_dir_texels, slot).xyz;
    uint prim;
    float t;
    vec2 bary;
    trace(o.xyz, d, o.w, false, prim, t, bary);

    // Record it: t, primitive, barycentrics
    hits[slot] = Hit(t, prim, bary);
}
