// The accumulate kernel, shared by its two film encodings and by both
// schedules: one thread per pixel of the wave. Sum the finished radiance of
// that pixel's paths, in sample order, and fold the sums, the sums of
// squares and the sums of the odd-numbered samples (the second half film of
// the error estimate) into the film, which holds the band of rows from
// pixel film_base.
// FILM_FP64 = 1 sums in double precision (devices with shaderFloat64);
// FILM_FP64 = 0 keeps an f32 sum with a Neumaier compensation.
// The including kernel defines finished_radiance: the wavefront's accumulate
// reads what the passes left in path_radiance, the megakernel traces the
// whole path there and then.
#include "common/bindings.glsl"

#ifndef FILM_FP64
#error "build.rs defines FILM_FP64 for the kernels in FILM_F32_KERNELS"
#endif

// The finished radiance of the path in wave slot `slot`
vec3 finished_radiance(uint slot);

#if FILM_FP64

// Read a film pixel as three doubles
dvec3 film_value(FilmPixel f) {
    return dvec3(packDouble2x32(f.lo.xy), packDouble2x32(f.lo.zw), packDouble2x32(f.hi.xy));
}

// Write three doubles as a film pixel
FilmPixel film_pixel(dvec3 v) {
    return FilmPixel(uvec4(unpackDouble2x32(v.x), unpackDouble2x32(v.y)), uvec4(unpackDouble2x32(v.z), 0u, 0u));
}

#else

// Add x to the compensated sum (sum, comp), per component
void neumaier_add(inout vec3 sum, inout vec3 comp, vec3 x) {
    precise vec3 t = sum + x;
    precise vec3 big_sum = (sum - t) + x;
    precise vec3 big_x = (x - t) + sum;
    comp += mix(big_x, big_sum, greaterThanEqual(abs(sum), abs(x)));
    sum = t;
}

#endif

void main() {
    uint t = gl_GlobalInvocationID.x;
    if (t >= pc.wave_pixels) {
        return;
    }
    // Index the pixel in the band of the film the device holds
    uvec2 first = wave_pixel_sample(t);
    uint pixel = first.x - pc.film_base;
    uint nonfinite = 0u;

#if FILM_FP64
    // Sum this pixel's samples of the wave in double precision
    dvec3 s = dvec3(0.0);
    dvec3 q = dvec3(0.0);
    dvec3 o = dvec3(0.0);
    uint sample_index = first.y;
    for (uint slot = t; slot < pc.path_count; slot += pc.wave_pixels, ++sample_index) {
        vec3 l = finished_radiance(slot);
        if (any(isnan(l)) || any(isinf(l))) {
            nonfinite += 1u;
            continue;
        }
        dvec3 d = dvec3(l);
        s += d;
        q += d * d;
        if ((sample_index & 1u) != 0u) {
            o += d;
        }
    }

    // Fold the wave's sums into the film
    film[pixel] = film_pixel(film_value(film[pixel]) + s);
    film_sq[pixel] = film_pixel(film_value(film_sq[pixel]) + q);
    film_odd[pixel] = film_pixel(film_value(film_odd[pixel]) + o);
#else
    // Sum this pixel's samples of the wave with compensation
    precise vec3 s = vec3(0.0);
    precise vec3 sc = vec3(0.0);
    precise vec3 q = vec3(0.0);
    precise vec3 qc = vec3(0.0);
    precise vec3 o = vec3(0.0);
    precise vec3 oc = vec3(0.0);
    uint sample_index = first.y;
    for (uint slot = t; slot < pc.path_count; slot += pc.wave_pixels, ++sample_index) {
        vec3 l = finished_radiance(slot);
        if (any(isnan(l)) || any(isinf(l))) {
            nonfinite += 1u;
            continue;
        }
        neumaier_add(s, sc, l);
        neumaier_add(q, qc, l * l);
        if ((sample_index & 1u) != 0u) {
            neumaier_add(o, oc, l);
        }
    }

    // Fold the wave's sums into the film
    precise vec3 fs = uintBitsToFloat(film[pixel].lo.xyz);
    precise vec3 fc = uintBitsToFloat(film[pixel].hi.xyz);
    neumaier_add(fs, fc, s);
    film[pixel] = FilmPixel(uvec4(floatBitsToUint(fs), 0u), uvec4(floatBitsToUint(fc + sc), 0u));
    precise vec3 gs = uintBitsToFloat(film_sq[pixel].lo.xyz);
    precise vec3 gc = uintBitsToFloat(film_sq[pixel].hi.xyz);
    neumaier_add(gs, gc, q);
    film_sq[pixel] = FilmPixel(uvec4(floatBitsToUint(gs), 0u), uvec4(floatBitsToUint(gc + qc), 0u));
    precise vec3 hs = uintBitsToFloat(film_odd[pixel].lo.xyz);
    precise vec3 hc = uintBitsToFloat(film_odd[pixel].hi.xyz);
    neumaier_add(hs, hc, o);
    film_odd[pixel] = FilmPixel(uvec4(floatBitsToUint(hs), 0u), uvec4(floatBitsToUint(hc + oc), 0u));
#endif

    if (nonfinite > 0u) {
        atomicAdd(counters[COUNTER_NONFINITE], nonfinite);
    }
}
