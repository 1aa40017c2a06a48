#version 450
// generate: one thread per path slot. Build the camera ray, start the path
// state and put the ray on ray queue 0.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"
#include "common/random.glsl"
#include "common/sampling.glsl"

void main() {
    uint slot = gl_GlobalInvocationID.x;
    if (slot >= pc.path_count) {
        return;
    }

    // Locate the pixel and sample this path slot renders
    uvec2 ps = path_pixel_sample(slot);
    uint pixel = ps.x;
    uint sample_index = ps.y;
    uint key = rng_key(frame.seed, pixel, sample_index);
    vec2 pixel_xy = vec2(float(pixel % frame.width), float(pixel / frame.width));

    // Jitter the sample inside its stratum of the pixel
    vec2 jitter = rng_uniform2(key, 0u);
    if (frame.strata > 0u) {
        uint cell = sample_index % (frame.strata * frame.strata);
        vec2 stratum = vec2(float(cell % frame.strata), float(cell / frame.strata));
        jitter = (stratum + jitter) / float(frame.strata);
    }
    vec2 film = (pixel_xy + jitter) / vec2(float(frame.width), float(frame.height));

    // Shoot a ray through the film point
    vec2 ndc = vec2(2.0 * film.x - 1.0, 1.0 - 2.0 * film.y);
    vec3 dir = ndc.x * frame.cam_u.w * frame.cam_u.xyz + ndc.y * frame.cam_v.w * frame.cam_v.xyz
        - frame.cam_w.xyz;
    vec3 origin = frame.eye.xyz;
    if (HAS_DOF && frame.eye.w > 0.0) {
        // Move the origin across the thin lens and aim at the plane in focus,
        // relative to the eye: (eye + dir f) - (eye + lens) would cancel far from the origin
        vec2 lens = frame.eye.w * sample_disk_concentric(rng_uniform2(key, 2u));
        vec3 lens_offset = lens.x * frame.cam_u.xyz + lens.y * frame.cam_v.xyz;
        origin += lens_offset;
        dir = dir * frame.cam_w.w - lens_offset;
    }

    // Start the path state
    ray_origin[slot] = vec4(origin, FLT_MAX);
    ray_dir[slot] = vec4(normalize(dir), 0.0);
    path_throughput[slot] = vec4(1.0, 1.0, 1.0, 0.0);
    path_radiance[slot] = vec4(0.0);

    // Enqueue camera ray
    ray_queues[slot] = slot;
}
