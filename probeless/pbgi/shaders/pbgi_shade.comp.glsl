#version 430
// Micro-buffer final rendering (paper 001 §5.3, Eq. 9): one invocation per level-0 pixel of the batch sums
// f(wi, wo) L(wi) cos(theta) d(omega) over its micro-buffer. In the orthographic hemisphere projection a texel of
// area A at height z subtends A / z sr, so cos(theta) d(omega) = A (Nusselt) and no texel is weighted by the
// approximate constant 2 pi / M^2; A = texel_area = pi / (texels inside the disk), so the texels' projected areas
// sum to the disk's exactly (a white furnace stays white). Empty texels read the far field (the cubemap, near_field
// mode and the envmap baseline) or nothing. For a specular lobe with roughness below is_roughness, the specular part
// is estimated instead from is_samples GGX importance samples reading the micro-buffer bilinearly (§6.3's proposed
// fix); the diffuse part is always the texel sum.
layout(local_size_x = 64) in;
#include "brdf.glsl"
#include "pbgi_common.glsl"

struct Material { float br, bg, bb, roughness, metalness; uint model; float pad0, pad1; };  // microbuffer.MAT_DTYPE
layout(std430, binding = 3) readonly buffer Materials { Material mats[]; };
layout(std430, binding = 4) writeonly buffer Radiance { vec4 radiance[]; };

uniform uint n_pixels;
uniform uint pixel_first;      // global index of the batch's first level-0 pixel
uniform vec3 camera_position;  // [m, world]
uniform bool has_far;
uniform samplerCube far_field; // linear radiance, world directions
uniform float is_roughness;    // importance-sampled lookup below this roughness (0: never)
uniform uint is_samples;
uniform float texel_area;     // pi / (texels inside the unit disk)

vec3 texel_radiance(uint base, int x, int y, vec3 dir) {
    uint v = micro[base + uint(y * M + x)];
    if (v == MB_EMPTY) return has_far ? textureLod(far_field, dir, 0.0).rgb : vec3(0.0);
    Node a = nodes[v & ((1u << idx_bits) - 1u)];
    return vec3(a.red, a.green, a.blue);
}

vec3 texel_dir(mat3 f, int x, int y) {
    vec2 q = (vec2(x, y) + 0.5) / float(M) * 2.0 - 1.0;
    return f * vec3(q, sqrt(max(0.0, 1.0 - dot(q, q))));
}

// Bilinear lookup of the micro-buffer along world direction w (texels outside the disk left out).
vec3 lookup(uint base, mat3 f, vec3 w) {
    vec3 l = transpose(f) * w;
    vec2 t = (l.xy + 1.0) * 0.5 * float(M) - 0.5;
    ivec2 t0 = ivec2(floor(t));
    vec2 fr = t - vec2(t0);
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < 2; ++i) {
            ivec2 x = clamp(t0 + ivec2(i, j), ivec2(0), ivec2(M - 1));
            vec2 q = (vec2(x) + 0.5) / float(M) * 2.0 - 1.0;
            if (dot(q, q) >= 1.0) continue;
            float wt = (i == 1 ? fr.x : 1.0 - fr.x) * (j == 1 ? fr.y : 1.0 - fr.y);
            sum += wt * texel_radiance(base, x.x, x.y, texel_dir(f, x.x, x.y));
            wsum += wt;
        }
    }
    return wsum > 0.0 ? sum / wsum : vec3(0.0);
}

void main() {
    uint k = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;
    if (k >= n_pixels) return;
    GPixel g = gpix[pixel_first + k];
    Material m = mats[g.slot];
    vec3 p = vec3(g.px, g.py, g.pz), n = vec3(g.nx, g.ny, g.nz), base_color = vec3(m.br, m.bg, m.bb);
    vec3 wo = normalize(camera_position - p);
    mat3 f = mb_frame(n);
    uint base = (g.slot - slot_base) * uint(M * M);
    bool sampled = m.model != uint(BRDF_LAMBERT) && m.roughness < is_roughness && is_samples > 0u;
    vec3 f0 = m.model == uint(BRDF_GGX) ? base_color : mix(vec3(0.04), base_color, m.metalness);
    float da = texel_area;
    vec3 sum = vec3(0.0);
    for (int y = 0; y < M; ++y) {
        for (int x = 0; x < M; ++x) {
            vec2 q = (vec2(x, y) + 0.5) / float(M) * 2.0 - 1.0;
            if (dot(q, q) >= 1.0) continue;
            vec3 wi = texel_dir(f, x, y);
            vec3 fr = brdf_eval(int(m.model), base_color, m.roughness, m.metalness, n, wi, wo);
            if (sampled) fr -= brdf_eval(BRDF_GGX, f0, m.roughness, 0.0, n, wi, wo);
            if (any(greaterThan(fr, vec3(0.0)))) sum += fr * texel_radiance(base, x, y, wi) * da;
        }
    }
    if (sampled) {
        float alpha = max(m.roughness * m.roughness, 1e-3);
        mat3 tf = tangent_frame(n);
        vec3 spec = vec3(0.0);
        for (uint s = 0u; s < is_samples; ++s) {
            vec3 h = tf * ggx_sample_half(hammersley(s, is_samples), alpha);
            vec3 wi = reflect(-wo, h);
            float cosi = dot(n, wi);
            if (cosi <= 0.0) continue;
            float pdf = ggx_pdf_reflect(alpha, n, wi, wo);
            if (pdf <= 0.0) continue;
            spec += brdf_eval(BRDF_GGX, f0, m.roughness, 0.0, n, wi, wo) * cosi / pdf * lookup(base, f, wi);
        }
        sum += spec / float(is_samples);
    }
    radiance[g.slot] = vec4(sum, 1.0);
}
