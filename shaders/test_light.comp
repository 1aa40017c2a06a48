#version 450
// test_light: a test hook, not a pass of the renderer. One thread per item:
// sample a light for next-event estimation from a point with the very
// function the shade kernel calls (sample_light), or take a direction
// given, and evaluate the environment map there with the functions an
// escaped path calls (envmap_pdf, envmap_radiance). The items sit in
// path-state buffers the renderer already binds:
//   in   ray_origin[i]        xy: random numbers u (sample), or xyz: wi (evaluate),
//                             w: TEST_LIGHT_* flags (bits)
//   in   ray_dir[i]           xyz: the point lit
//   out  shadow_origin[i]     xyz: sampled wi, w: its pdf
//   out  shadow_dir[i]        xyz: the sample's radiance, w: 1 when sample_light returned true
//   out  shadow_radiance[i]   xyz: envmap_radiance at wi, w: envmap_pdf at wi
// pc.path_count is the number of items.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"
#include "common/lights.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.path_count) {
        return;
    }

    // Read the item: the point, and u or wi
    vec4 a = ray_origin[i];
    vec3 from = ray_dir[i].xyz;
    uint flags = floatBitsToUint(a.w);

    // Sample a light, or take the direction given
    vec3 wi = a.xyz;
    if ((flags & TEST_LIGHT_EVALUATE) == 0u) {
        LightSample ls;
        bool ok = sample_light(from, a.xy, ls);
        shadow_origin[i] = vec4(ls.wi, ls.pdf);
        shadow_dir[i] = vec4(ls.le, ok ? 1.0 : 0.0);
        wi = ls.wi;
    }

    // Evaluate the environment map at the direction
    EnvmapHeader h = envmap_header();
    shadow_radiance[i] = envmap_present(h) ? vec4(envmap_radiance(h, wi), envmap_pdf(h, wi)) : vec4(0.0);
}
