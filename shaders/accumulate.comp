#version 450
// accumulate: one thread per pixel the wave touched. Sum the finished
// radiance of that pixel's paths, in slot order, and fold the sums and the
// sums of squares into the film with compensated (Neumaier) additions.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"

// Add x to the compensated sum (sum, comp), per component
void neumaier_add(inout vec3 sum, inout vec3 comp, vec3 x) {
    precise vec3 t = sum + x;
    precise vec3 big_sum = (sum - t) + x;
    precise vec3 big_x = (x - t) + sum;
    comp += mix(big_x, big_sum, greaterThanEqual(abs(sum), abs(x)));
    sum = t;
}

void main() {
    uint t = gl_GlobalInvocationID.x;
    if (t >= min(pc.path_count, frame.pixel_count)) {
        return;
    }
    uint pixel = (pc.pixel_base + t) % frame.pixel_count;

    // Sum this pixel's samples of the wave, skipping non-finite ones
    precise vec3 s = vec3(0.0);
    precise vec3 sc = vec3(0.0);
    precise vec3 q = vec3(0.0);
    precise vec3 qc = vec3(0.0);
    uint nonfinite = 0u;
    for (uint slot = t; slot < pc.path_count; slot += frame.pixel_count) {
        vec3 l = path_radiance[slot].rgb;
        if (any(isnan(l)) || any(isinf(l))) {
            nonfinite += 1u;
            continue;
        }
        neumaier_add(s, sc, l);
        neumaier_add(q, qc, l * l);
    }
    if (nonfinite > 0u) {
        atomicAdd(counters[COUNTER_NONFINITE], nonfinite);
    }

    // Fold the wave's sums into the film
    precise vec3 fs = film[pixel].sum.rgb;
    precise vec3 fc = film[pixel].comp.rgb;
    neumaier_add(fs, fc, s);
    film[pixel] = FilmPixel(vec4(fs, 0.0), vec4(fc + sc, 0.0));
    precise vec3 gs = film_sq[pixel].sum.rgb;
    precise vec3 gc = film_sq[pixel].comp.rgb;
    neumaier_add(gs, gc, q);
    film_sq[pixel] = FilmPixel(vec4(gs, 0.0), vec4(gc + qc, 0.0));
}
