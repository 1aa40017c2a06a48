#version 450
// megakernel (f32 film): the same kernel for devices without shaderFloat64,
// folding the paths into the film with the f32 accumulate pass's
// compensated sums.
#extension GL_GOOGLE_include_directive : require
#define FILM_FP64 0
#include "common/accumulate.glsl"
#include "common/path.glsl"

// Trace the path of the slot from its camera ray to its end
vec3 finished_radiance(uint slot) { return trace_path(slot); }
