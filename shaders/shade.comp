#version 450
// shade: one thread per ray of the current queue. Add the emission or the
// environment, sample a light for next-event estimation (to the shadow
// queue), sample the material, apply Russian roulette, and put the path
// that goes on onto the next ray queue.
#extension GL_GOOGLE_include_directive : require
#include "common/path.glsl"

void main() {
    uint slot;
    if (!queue_item(ray_queue_of(pc.bounce), slot)) {
        return;
    }

    // Shade the hit; radiance is read only where it changes
    PathState path = PathState(read_state(ray_origin_texels, slot), read_state(ray_dir_texels, slot),
                               read_state(throughput_texels, slot), vec4(0.0));
    Shading sh = shade_hit(slot, pc.bounce, read_hit(slot), path);

    // Enqueue the light sample's shadow ray
    if (sh.shadow) {
        shadow_origin[slot] = sh.shadow_ray.origin;
        shadow_dir[slot] = sh.shadow_ray.dir;
        shadow_radiance[slot] = sh.shadow_ray.radiance;
        queue_push(SHADOW_QUEUE, slot);
    }

    // Enqueue the continuation ray
    if (sh.goes_on) {
        ray_origin[slot] = path.origin;
        ray_dir[slot] = path.dir;
        path_throughput[slot] = path.throughput;
        queue_push(ray_queue_of(pc.bounce + 1u), slot);
    }

    // Add the emission or environment
    if (sh.adds) {
        path_radiance[slot] = read_state(radiance_texels, slot) + sh.emitted;
    }
}
