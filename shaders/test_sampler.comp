#version 450
// test_sampler: a test hook, not a pass of the renderer. One thread per
// item: draw the numbers of one dimension of one path sample with the very
// functions the path code calls (sample_stream, sample_2d or
// sample_2d_partnered, sample_1d),
// under the sampler the SAMPLER specialisation constant names and the
// frame's seed and halves. The items sit in path-state buffers the
// renderer already binds:
//   in   ray_origin[i]      bits of (pixel, sample index, dimension, partner)
//   out  shadow_origin[i]   xy: the pair at the dimension (sample_2d, or
//                           sample_2d_partnered with the partner's draw unless
//                           the partner is TEST_SAMPLER_ALONE), z: sample_1d, w: 0
// pc.path_count is the number of items.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"
#include "common/sampler.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.path_count) {
        return;
    }

    // Draw the pair and the single number of the item's dimension
    uvec4 item = floatBitsToUint(ray_origin[i]);
    SampleStream st = sample_stream(frame.seed, item.x, item.y, frame.halves != 0u);
    vec2 pair = item.w == TEST_SAMPLER_ALONE ? sample_2d(st, item.z) : sample_2d_partnered(st, item.z, item.w);
    shadow_origin[i] = vec4(pair, sample_1d(st, item.z), 0.0);
}
