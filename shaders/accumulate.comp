#version 450
// accumulate: one thread per pixel of the wave; folds the wave's radiance
// sums and sums of squares into the film. build.rs compiles it with
// FILM_FP64 = 1 (double precision, devices with shaderFloat64) and with
// FILM_FP64 = 0 (compensated f32 sums).
#extension GL_GOOGLE_include_directive : require
#include "common/accumulate.glsl"

// Read the radiance the passes left in the path's slot
vec3 finished_radiance(uint slot) { return path_radiance[slot].rgb; }
