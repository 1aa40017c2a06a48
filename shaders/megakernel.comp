#version 450
// megakernel: the whole wave in one kernel, one thread per pixel of the
// wave. Each thread follows its pixel's paths of the wave one after the
// other (camera ray, bounces, shadow rays inline, path state in registers)
// and folds them into the film as the accumulate pass does. build.rs
// compiles it with FILM_FP64 = 1 and 0 (see common/accumulate.glsl).
#extension GL_GOOGLE_include_directive : require
#include "common/accumulate.glsl"
#include "common/path.glsl"

// Trace the path of the slot from its camera ray to its end
vec3 finished_radiance(uint slot) { return trace_path(slot); }
