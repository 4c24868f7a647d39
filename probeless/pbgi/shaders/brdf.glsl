// BRDFs of the point-based GI renderer: the formulas of probeless/pbgi/brdf.py (its module doc), float32.
// n unit normal, wi unit direction towards the light, wo towards the viewer, all away from the surface; values in
// 1/sr, cosine factor not included; zero where n.wi <= 0 or n.wo <= 0. roughness is perceptual (alpha = r^2).
// An include file: no #version, no #include.

#define BRDF_LAMBERT 0
#define BRDF_GGX 1
#define BRDF_DISNEY 2
#ifndef BRDF_PI
#define BRDF_PI 3.14159265358979323846
#endif

const float BRDF_MIN_ALPHA = 1e-3;     // smallest GGX alpha evaluated (MIN_ALPHA in brdf.py)
const float BRDF_DIELECTRIC_F0 = 0.04; // Fresnel reflectance of the non-metal part

float brdf_alpha(float roughness) { return max(roughness * roughness, BRDF_MIN_ALPHA); }

// GGX D(h) [1/sr]; the denominator (n.h)^2 (a^2 - 1) + 1 as |n x h|^2 + a^2 (n.h)^2 (no cancellation).
float ggx_d(float alpha, vec3 n, vec3 h) {
    float a2 = max(alpha, BRDF_MIN_ALPHA);
    a2 *= a2;
    float c = dot(n, h);
    vec3 s = cross(n, h);
    float den = dot(s, s) + a2 * c * c;
    return c > 0.0 ? a2 / (BRDF_PI * den * den) : 0.0;
}

// Separable Smith G1(wi) G1(wo) / (4 cos_i cos_o) of GGX, as 1 / ((c_i + s_i)(c_o + s_o)).
float ggx_visibility(float a2, float ci, float co) {
    return 1.0 / ((ci + sqrt(a2 + (1.0 - a2) * ci * ci)) * (co + sqrt(a2 + (1.0 - a2) * co * co)));
}

vec3 brdf_schlick(vec3 f0, float cos_theta) {
    float m = 1.0 - clamp(cos_theta, 0.0, 1.0);
    float m2 = m * m;
    return f0 + (1.0 - f0) * (m2 * m2 * m);
}

vec3 brdf_ggx(vec3 f0, float roughness, vec3 n, vec3 wi, vec3 wo) {
    float ci = dot(n, wi), co = dot(n, wo);
    if (ci <= 0.0 || co <= 0.0) return vec3(0.0);
    vec3 h = normalize(wi + wo);
    float alpha = brdf_alpha(roughness);
    return ggx_d(alpha, n, h) * ggx_visibility(alpha * alpha, ci, co) * brdf_schlick(f0, dot(wo, h));
}

vec3 brdf_disney(vec3 base, float roughness, float metalness, vec3 n, vec3 wi, vec3 wo) {
    float ci = dot(n, wi), co = dot(n, wo);
    if (ci <= 0.0 || co <= 0.0) return vec3(0.0);
    vec3 h = normalize(wi + wo);
    float cd = dot(wi, h);
    float fd90 = 0.5 + 2.0 * roughness * cd * cd;
    float ml = 1.0 - ci, mv = 1.0 - co;
    float fl = 1.0 + (fd90 - 1.0) * (ml * ml) * (ml * ml) * ml;
    float fv = 1.0 + (fd90 - 1.0) * (mv * mv) * (mv * mv) * mv;
    vec3 diffuse = base * ((1.0 - metalness) / BRDF_PI * fl * fv);
    return diffuse + brdf_ggx(mix(vec3(BRDF_DIELECTRIC_F0), base, metalness), roughness, n, wi, wo);
}

// model: BRDF_LAMBERT (base / pi), BRDF_GGX (f0 = base, metalness unused) or BRDF_DISNEY.
vec3 brdf_eval(int model, vec3 base, float roughness, float metalness, vec3 n, vec3 wi, vec3 wo) {
    if (model == BRDF_GGX) return brdf_ggx(base, roughness, n, wi, wo);
    if (model == BRDF_DISNEY) return brdf_disney(base, roughness, metalness, n, wi, wo);
    if (dot(n, wi) <= 0.0 || dot(n, wo) <= 0.0) return vec3(0.0);
    return base / BRDF_PI;
}

// Half-vector in the local frame (z = normal) with pdf D(h) (n.h), from u in [0, 1)^2 (alpha clamped as in ggx_d).
vec3 ggx_sample_half(vec2 u, float alpha) {
    float a2 = max(alpha, BRDF_MIN_ALPHA);
    a2 *= a2;
    float den = (1.0 - u.x) + a2 * u.x;
    float cos_t = sqrt((1.0 - u.x) / den), sin_t = sqrt(a2 * u.x / den);
    float phi = 2.0 * BRDF_PI * u.y;
    return vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
}

// Solid-angle pdf of wi = reflect(-wo, h) for h from ggx_sample_half: D(h) (n.h) / (4 |wo.h|), over the whole sphere.
float ggx_pdf_reflect(float alpha, vec3 n, vec3 wi, vec3 wo) {
    vec3 h = normalize(wi + wo);
    return ggx_d(alpha, n, h) * max(dot(n, h), 0.0) / (4.0 * abs(dot(wo, h)));
}

// The i-th of n Hammersley points: (i / n, base-2 radical inverse of i).
vec2 hammersley(uint i, uint n) {
    return vec2(float(i) / float(n), float(bitfieldReverse(i)) * 2.3283064365386963e-10);
}

// Orthonormal frame, columns t, b, n (t x b = n), of a unit normal (Duff et al. 2017); frame * local -> world.
mat3 tangent_frame(vec3 n) {
    float sgn = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n.z);
    float b = n.x * n.y * a;
    return mat3(vec3(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x), vec3(b, sgn + n.y * n.y * a, -n.y), n);
}
