#version 450
// accumulate (f32 film): the same pass for devices without shaderFloat64,
// with Neumaier-compensated f32 sums (`precise` keeps the compiler from
// folding the compensation away).
#extension GL_GOOGLE_include_directive : require
#define FILM_FP64 0
#include "common/accumulate.glsl"

// Read the radiance the passes left in the path's slot
vec3 finished_radiance(uint slot) { return path_radiance[slot].rgb; }
