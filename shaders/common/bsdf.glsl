// Materials: sample a direction, evaluate f * cos, and give the pdf. Each
// material type sits behind `material_present`, a specialisation constant,
// so a scene without it compiles the code away.
#ifndef BSDF_GLSL
#define BSDF_GLSL

#include "common/sampling.glsl"
#include "common/textures.glsl"
#include "common/microfacet.glsl"

// Local shading geometry at a hit, oriented towards the incoming ray
struct Surface {
    vec3 p;       // position
    vec3 ng;      // geometric normal, on the side of wo
    vec3 ns;      // shading normal, on the side of wo
    vec2 uv;      // texture coordinates
    bool front;   // wo is on the front side of the geometric normal
    vec3 dpdu;    // tangent dp/du (not unit), set only where a material needs it
    vec3 ns_front; // shading normal before orienting it (front side out)
    uint tri;     // the triangle's shading index (mesh attributes), NO_TEXTURE on a sphere
    vec2 bary;    // the hit's barycentrics of vertices 1 and 2 (mesh attributes)
};

// Look up texture `tex` at surface s: a mesh attribute at the hit's
// barycentrics, any other texture at its uv
vec3 surface_texture(uint tex, Surface s) {
    if (HAS_MESH_ATTRIBUTES) {
        uvec4 header = texture_header(tex);
        if (header.w == TEXELS_ATTRIBUTE) {
            return attribute_lookup(header, s.tri, s.bary);
        }
    }
    return texture_lookup(tex, s.uv);
}

// The result of sampling a material
struct BsdfSample {
    vec3 wi;      // sampled direction
    vec3 weight;  // f * |cos| / pdf
    float pdf;    // solid-angle pdf; 0 for a delta lobe
    bool delta;   // the direction came from a delta lobe (no MIS)
    bool weigh;   // weight and pdf are still to come from the material's evaluation
};

// Tell whether a material is sampled only by its own strategy: mirror,
// smooth and thin dielectrics, and glossy cone reflection (whose estimator
// weight is the reflectance: the shade kernel combines no pdf for it)
bool material_is_delta(Material m) {
    uint t = m.info.x;
    return t == MAT_MIRROR || t == MAT_DIELECTRIC || t == MAT_GLOSSY || t == MAT_CONDUCTOR
        || t == MAT_THINDIELECTRIC;
}

// Find the opacity of a masked material at a surface point (Mitsuba's
// mask): a constant, or a texture holding its luminance in every channel;
// clamped to [0, 1] as Mitsuba clamps it
float material_opacity(Material m, Surface s) {
    float opacity = uintBitsToFloat(m.layers.x);
    if (HAS_TEXTURES && m.layers.y != NO_TEXTURE) {
        opacity = surface_texture(m.layers.y, s).r;
    }
    return clamp(opacity, 0.0, 1.0);
}

// Tilt the shading normal of surface s by material m's normal map, seen
// from wo (Mitsuba's normalmap): the texel's 2 c - 1 in the frame of the
// front shading normal and dp/du (s.dpdu) with its third axis along s.ns;
// or by its bump map (Mitsuba's bumpmap): the normal of the surface moved
// along its front shading normal by the heights' gradient times the
// scale, dpdv being dp/dv in Mitsuba's texture coordinates, and turned to
// the front of the geometric normal ng_front. Behind a map that wraps a
// two-sided material, its tilt mirrored through the surface; turned to
// face wo where it does not. s.dpdu becomes the tilted frame's tangent
void tilt_shading_normal(Material m, inout Surface s, vec3 wo, vec3 dpdv, vec3 ng_front) {
    // Build Mitsuba's shading frame: dp/du made orthogonal to the front normal
    vec3 d = s.dpdu - dot(s.ns_front, s.dpdu) * s.ns_front;
    float len2 = dot(d, d);
    vec3 t, b;
    if (len2 > 0.0) {
        t = d * inversesqrt(len2);
        b = cross(s.ns_front, t);
    } else {
        orthonormal_basis(s.ns_front, t, b);
    }
    vec3 c;
    if ((m.info.z & MAT_FLAG_BUMP_MAP) != 0u) {
        // Move the surface along its normal by the heights, and take the
        // normal of the moved surface in the shading frame
        vec2 g = uintBitsToFloat(m.layers.w) * texture_gradient(m.layers.z, s.uv);
        vec3 n = s.ns_front;
        vec3 du = s.dpdu + (g.x - dot(n, s.dpdu)) * n;
        vec3 dv = dpdv + (g.y - dot(n, dpdv)) * n;
        vec3 nb = normalize(cross(du, dv));
        nb = dot(ng_front, nb) < 0.0 ? -nb : nb;
        c = vec3(dot(nb, t), dot(nb, b), dot(nb, n));
    } else {
        c = 2.0 * texture_lookup(m.layers.z, s.uv) - 1.0;
    }
    if ((m.info.z & MAT_FLAG_NORMAL_MAP_MIRRORED) != 0u && dot(s.ns_front, wo) < 0.0) {
        c.xy = -c.xy;
    }
    vec3 n = c.x * t + c.y * b + c.z * s.ns;
    if (dot(wo, n) <= 0.0) {
        // Turn the tilt to face the viewer (flip_invalid_normals)
        n = -c.x * t - c.y * b + c.z * s.ns;
    }
    s.ns = normalize(n);
    s.dpdu = t - dot(s.ns, t) * s.ns;
}

// The factor a normal map puts on the response to light from wi (Mitsuba's
// normalmap): 0 unless wi lies on the same side of the surface's own
// shading normal n and the tilted one nt; else, when enabled, Mitsuba's
// shadowing term for tilted normals (Estevez et al. 2019)
float tilt_factor(Material m, vec3 n, vec3 nt, vec3 wi) {
    float cos_i = dot(wi, n);
    if (cos_i * dot(wi, nt) <= 0.0) {
        return 0.0;
    }
    if ((m.info.z & MAT_FLAG_NORMAL_MAP_SHADOWING) == 0u) {
        return 1.0;
    }
    float cos_d = dot(nt, n);
    float alpha2 = min(0.125 * max(1.0 - cos_d * cos_d, 0.0) / (cos_d * cos_d), 1.0);
    float tan2_i = max(1.0 - cos_i * cos_i, 0.0) / (cos_i * cos_i);
    return 2.0 / (1.0 + sqrt(1.0 + alpha2 * tan2_i));
}

// Find the diffuse colour of a material at a surface point
vec3 material_albedo(Material m, Surface s) {
    if (HAS_TEXTURES && m.info.y != NO_TEXTURE) {
        return surface_texture(m.info.y, s);
    }
    return m.color.rgb;
}

// Reflect wo about unit n
vec3 mirror_direction(vec3 wo, vec3 n) {
    return 2.0 * dot(wo, n) * n - wo;
}

// Probability of picking the diffuse lobe of a Phong material
float phong_diffuse_probability(vec3 kd, vec3 ks) {
    float d = kd.r + kd.g + kd.b;
    float s = ks.r + ks.g + ks.b;
    return d + s > 0.0 ? d / (d + s) : 1.0;
}

// Evaluate the Phong lobe (n + 2) / (2 pi) cos^n(alpha) and its sampling
// pdf for unit r (the mirror direction) and wi. cos^n is exp(n log(1 - y))
// with y = 1 - cos(alpha) to full precision: pow(dot(r, wi), n) loses it
// near the peak (an ulp of cos is 2e-4 of a lobe of n = 3000)
vec2 phong_lobe(vec3 r, vec3 wi, float n) {
    if (dot(r, wi) <= 0.0) {
        return vec2(0.0);
    }
    float c = exp(n * log_one_minus(min(one_minus_cos_between(r, wi), 1.0)));
    return vec2((n + 2.0) * (0.5 * INV_PI) * c, (n + 1.0) * (0.5 * INV_PI) * c);
}

// Give the solid-angle pdf of the glossy cone sampling at cos(alpha) and
// sin(alpha) from the mirror direction: the disc of radius r_disc at unit
// distance along it, seen from the hit, 1 / (pi r_disc^2 cos^3 alpha)
float glossy_pdf(float cos_a, float sin_a, float r_disc) {
    if (r_disc <= 0.0 || cos_a <= 0.0 || sin_a > r_disc * cos_a) {
        return 0.0;
    }
    return INV_PI / (r_disc * r_disc * cos_a * cos_a * cos_a);
}

// Read one weight of a principled material (MAT_FLAG_WEIGHT_TEXTURES):
// its constant, or its texture at the surface point (Mitsuba's eval_1:
// the texture holds its luminance in every channel)
float principled_weight(uint word, Surface s) {
    return (word & WEIGHT_TEXTURE) != 0u ? surface_texture(word & ~WEIGHT_TEXTURE, s).r
        : uintBitsToFloat(word);
}

// Give whether a principled material reads some weights from textures
bool principled_textured(Material m) {
    return HAS_TEXTURES && material_present(MAT_PRINCIPLED) && m.info.x == MAT_PRINCIPLED
        && (m.info.z & MAT_FLAG_WEIGHT_TEXTURES) != 0u;
}

// Read a rough conductor's or dielectric's roughness at a surface point
// where textures give it (Mitsuba's eval_1: each texture holds its
// luminance in every channel), at least MIN_MICROFACET_ALPHA as Mitsuba's
// distribution keeps it; one texture for both directions is read once.
// Give a principled material with textured weights the alphas, metallic,
// specular tint, sheen, sheen tint, clearcoat and clearcoat alpha at the
// point. Every other material is returned unchanged
Material surface_material(Material m, Surface s) {
    bool rough = (material_present(MAT_ROUGHCONDUCTOR) && m.info.x == MAT_ROUGHCONDUCTOR)
        || (material_present(MAT_ROUGHDIELECTRIC) && m.info.x == MAT_ROUGHDIELECTRIC);
    if (principled_textured(m)) {
        // Map roughness and anisotropy to the GGX alphas (Mitsuba's calc_dist_params)
        uvec4 w0 = texelFetch(material_texels, int(m.info.w) + 1);
        uvec4 w1 = texelFetch(material_texels, int(m.info.w) + 2);
        float roughness = principled_weight(w0.x, s);
        float r2 = roughness * roughness;
        float aspect = sqrt(1.0 - 0.9 * principled_weight(w0.y, s));
        m.specular = vec4(max(r2 / aspect, 0.001), max(r2 * aspect, 0.001),
                          principled_weight(w0.z, s), principled_weight(w0.w, s));
        m.params = vec4(principled_weight(w1.x, s), principled_weight(w1.y, s),
                        principled_weight(w1.z, s), 0.1 + (0.001 - 0.1) * principled_weight(w1.w, s));
    }
    if (HAS_TEXTURES && rough) {
        if (m.info.y != NO_TEXTURE) {
            m.color.w = max(surface_texture(m.info.y, s).r, MIN_MICROFACET_ALPHA);
        }
        if (m.info.w != NO_TEXTURE) {
            m.specular.w = m.info.w == m.info.y
                ? m.color.w : max(surface_texture(m.info.w, s).r, MIN_MICROFACET_ALPHA);
        }
    }
    return m;
}

// The microfacet distribution of a rough conductor
Microfacet rough_conductor_distribution(Material m) {
    return Microfacet(uint(m.params.w), m.color.w, m.specular.w);
}

// The shading frame of a rough conductor: the tangent is dp/du made
// orthogonal to ns (Gram-Schmidt, as Mitsuba's shading frame), the
// bitangent ns x tangent
void rough_conductor_frame(Surface s, out vec3 t, out vec3 b) {
    vec3 d = s.dpdu - dot(s.ns, s.dpdu) * s.ns;
    float len2 = dot(d, d);
    if (len2 > 0.0) {
        t = d * inversesqrt(len2);
        b = cross(s.ns, t);
    } else {
        orthonormal_basis(s.ns, t, b);
    }
}

// Evaluate f * cos and the pdf of visible-normal sampling of a rough
// conductor for lo and li in its local frame (lo.z > 0 and li.z > 0)
vec3 rough_conductor_eval(Material m, vec3 lo, vec3 li, out float pdf) {
    pdf = 0.0;
    vec3 h = normalize(lo + li);
    Microfacet d = rough_conductor_distribution(m);
    float dens = microfacet_d(d, h);
    float g1o = microfacet_g1(d, lo, h);
    float g1i = microfacet_g1(d, li, h);
    if (dens == 0.0 || g1o == 0.0 || g1i == 0.0) {
        return vec3(0.0);
    }
    float common_term = dens * g1o / (4.0 * lo.z);
    pdf = common_term;
    vec3 f = fresnel_conductor(dot(lo, h), m.specular.rgb, m.params.rgb);
    return m.color.rgb * f * (common_term * g1i);
}

// Fresnel reflectance of a smooth dielectric for unpolarised light;
// eta = eta_t / eta_i, cos_i >= 0
float fresnel_dielectric(float cos_i, float eta, out float cos_t) {
    float sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) {
        cos_t = 0.0;
        return 1.0;
    }
    cos_t = sqrt(max(0.0, 1.0 - sin2_t));
    float r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_parl * r_parl + r_perp * r_perp);
}

// The index ratio eta_t / eta_i of a rough dielectric for light leaving
// by wo: the inside over the outside seen from the front (geometric) side
float rough_dielectric_eta(Material m, Surface s) {
    return s.front ? m.params.x : 1.0 / m.params.x;
}

// Evaluate f * |cos| and the pdf of sampling a rough dielectric (Walter et
// al. 2007, as Mitsuba's roughdielectric) for lo and li in its local frame,
// lo.z > 0 on the side of wo and eta = eta_t / eta_i across the surface:
// reflection through the half vector lo + li when li.z > 0, refraction
// through the generalised half vector lo + eta li when li.z < 0, the
// Fresnel term choosing between them; refracted radiance is scaled by
// 1 / eta^2 (so eta^2 of the Jacobian cancels in f)
vec3 rough_dielectric_eval(Material m, vec3 lo, vec3 li, float eta, out float pdf) {
    pdf = 0.0;
    if (lo.z <= 0.0 || li.z == 0.0) {
        return vec3(0.0);
    }
    bool reflect = li.z > 0.0;
    vec3 h = reflect ? lo + li : lo + eta * li;
    float len2 = dot(h, h);
    if (!(len2 > 0.0)) {
        return vec3(0.0);
    }
    // Turn the half vector to the side of the macro normal
    h *= (h.z < 0.0 ? -1.0 : 1.0) * inversesqrt(len2);
    float ho = dot(lo, h);
    float hi = dot(li, h);
    // Require both directions to see the microfacet from their own side
    if (ho <= 0.0 || hi * li.z <= 0.0) {
        return vec3(0.0);
    }
    Microfacet d = rough_conductor_distribution(m);
    float dens = microfacet_d(d, h);
    float g1o = microfacet_g1(d, lo, h);
    float g1i = microfacet_g1(d, li, h);
    if (dens == 0.0 || g1o == 0.0 || g1i == 0.0) {
        return vec3(0.0);
    }
    float cos_t;
    float f = fresnel_dielectric(ho, eta, cos_t);
    // Take the density of the visible normal h, then of li through the half-vector Jacobian
    float visible = dens * g1o * ho / lo.z;
    if (reflect) {
        pdf = visible * f / (4.0 * hi);
        return m.specular.rgb * (f * dens * g1o * g1i / (4.0 * lo.z));
    }
    float denom = ho + eta * hi;
    float denom2 = denom * denom;
    if (!(denom2 > 0.0)) {
        return vec3(0.0);
    }
    pdf = visible * (1.0 - f) * eta * eta * abs(hi) / denom2;
    return m.color.rgb * ((1.0 - f) * dens * g1o * g1i * ho * abs(hi) / (lo.z * denom2));
}

// Probability that a smooth plastic samples its coating's mirror
// reflection for light leaving at cos_o (Mitsuba's choice: the Fresnel
// reflectance against the transmittance, steered by the layers' mean colours)
float plastic_specular_probability(Material m, float cos_o) {
    float cos_t;
    float f = fresnel_dielectric(cos_o, m.color.w, cos_t);
    float ps = f * m.specular.w;
    float pd = (1.0 - f) * (1.0 - m.specular.w);
    return ps + pd > 0.0 ? ps / (ps + pd) : 0.0;
}

// Evaluate f * cos and the pdf of the diffuse base of a smooth plastic,
// light leaving at cos_o and arriving at cos_i (both > 0): refracted in and
// out through the coating (Fresnel transmittance both ways, radiance
// scaled by 1 / eta^2), the internal reflections summed by the diffuse
// Fresnel reflectance Fdr inside (params.x), linearly or not (params.y)
vec3 plastic_eval(Material m, Surface s, float cos_o, float cos_i, out float pdf) {
    float eta = m.color.w;
    float cos_t;
    float f_o = fresnel_dielectric(cos_o, eta, cos_t);
    float f_i = fresnel_dielectric(cos_i, eta, cos_t);
    vec3 kd = material_albedo(m, s);
    vec3 diffuse = kd / (1.0 - (m.params.y > 0.0 ? kd * m.params.x : vec3(m.params.x)));
    pdf = (1.0 - plastic_specular_probability(m, cos_o)) * cos_i * INV_PI;
    return diffuse * (cos_i * INV_PI * (1.0 - f_o) * (1.0 - f_i) / (eta * eta));
}

// Read entry k of the coating transmittance table at material texel `base`
float rough_plastic_entry(uint base, uint k) {
    return uintBitsToFloat(texelFetch(material_texels, int(base + k / 4u))[k & 3u]);
}

// Interpolate a rough plastic's coating transmittance at cosine c in
// [0, 1] linearly in its table (info.w), as Mitsuba's lerp_gather does
float rough_plastic_transmittance(Material m, float c) {
    float x = c * float(ROUGH_TRANSMITTANCE_RES - 1u);
    uint k = min(uint(x), ROUGH_TRANSMITTANCE_RES - 2u);
    float v0 = rough_plastic_entry(m.info.w, k);
    float v1 = rough_plastic_entry(m.info.w, k + 1u);
    return mix(v0, v1, x - float(k));
}

// The coating's microfacet distribution of a rough plastic (isotropic)
Microfacet rough_plastic_distribution(Material m) {
    return Microfacet(uint(m.params.w), m.params.z, m.params.z);
}

// Probability that a rough plastic samples its coating's microfacet
// reflection for light leaving at cos_o (Mitsuba's choice: the coating's
// reflectance 1 - T against its transmittance T, steered by the layers'
// mean colours, specular.w)
float rough_plastic_specular_probability(Material m, float cos_o) {
    float t = rough_plastic_transmittance(m, cos_o);
    float ps = (1.0 - t) * m.specular.w;
    float pd = t * (1.0 - m.specular.w);
    return ps + pd > 0.0 ? ps / (ps + pd) : 0.0;
}

// Evaluate f * cos and the pdf of a rough plastic (Mitsuba's roughplastic)
// for light leaving by wo and arriving from wi, both above the shading
// normal (cos_o, cos_i > 0): the coating's microfacet reflection (Fresnel
// of the index ratio color.w, Smith's masking both ways) plus the diffuse
// base refracted in and out, weighed by the coating's rough transmittance
// both ways and 1 / eta^2, the internal reflections summed by the
// coating's internal reflectance (params.x), linearly or not (params.y);
// the pdf mixes visible-normal and cosine sampling by the lobe choice
vec3 rough_plastic_eval(Material m, Surface s, vec3 wo, vec3 wi, float cos_o, float cos_i, out float pdf) {
    float eta = m.color.w;
    vec3 h = normalize(wo + wi);
    Microfacet d = rough_plastic_distribution(m);
    // The distribution is isotropic: any tangent frame will do
    vec3 t, b;
    orthonormal_basis(s.ns, t, b);
    vec3 lh = vec3(dot(h, t), dot(h, b), dot(h, s.ns));
    vec3 lo = vec3(dot(wo, t), dot(wo, b), cos_o);
    vec3 li = vec3(dot(wi, t), dot(wi, b), cos_i);
    float dens = microfacet_d(d, lh);
    float g1o = microfacet_g1(d, lo, lh);
    float g1i = microfacet_g1(d, li, lh);
    float cos_t;
    float f = fresnel_dielectric(dot(wo, h), eta, cos_t);
    vec3 specular = m.specular.rgb * (f * dens * g1o * g1i / (4.0 * cos_o));
    vec3 kd = material_albedo(m, s);
    vec3 diffuse = kd / (1.0 - (m.params.y > 0.0 ? kd * m.params.x : vec3(m.params.x)));
    float t_o = rough_plastic_transmittance(m, cos_o);
    float t_i = rough_plastic_transmittance(m, cos_i);
    float ps = rough_plastic_specular_probability(m, cos_o);
    pdf = ps * dens * g1o / (4.0 * cos_o) + (1.0 - ps) * cos_i * INV_PI;
    return specular + diffuse * (INV_PI * cos_i * t_o * t_i / (eta * eta));
}

// Give a principled material's further parameters at a surface point: x
// roughness, y flatness, z the diffuse lobe's sampling probability, w the
// clearcoat's. Constant weights give a texel of them; textured ones (read
// by surface_material into m) the probabilities as Mitsuba computes them
vec4 principled_params(Material m, Surface s) {
    vec4 q = uintBitsToFloat(texelFetch(material_texels, int(m.info.w)));
    if (principled_textured(m)) {
        uint roughness = texelFetch(material_texels, int(m.info.w) + 1).x;
        uvec4 w2 = texelFetch(material_texels, int(m.info.w) + 3);
        vec3 rates = uintBitsToFloat(w2.yzw);
        float pc = 0.25 * m.params.z * rates.y;
        float pd = (1.0 - m.specular.z) * rates.z;
        float rcp = 1.0 / (rates.x + pc + pd);
        q = vec4(principled_weight(roughness, s), principled_weight(w2.x, s), pd * rcp, pc * rcp);
    }
    return q;
}

// Give Mitsuba's luminance of a linear colour
float mitsuba_luminance(vec3 c) {
    return dot(c, vec3(LUMINANCE_R, LUMINANCE_G, LUMINANCE_B));
}

// Give Schlick's weight (1 - c)^5, c clamped to [0, 1]
float schlick_weight(float c) {
    float x = clamp(1.0 - c, 0.0, 1.0);
    float x2 = x * x;
    return x2 * x2 * x;
}

// Give Schlick's Fresnel term from the reflectance r0 at normal incidence
// for light arriving from outside at cos_i >= 0 (Mitsuba's calc_schlick):
// the angle inside the denser side sets the weight
vec3 principled_schlick(vec3 r0, float cos_i, float eta) {
    float c = cos_i;
    if (!(eta > 1.0)) {
        c = sqrt(max(1.0 - (1.0 - cos_i * cos_i) / (eta * eta), 0.0));
    }
    return mix(vec3(schlick_weight(c)), vec3(1.0), r0);
}

// Evaluate the GTR1 density of the clearcoat's normals at m (alpha2 its
// squared roughness), as Mitsuba's GTR1Isotropic
float gtr1_d(float alpha2, vec3 m) {
    float r = (alpha2 - 1.0) / (PI * log(alpha2) * (1.0 + (alpha2 - 1.0) * m.z * m.z));
    return r * m.z > 1e-20 ? r : 0.0;
}

// Sample a clearcoat normal with density gtr1_d(alpha2, m) cos(m)
vec3 gtr1_sample(float alpha2, vec2 u) {
    float phi = 2.0 * PI * u.x;
    float cos2 = (1.0 - pow(alpha2, 1.0 - u.y)) / (1.0 - alpha2);
    float sin_t = sqrt(max(0.0, 1.0 - cos2));
    return vec3(cos(phi) * sin_t, sin(phi) * sin_t, sqrt(max(0.0, cos2)));
}

// Evaluate f * cos and the pdf of Mitsuba's principled BSDF (the Disney
// BRDF, `principled.cpp`, without its transmission) for lo (towards the
// viewer) and li (towards the light) in the shading frame, both above it:
// the GGX specular lobe with Fresnel mixed from the dielectric's, the
// metal's and the tinted one's; the GTR1 clearcoat, as Mitsuba writes it
// (0.25 clearcoat F D G cos, with no 1 / (4 cos cos)); the diffuse lobe with
// retro-reflection, lerped towards the fake subsurface by flatness; sheen.
// The pdf mixes cosine, visible-normal and GTR1 sampling by the lobes'
// probabilities
vec3 principled_eval(Material m, Surface s, vec3 lo, vec3 li, out float pdf) {
    vec4 q = principled_params(m, s);
    vec3 base = material_albedo(m, s);
    float eta = m.color.w;
    float metallic = m.specular.z;
    float spec_tint = m.specular.w;
    float brdf = 1.0 - metallic;
    float lum = mitsuba_luminance(base);
    vec3 tint = lum > 0.0 ? base / lum : vec3(1.0);
    vec3 h = normalize(lo + li);
    float ho = dot(lo, h);
    float hi = dot(li, h);
    bool facing = ho > 0.0 && hi > 0.0;
    vec3 value = vec3(0.0);
    float coat_pdf = 0.0;

    // Add the specular lobe
    Microfacet d = Microfacet(MICROFACET_GGX, m.specular.x, m.specular.y);
    float dens = microfacet_d(d, h);
    float g1o = microfacet_g1(d, lo, h);
    float cos_t;
    float f_dielectric = fresnel_dielectric(ho, eta, cos_t);
    if (facing && f_dielectric > 0.0) {
        float r0 = (eta - 1.0) / (eta + 1.0);
        vec3 f = brdf * (1.0 - spec_tint) * f_dielectric + metallic * principled_schlick(base, ho, eta)
            + brdf * spec_tint * principled_schlick(tint * (r0 * r0), ho, eta);
        value += f * (dens * g1o * microfacet_g1(d, li, h) / (4.0 * lo.z));
    }
    float spec_pdf = dens * g1o * ho / lo.z;

    // Add the clearcoat
    float clearcoat = m.params.z;
    if (clearcoat > 0.0 && facing) {
        float alpha2 = m.params.w * m.params.w;
        float dcc = gtr1_d(alpha2, h);
        Microfacet cc = Microfacet(MICROFACET_GGX, 0.25, 0.25);
        float gcc = microfacet_g1(cc, lo, h) * microfacet_g1(cc, li, h);
        value += vec3(clearcoat * 0.25 * principled_schlick(vec3(0.04), ho, eta).x * dcc * gcc * li.z);
        coat_pdf = h.z * dcc;
    }

    // Add the diffuse lobe: retro-reflection, lerped to the fake subsurface
    float fo = schlick_weight(li.z);
    float fi = schlick_weight(lo.z);
    if (brdf > 0.0) {
        float f_diff = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo);
        float rr = 2.0 * q.x * hi * hi;
        float f_retro = rr * (fo + fi + fo * fi * (rr - 1.0));
        float fss = mix(1.0, 0.5 * rr, fo) * mix(1.0, 0.5 * rr, fi);
        float f_ss = 1.25 * (fss * (1.0 / (li.z + lo.z) - 0.5) + 0.5);
        value += brdf * li.z * INV_PI * mix(f_diff + f_retro, f_ss, q.y) * base;
    }

    // Add the sheen
    float sheen = m.params.x;
    if (sheen > 0.0 && brdf > 0.0) {
        vec3 c_sheen = mix(vec3(1.0), tint, m.params.y);
        value += sheen * brdf * schlick_weight(abs(hi)) * li.z * c_sheen;
    }

    // Mix the lobes' sampling densities (the half vector's Jacobian 1 / (4 h.li))
    pdf = q.z * li.z * INV_PI;
    if (facing) {
        pdf += ((1.0 - q.z - q.w) * spec_pdf + q.w * coat_pdf) / (4.0 * hi);
    }
    return value;
}

// Evaluate f * cos(ns, wi) and the pdf of sampling wi. Glossy reflection is
// defined by its sampling (weight = reflectance): its f * cos is the
// reflectance times that pdf, so that weight = f * cos / pdf as for the others
vec3 component_eval(Material m, Surface s, vec3 wo, vec3 wi, out float pdf) {
    pdf = 0.0;
    if (material_present(MAT_ROUGHDIELECTRIC) && m.info.x == MAT_ROUGHDIELECTRIC) {
        // Reflect above both normals, refract below both: no light leaks
        // through the geometric surface, nor where the normals disagree
        float side_s = dot(wi, s.ns);
        float cos_o = dot(wo, s.ns);
        if (dot(wi, s.ng) * side_s <= 0.0 || cos_o <= 0.0) {
            return vec3(0.0);
        }
        vec3 t, b;
        rough_conductor_frame(s, t, b);
        vec3 lo = vec3(dot(wo, t), dot(wo, b), cos_o);
        vec3 li = vec3(dot(wi, t), dot(wi, b), side_s);
        return rough_dielectric_eval(m, lo, li, rough_dielectric_eta(m, s), pdf);
    }
    // Reject directions below the geometric surface: no light leaks
    if (dot(wi, s.ng) <= 0.0) {
        return vec3(0.0);
    }
    float cos_i = dot(wi, s.ns);
    if (cos_i <= 0.0) {
        return vec3(0.0);
    }
    if (material_present(MAT_LAMBERT) && m.info.x == MAT_LAMBERT) {
        pdf = cos_i * INV_PI;
        return material_albedo(m, s) * (cos_i * INV_PI);
    }
    if (material_present(MAT_PHONG) && m.info.x == MAT_PHONG) {
        vec3 kd = material_albedo(m, s);
        vec3 ks = m.specular.rgb;
        float pd = phong_diffuse_probability(kd, ks);
        vec2 lobe = phong_lobe(mirror_direction(wo, s.ns), wi, m.specular.w);
        pdf = pd * cos_i * INV_PI + (1.0 - pd) * lobe.y;
        return (kd * INV_PI + ks * lobe.x) * cos_i;
    }
    if (material_present(MAT_GLOSSY) && m.info.x == MAT_GLOSSY) {
        vec3 r = mirror_direction(wo, s.ns);
        pdf = glossy_pdf(dot(r, wi), length(cross(r, wi)), m.color.w);
        return m.color.rgb * pdf;
    }
    bool principled = material_present(MAT_PRINCIPLED) && m.info.x == MAT_PRINCIPLED;
    if ((material_present(MAT_ROUGHCONDUCTOR) && m.info.x == MAT_ROUGHCONDUCTOR) || principled) {
        // Evaluate in the shading frame turned by dp/du (anisotropic lobes)
        vec3 t, b;
        rough_conductor_frame(s, t, b);
        float cos_o = dot(wo, s.ns);
        if (cos_o <= 0.0) {
            return vec3(0.0);
        }
        vec3 lo = vec3(dot(wo, t), dot(wo, b), cos_o);
        vec3 li = vec3(dot(wi, t), dot(wi, b), cos_i);
        if (principled) {
            return principled_eval(m, s, lo, li, pdf);
        }
        return rough_conductor_eval(m, lo, li, pdf);
    }
    if (material_present(MAT_PLASTIC) && m.info.x == MAT_PLASTIC) {
        // Evaluate the diffuse base only: the coating's mirror reflection is a delta lobe
        float cos_o = dot(wo, s.ns);
        if (cos_o <= 0.0) {
            return vec3(0.0);
        }
        return plastic_eval(m, s, min(cos_o, 1.0), min(cos_i, 1.0), pdf);
    }
    if (material_present(MAT_ROUGHPLASTIC) && m.info.x == MAT_ROUGHPLASTIC) {
        float cos_o = dot(wo, s.ns);
        if (cos_o <= 0.0) {
            return vec3(0.0);
        }
        return rough_plastic_eval(m, s, wo, wi, min(cos_o, 1.0), min(cos_i, 1.0), pdf);
    }
    return vec3(0.0);
}

// Reflect lo about the normal h, both in the frame (t, b, n), and give the
// reflection in world space; false when it falls below the surface
bool reflect_in_frame(vec3 lo, vec3 h, vec3 t, vec3 b, vec3 n, out vec3 wi) {
    vec3 li = 2.0 * dot(lo, h) * h - lo;
    wi = normalize(li.x * t + li.y * b + li.z * n);
    return li.z > 0.0;
}

// Sample a direction from a material that is not a blend; false ends the
// path. A material whose direction is weighed by its own evaluation sets
// bs.weigh and leaves the weighing to bsdf_sample, which does it once for
// every material (one copy of the evaluation code in the kernel)
bool component_sample(Material m, Surface s, vec3 wo, vec3 u, out BsdfSample bs) {
    bs.wi = vec3(0.0);
    bs.weight = vec3(0.0);
    bs.pdf = 0.0;
    bs.delta = false;
    bs.weigh = false;
    uint type = m.info.x;

    if (material_present(MAT_LAMBERT) && type == MAT_LAMBERT) {
        // Sample the cosine lobe around the shading normal
        bs.wi = sample_cosine_hemisphere(u.xy, s.ns);
        float cos_i = dot(bs.wi, s.ns);
        if (dot(bs.wi, s.ng) <= 0.0 || cos_i <= 0.0) {
            return false;
        }
        bs.pdf = cos_i * INV_PI;
        bs.weight = material_albedo(m, s);
        return true;
    }

    if (material_present(MAT_PHONG) && type == MAT_PHONG) {
        // Pick the diffuse or the Phong lobe, then weigh by the mixture pdf
        vec3 kd = material_albedo(m, s);
        float pd = phong_diffuse_probability(kd, m.specular.rgb);
        vec3 r = mirror_direction(wo, s.ns);
        if (u.z < pd) {
            bs.wi = sample_cosine_hemisphere(u.xy, s.ns);
        } else {
            // cos(alpha) = u^(1 / (n + 1)); y = 1 - cos(alpha) to full
            // precision, so that the lobe of a huge n is not quantised to the
            // ulps of cos near 1
            float y = one_minus_exp(log(max(u.x, 1e-30)) / (m.specular.w + 1.0));
            float cos_a = 1.0 - y;
            float sin_a = sqrt(y * (2.0 - y));
            float phi = 2.0 * PI * u.y;
            bs.wi = normalize(to_world(vec3(cos(phi) * sin_a, sin(phi) * sin_a, cos_a), r));
        }
        bs.weigh = true;
        return true;
    }

    if (material_present(MAT_MIRROR) && type == MAT_MIRROR) {
        // Reflect about the shading normal
        bs.wi = mirror_direction(wo, s.ns);
        bs.weight = m.color.rgb;
        bs.delta = true;
        return dot(bs.wi, s.ng) > 0.0;
    }

    if (material_present(MAT_GLOSSY) && type == MAT_GLOSSY) {
        // Offset the mirror direction by a point of the disc of radius sin(cone)
        vec3 r = mirror_direction(wo, s.ns);
        vec2 d = m.color.w * sample_disk_concentric(u.xy);
        bs.wi = normalize(to_world(vec3(d, 1.0), r));
        bs.weight = m.color.rgb;
        bs.delta = true;
        // A direction below the surface carries nothing
        return dot(bs.wi, s.ng) > 0.0 && dot(bs.wi, s.ns) > 0.0;
    }

    if (material_present(MAT_CONDUCTOR) && type == MAT_CONDUCTOR) {
        // Reflect about the shading normal, weighted by the conductor's Fresnel term
        bs.wi = mirror_direction(wo, s.ns);
        bs.weight = m.color.rgb * fresnel_conductor(min(dot(wo, s.ns), 1.0), m.specular.rgb, m.params.rgb);
        bs.delta = true;
        return dot(bs.wi, s.ng) > 0.0;
    }

    if (material_present(MAT_ROUGHCONDUCTOR) && type == MAT_ROUGHCONDUCTOR) {
        // Reflect about a visible microfacet normal; weigh by f * cos / pdf
        vec3 t, b;
        rough_conductor_frame(s, t, b);
        float cos_o = dot(wo, s.ns);
        if (cos_o <= 0.0) {
            return false;
        }
        vec3 lo = vec3(dot(wo, t), dot(wo, b), cos_o);
        vec3 h = microfacet_sample_visible(rough_conductor_distribution(m), lo, u.xy);
        bs.weigh = true;
        return reflect_in_frame(lo, h, t, b, s.ns, bs.wi);
    }

    if (material_present(MAT_PLASTIC) && type == MAT_PLASTIC) {
        // Choose the coating's mirror reflection or the diffuse base
        float cos_o = min(dot(wo, s.ns), 1.0);
        if (cos_o <= 0.0) {
            return false;
        }
        float ps = plastic_specular_probability(m, cos_o);
        if (u.z < ps) {
            float cos_t;
            bs.wi = mirror_direction(wo, s.ns);
            bs.weight = m.specular.rgb * (fresnel_dielectric(cos_o, m.color.w, cos_t) / ps);
            bs.delta = true;
            return dot(bs.wi, s.ng) > 0.0;
        }
        bs.wi = sample_cosine_hemisphere(u.xy, s.ns);
        bs.weigh = true;
        return true;
    }

    if (material_present(MAT_ROUGHPLASTIC) && type == MAT_ROUGHPLASTIC) {
        // Choose the coating's microfacet reflection (about a visible
        // normal) or the diffuse base (cosine-weighted); weigh by f * cos
        // over the mixture pdf
        float cos_o = dot(wo, s.ns);
        if (cos_o <= 0.0) {
            return false;
        }
        if (u.z < rough_plastic_specular_probability(m, min(cos_o, 1.0))) {
            vec3 t, b;
            orthonormal_basis(s.ns, t, b);
            vec3 lo = vec3(dot(wo, t), dot(wo, b), cos_o);
            vec3 h = microfacet_sample_visible(rough_plastic_distribution(m), lo, u.xy);
            if (!reflect_in_frame(lo, h, t, b, s.ns, bs.wi)) {
                return false;
            }
        } else {
            bs.wi = sample_cosine_hemisphere(u.xy, s.ns);
        }
        bs.weigh = true;
        return true;
    }

    if (material_present(MAT_PRINCIPLED) && type == MAT_PRINCIPLED) {
        // Choose the diffuse lobe (cosine-weighted), the clearcoat (about a
        // GTR1 normal) or the specular lobe (about a visible GGX normal) by
        // their probabilities; weigh by f * cos over the mixture pdf
        float cos_o = dot(wo, s.ns);
        if (cos_o <= 0.0) {
            return false;
        }
        vec4 q = principled_params(m, s);
        if (u.z < q.z) {
            bs.wi = sample_cosine_hemisphere(u.xy, s.ns);
        } else {
            vec3 t, b;
            rough_conductor_frame(s, t, b);
            vec3 lo = vec3(dot(wo, t), dot(wo, b), cos_o);
            vec3 h = u.z < q.z + q.w ? gtr1_sample(m.params.w * m.params.w, u.xy)
                : microfacet_sample_visible(Microfacet(MICROFACET_GGX, m.specular.x, m.specular.y), lo, u.xy);
            // GTR1 normals are not sampled visible: one may face away from wo
            if (dot(lo, h) <= 0.0 || !reflect_in_frame(lo, h, t, b, s.ns, bs.wi)) {
                return false;
            }
        }
        bs.weigh = true;
        return true;
    }

    if (material_present(MAT_ROUGHDIELECTRIC) && type == MAT_ROUGHDIELECTRIC) {
        // Reflect about or refract through a visible microfacet normal,
        // chosen by its Fresnel term; weigh by f * |cos| / pdf
        vec3 t, b;
        rough_conductor_frame(s, t, b);
        float cos_o = dot(wo, s.ns);
        if (cos_o <= 0.0) {
            return false;
        }
        vec3 lo = vec3(dot(wo, t), dot(wo, b), cos_o);
        vec3 h = microfacet_sample_visible(rough_conductor_distribution(m), lo, u.xy);
        float eta = rough_dielectric_eta(m, s);
        float ho = dot(lo, h);
        float cos_t;
        float f = fresnel_dielectric(ho, eta, cos_t);
        bool reflected = u.z < f;
        vec3 li = reflected ? 2.0 * ho * h - lo : -lo / eta + (ho / eta - cos_t) * h;
        // Drop a reflection below the surface or a refraction above it: it carries nothing
        if ((li.z > 0.0) != reflected) {
            return false;
        }
        bs.wi = normalize(li.x * t + li.y * b + li.z * s.ns);
        bs.weigh = true;
        return true;
    }

    if (material_present(MAT_THINDIELECTRIC) && type == MAT_THINDIELECTRIC) {
        // A thin slab: the Fresnel reflectance R at the angle of incidence
        // (the same from either side), its inter-reflections summed,
        // R' = R + (1 - R)^2 R / (1 - R^2) = 2R / (1 + R), chooses a mirror
        // reflection; the rest passes straight through, undeflected. Each
        // choice is sampled with its own probability: the weight is the
        // factor on the lobe
        float cos_o = min(abs(dot(wo, s.ns)), 1.0);
        float cos_t;
        float r = fresnel_dielectric(cos_o, m.color.w, cos_t);
        r *= 2.0 / (1.0 + r);
        bs.delta = true;
        if (u.z <= r) {
            bs.wi = mirror_direction(wo, s.ns);
            bs.weight = m.specular.rgb;
            return dot(bs.wi, s.ng) > 0.0;
        }
        bs.wi = -wo;
        bs.weight = m.color.rgb;
        return true;
    }

    if (material_present(MAT_DIELECTRIC) && type == MAT_DIELECTRIC) {
        // Choose reflection or refraction by the exact Fresnel term
        float eta = s.front ? m.color.w : 1.0 / m.color.w;
        float cos_o = min(dot(wo, s.ns), 1.0);
        float cos_t;
        float f = fresnel_dielectric(cos_o, eta, cos_t);
        bs.delta = true;
        if (u.z < f) {
            bs.wi = mirror_direction(wo, s.ns);
            bs.weight = vec3(1.0);
            return dot(bs.wi, s.ng) > 0.0;
        }
        // Refract; radiance is scaled by 1 / eta^2 on the way in
        bs.wi = normalize(-wo / eta + (cos_o / eta - cos_t) * s.ns);
        bs.weight = m.color.rgb / (eta * eta);
        return dot(bs.wi, s.ng) < 0.0;
    }
    return false;
}

// Tell whether material m blends two components (Mitsuba's blendbsdf)
bool material_is_blend(Material m) {
    return material_present(MAT_BLEND) && m.info.x == MAT_BLEND;
}

// Find the weight of a blend's second component at a surface point: a
// constant, or a texture holding its luminance in every channel; clamped
// to [0, 1] as Mitsuba clamps it
float blend_weight(Material m, Surface s) {
    float w = m.color.x;
    if (HAS_TEXTURES && m.info.y != NO_TEXTURE) {
        w = surface_texture(m.info.y, s).r;
    }
    return clamp(w, 0.0, 1.0);
}

// Evaluate f * cos at wi and the pdf of sampling wi: for a blend, the
// mixture of its components, (1 - w) times the first plus w times the
// second. One loop over the parts keeps one copy of the materials' code
vec3 bsdf_eval(Material m, Surface s, vec3 wo, vec3 wi, out float pdf) {
    bool blend = material_is_blend(m);
    float w = blend ? blend_weight(m, s) : 0.0;
    uint parts = blend ? 2u : 1u;
    vec3 f = vec3(0.0);
    pdf = 0.0;
    for (uint k = 0u; k < parts; ++k) {
        Material c = blend ? surface_material(material(m.info.w + k), s) : m;
        float share = blend ? (k == 0u ? 1.0 - w : w) : 1.0;
        float pdf_k;
        vec3 f_k = component_eval(c, s, wo, wi, pdf_k);
        f += share * f_k;
        pdf += share * pdf_k;
    }
    return f;
}

// Give the probability with which material c samples the delta lobe it
// just sampled, seen from wo: a smooth plastic's chance of its coating's
// reflection; 1 for a mirror or smooth conductor, whose only lobe it is
float delta_lobe_chance(Material c, Surface s, vec3 wo) {
    if (material_present(MAT_PLASTIC) && c.info.x == MAT_PLASTIC) {
        return plastic_specular_probability(c, min(dot(wo, s.ns), 1.0));
    }
    return 1.0;
}

// Sample a direction from the material; false ends the path. A blend picks
// its second component with probability w by the lobe number (the rest of
// it left for the component, as Mitsuba rescales it), then weighs the
// direction by the mixture's f * cos over the mixture's pdf. Where the
// component samples a delta lobe, Mitsuba's blend mixes the lobe's
// probability with the other component's density there, and its weight
// with the other's f * cos: lancer does the same, so that the images agree
bool bsdf_sample(Material m, Surface s, vec3 wo, vec3 u, out BsdfSample bs) {
    bool blend = material_is_blend(m);
    Material c = m;
    float share = 1.0;
    uint other = 0u;
    if (blend) {
        float w = blend_weight(m, s);
        bool second = u.z < w;
        u.z = second ? u.z / w : (u.z - w) / (1.0 - w);
        c = surface_material(material(m.info.w + (second ? 1u : 0u)), s);
        other = m.info.w + (second ? 0u : 1u);
        share = second ? w : 1.0 - w;
    }
    if (!component_sample(c, s, wo, u, bs)) {
        return false;
    }
    if (blend && bs.delta) {
        float chance = delta_lobe_chance(c, s, wo);
        float pdf_other;
        vec3 f_other = component_eval(surface_material(material(other), s), s, wo, bs.wi, pdf_other);
        float mixed = share * chance + (1.0 - share) * pdf_other;
        bs.weight = mixed > 0.0 ? (share * chance * bs.weight + (1.0 - share) * f_other) / mixed : vec3(0.0);
        return mixed > 0.0;
    }
    if (blend || bs.weigh) {
        // Weigh by f * cos over the pdf: a blend's, of the mixture
        bs.weigh = false;
        float pdf;
        vec3 f = bsdf_eval(m, s, wo, bs.wi, pdf);
        bs.pdf = pdf;
        bs.weight = pdf > 0.0 ? f / pdf : vec3(0.0);
        return pdf > 0.0;
    }
    return true;
}

#endif
