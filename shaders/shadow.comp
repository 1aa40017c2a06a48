#version 450
// shadow: one thread per shadow ray. Test occlusion through the BVH and
// add the light sample's radiance to its path when nothing is in the way.
#extension GL_GOOGLE_include_directive : require
#include "common/path.glsl"

void main() {
    uint slot;
    if (!queue_item(SHADOW_QUEUE, slot)) {
        return;
    }

    // Add the light sample when nothing is in the way
    if (unoccluded(read_state(shadow_origin_texels, slot), read_state(shadow_dir_texels, slot).xyz)) {
        path_radiance[slot] = read_state(radiance_texels, slot) + read_state(shadow_radiance_texels, slot);
    }
}
