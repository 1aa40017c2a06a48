#version 450
// intersect: one thread per ray of the current queue. Find the closest hit
// through the BVH and write the hit record of its path slot.
#extension GL_GOOGLE_include_directive : require
#include "common/path.glsl"

void main() {
    uint slot;
    if (!queue_item(ray_queue_of(pc.bounce), slot)) {
        return;
    }

    // Find the closest hit and record it: t, primitive, barycentrics
    hits[slot] = first_hit(read_state(ray_origin_texels, slot), read_state(ray_dir_texels, slot).xyz, pc.bounce);
}
