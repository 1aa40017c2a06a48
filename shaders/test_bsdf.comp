#version 450
// test_bsdf: a test hook, not a pass of the renderer. One thread per item:
// sample a material, or evaluate it at a given direction, with the very
// functions the shade kernel calls (bsdf_sample, bsdf_eval), on a surface
// at the origin whose geometric and shading normals are +z and whose tangent
// dp/du is +x. The items sit
// in path-state buffers the renderer already binds:
//   in   ray_origin[i]        xyz: random numbers u (sample) or wi (evaluate),
//                             w: material index (bits)
//   in   ray_dir[i]           xyz: wo, w: TEST_BSDF_* flags (bits)
//   out  shadow_origin[i]     xyz: sampled wi, w: its pdf
//   out  shadow_dir[i]        xyz: sample weight, w: TEST_BSDF_* result flags (bits)
//   out  shadow_radiance[i]   xyz: f * cos at wi, w: bsdf_eval's pdf at wi
// pc.path_count is the number of items.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"
#include "common/bsdf.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.path_count) {
        return;
    }

    // Read the item: material, side, wo, and u or wi
    vec4 a = ray_origin[i];
    vec4 b = ray_dir[i];
    Material m = material(floatBitsToUint(a.w));
    uint flags = floatBitsToUint(b.w);
    Surface s;
    s.p = vec3(0.0);
    s.ng = vec3(0.0, 0.0, 1.0);
    s.ns = s.ng;
    s.uv = vec2(0.0);
    s.dpdu = vec3(1.0, 0.0, 0.0);
    s.tri = NO_TEXTURE;
    s.bary = vec2(0.0);
    s.front = (flags & TEST_BSDF_FRONT) != 0u;
    vec3 wo = b.xyz;

    // Sample the material, or take the direction given
    vec3 wi = a.xyz;
    if ((flags & TEST_BSDF_EVALUATE) == 0u) {
        BsdfSample bs;
        bool ok = bsdf_sample(m, s, wo, a.xyz, bs);
        uint result = (ok ? TEST_BSDF_OK : 0u) | (bs.delta ? TEST_BSDF_DELTA : 0u);
        shadow_origin[i] = vec4(bs.wi, bs.pdf);
        shadow_dir[i] = vec4(bs.weight, uintBitsToFloat(result));
        wi = bs.wi;
    }

    // Evaluate f * cos and the pdf at the direction
    float pdf;
    vec3 f = bsdf_eval(m, s, wo, wi, pdf);
    shadow_radiance[i] = vec4(f, pdf);
}
