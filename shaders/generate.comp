#version 450
// generate: one thread per path slot. Build the camera ray, start the path
// state and put the ray on ray queue 0.
#extension GL_GOOGLE_include_directive : require
#include "common/path.glsl"

void main() {
    uint slot = gl_GlobalInvocationID.x;
    if (slot >= pc.path_count) {
        return;
    }

    // Start the path state
    PathState path = start_path(slot);
    ray_origin[slot] = path.origin;
    ray_dir[slot] = path.dir;
    path_throughput[slot] = path.throughput;
    path_radiance[slot] = path.radiance;

    // Enqueue camera ray
    ray_queues[slot] = slot;
}
