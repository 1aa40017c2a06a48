#version 450
// accumulate (f64 film): one thread per pixel of the wave; folds the
// wave's radiance sums and sums of squares into the film in double
// precision. Used on devices with shaderFloat64.
#extension GL_GOOGLE_include_directive : require
#define FILM_FP64 1
#include "common/accumulate.glsl"

// Read the radiance the passes left in the path's slot
vec3 finished_radiance(uint slot) { return path_radiance[slot].rgb; }
