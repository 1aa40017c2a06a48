// Counter-based random numbers: every value is a hash of (seed, pixel,
// sample, dimension), so results never depend on thread order.
#ifndef RANDOM_GLSL
#define RANDOM_GLSL

// Hash one 32-bit word (PCG output permutation, Jarzynski & Olano 2020)
uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Derive the key of one path sample from the seed, pixel and sample
uint rng_key(uint seed, uint pixel, uint sample_index) {
    return pcg_hash(pixel ^ pcg_hash(sample_index ^ pcg_hash(seed)));
}

// Draw a uniform float in [0, 1) for dimension `dim` of a path sample
float rng_uniform(uint key, uint dim) {
    return float(pcg_hash(key ^ pcg_hash(dim + 0x9E3779B9u)) >> 8) * (1.0 / 16777216.0);
}

// Draw two uniform floats for dimensions dim and dim + 1
vec2 rng_uniform2(uint key, uint dim) {
    return vec2(rng_uniform(key, dim), rng_uniform(key, dim + 1u));
}

#endif
