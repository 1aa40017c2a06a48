// The sampler: the numbers of every dimension of a path sample, a pure
// function of (seed, pixel, sample index, dimension), so results never
// depend on thread order, waves or split renders. The specialisation
// constant SAMPLER chooses, and each kernel compiles only that one:
//
// - SAMPLER_INDEPENDENT: a hash per (seed, pixel, sample, dimension)
//   (common/random.glsl);
// - SAMPLER_SOBOL: shuffled, Owen-scrambled Sobol points (Burley 2020,
//   "Practical Hash-based Owen Scrambling", JCGT 9(4)). A fixed-spp render
//   draws one sequence per pixel, seeded by (seed, pixel). A progressive
//   render (frame.halves) draws two independent halves: the even-numbered
//   samples of a pixel and the odd-numbered ones are two sequences with
//   seeds of their own, sample i being sample i / 2 of half i % 2, so that
//   the two half films of the error estimate are independent
//   randomisations of the same integral (their difference measures the
//   error; two halves of one sequence would differ by its stratification,
//   not its error). The halves cost some of the stratification: n / 2
//   points of each sequence rather than n of one. Each draw (a 2D pair or
//   a 1D dimension) shuffles the index within its sequence with a nested
//   uniform scramble seeded by (sequence seed, dimension), so that draws
//   are decorrelated from one another, takes
//   the Sobol point of the shuffled index (dimensions 0 and 1 for a pair,
//   0 alone for a 1D draw) and Owen-scrambles each coordinate with a seed
//   of its own. Sobol dimensions 0 and 1 form a (0, 2)-sequence, and
//   shuffling and Owen scrambling keep that: in each sequence, for every k,
//   each aligned block of 2^k consecutive indices, the first 2^k included,
//   puts one point in each elementary interval of area 2^-k. Any prefix is
//   well spread, so progressive renders need nothing else.
//
//   A pair draw may be partnered with an earlier pair draw of the same
//   path (sample_2d_partnered): it takes Sobol dimensions 2 and 3 of the
//   partner's shuffled index, scrambled with its own seeds, so that the two
//   pairs are one 4D Sobol point, stratified together (render::sobol).
#ifndef SAMPLER_GLSL
#define SAMPLER_GLSL

#include "common/random.glsl"
#include "generated/sobol.glsl"

// Where the numbers of one path sample come from
struct SampleStream {
    uint key;    // independent: rng_key of the sample; Sobol: the seed of the pixel's sequence
    uint index;  // independent: the sample index; Sobol: the index within the sequence
};

// Permute a 32-bit word so that each bit flips by a function of the bits
// below it (a Laine-Karras style hash; the constants are Vegdahl's 2021
// "better" variant, which pbrt-v4 and Cycles also use)
uint lk_permute(uint x, uint seed) {
    x ^= x * 0x3D20ADEAu;
    x += seed;
    x *= (seed >> 16u) | 1u;
    x ^= x * 0x05526C56u;
    x ^= x * 0x53A22864u;
    return x;
}

// Scramble a 32-bit fraction by a nested uniform (Owen) scramble: each digit
// flips by a hash of the digits above it
uint owen_scramble(uint x, uint seed) {
    return bitfieldReverse(lk_permute(bitfieldReverse(x), seed));
}

// Compute dimension 0 of Sobol point `index` as a 32-bit fraction: the van
// der Corput sequence, the index's bits reversed
uint sobol0(uint index) { return bitfieldReverse(index); }

// Compute dimension 1 of Sobol point `index` as a 32-bit fraction. Its
// generator (polynomial x + 1) is Pascal's triangle mod 2: by Lucas'
// theorem bit k of the index adds to fraction digit i (bit 31 - i) when the
// bits of i are a subset of those of k, so digit i is the xor of the index
// bits at every superset of i: a superset transform over the 5-bit
// positions, five shifts, then the digits reversed into a fraction.
// render::sobol::tests checks it against the direction numbers.
uint sobol1(uint index) {
    uint y = index;
    y ^= (y >> 1u) & 0x55555555u;
    y ^= (y >> 2u) & 0x33333333u;
    y ^= (y >> 4u) & 0x0F0F0F0Fu;
    y ^= (y >> 8u) & 0x00FF00FFu;
    y ^= (y >> 16u) & 0x0000FFFFu;
    return bitfieldReverse(y);
}

// Compute dimensions 2 and 3 of Sobol point `index` as 32-bit fractions,
// from their direction numbers: each set bit of the index adds (xor) its
// column of both
uvec2 sobol23(uint index) {
    uvec2 x = uvec2(0u);
    for (uint bit = 0u; bit < 32u; bit++) {
        uint mask = 0u - ((index >> bit) & 1u);
        x ^= mask & uvec2(SOBOL_DIRECTIONS[bit], SOBOL_DIRECTIONS[32u + bit]);
    }
    return x;
}

// Turn the top 24 bits of a 32-bit fraction into a float in [0, 1)
float fraction_to_float(uint x) { return float(x >> 8) * (1.0 / 16777216.0); }

// Derive the seed of draw `dim` of a pixel whose seed is pixel_seed
uint sobol_draw_seed(uint pixel_seed, uint dim) {
    return pcg_hash(pixel_seed ^ pcg_hash(dim + 0x9E3779B9u));
}

// Shuffle the sample index for the draw whose seed is draw_seed
uint sobol_shuffled_index(uint index, uint draw_seed) { return owen_scramble(index, draw_seed); }

// Start the numbers of one path sample of pixel `pixel`, in two independent
// halves when `halves`
SampleStream sample_stream(uint seed, uint pixel, uint sample_index, bool halves) {
    if (SAMPLER == SAMPLER_SOBOL) {
        uint pixel_seed = pcg_hash(pixel ^ pcg_hash(seed ^ 0x5BD1E995u));
        if (!halves) {
            return SampleStream(pixel_seed, sample_index);
        }
        uint half_seed = pcg_hash(pixel_seed + (sample_index & 1u) * 0x6A09E667u);
        return SampleStream(half_seed, sample_index >> 1u);
    }
    return SampleStream(rng_key(seed, pixel, sample_index), sample_index);
}

// Draw the number of dimension `dim` in [0, 1)
float sample_1d(SampleStream s, uint dim) {
    if (SAMPLER == SAMPLER_SOBOL) {
        uint draw = sobol_draw_seed(s.key, dim);
        uint index = sobol_shuffled_index(s.index, draw);
        return fraction_to_float(owen_scramble(sobol0(index), pcg_hash(draw + 1u)));
    }
    return rng_uniform(s.key, dim);
}

// Draw the numbers of dimensions dim and dim + 1 in [0, 1)^2, as one pair
vec2 sample_2d(SampleStream s, uint dim) {
    if (SAMPLER == SAMPLER_SOBOL) {
        uint draw = sobol_draw_seed(s.key, dim);
        uint index = sobol_shuffled_index(s.index, draw);
        uint x = owen_scramble(sobol0(index), pcg_hash(draw + 1u));
        uint y = owen_scramble(sobol1(index), pcg_hash(draw + 2u));
        return vec2(fraction_to_float(x), fraction_to_float(y));
    }
    return rng_uniform2(s.key, dim);
}

// Draw the numbers of dimensions dim and dim + 1 as a pair partnered with
// the pair draw at `partner`: under the Sobol sampler, Sobol dimensions 2
// and 3 of the partner's shuffled index, so that the partner's pair and
// this one are one 4D point; under the independent sampler, sample_2d
vec2 sample_2d_partnered(SampleStream s, uint dim, uint partner) {
    if (SAMPLER == SAMPLER_SOBOL) {
        uint index = sobol_shuffled_index(s.index, sobol_draw_seed(s.key, partner));
        uint draw = sobol_draw_seed(s.key, dim);
        uvec2 p = sobol23(index);
        uint x = owen_scramble(p.x, pcg_hash(draw + 1u));
        uint y = owen_scramble(p.y, pcg_hash(draw + 2u));
        return vec2(fraction_to_float(x), fraction_to_float(y));
    }
    return sample_2d(s, dim);
}

#endif
