#version 450
// shadow: one thread per shadow ray. Test occlusion through the BVH and
// add the light sample's radiance to its path when nothing is in the way.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"
#include "common/traverse.glsl"

void main() {
    uint slot;
    if (!queue_item(SHADOW_QUEUE, slot)) {
        return;
    }

    // Look for any hit before the light
    vec4 o = read_state(shadow_origin_texels, slot);
    vec3 d = read_state(shadow_dir_texels, slot).xyz;
    uint prim;
    float t;
    vec2 bary;
    if (!trace(o.xyz, d, o.w, true, prim, t, bary)) {
        // Add the unoccluded light sample
        path_radiance[slot] = read_state(radiance_texels, slot) + read_state(shadow_radiance_texels, slot);
    }
}
