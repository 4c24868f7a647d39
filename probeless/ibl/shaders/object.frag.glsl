#version 430
// Image-based shading: kd * diffuse + specular GGX lobe (Schlick f0 -> f90, energy-compensated) + kt * refraction.
// Cubemaps hold linear radiance and are sampled with the world direction (messages/lighting.py); env has its full
// mip chain (trilinear). Roughness is perceptual (GGX alpha = roughness^2): see ibl_specular.glsl.
const float PI = 3.14159265358979;
uniform samplerCube env;        // linear radiance, full mip chain
uniform float env_size;         // face size of env's level 0 [texels]
uniform samplerCube chain;      // GGX-prefiltered chain of env (probeless.ibl.prefilter)
uniform float chain_max_level;  // its last level (roughness 1)
uniform bool split_sum;         // the lobe from the chain x DFG (else importance-sampled from env)
#define MAX_LIGHTS 128
uniform samplerCube residual;   // env without its lights (with its mip chain), when light_count > 0
uniform int light_count;        // lights taken out of the map (probeless.ibl.prefilter.extract_lights)
uniform vec3 light_dir[MAX_LIGHTS];    // their unit world directions
uniform vec3 light_power[MAX_LIGHTS];  // their radiance x solid angle
uniform sampler2D light_parts;  // texel (j, k): part j of light k (direction), (j, light_count + k): its power
uniform int light_split;        // parts per light (0: none)
uniform float light_size;       // angular size of a light [rad]
uniform int sum_level;          // >= 0: the lobe as an exact sum over the texels of this mip level of env
uniform sampler2D dfg;          // (A, B) of probeless.ibl.dfg, s = n.v, t = roughness
uniform samplerCube glossy;     // an explicit prefiltered level (use_levels), read along R at level 0
uniform bool use_levels;        // the lobe comes from the given prefiltered levels (no Fresnel, no masking)
uniform vec3 sh_irr[25];        // SH radiance coefficients times the cosine-lobe A_l (irradiance)
uniform vec3 camera_position;
uniform vec3 kd;
uniform vec3 ks;                // specular reflectance at normal incidence (Schlick f0)
uniform vec3 f90;               // specular reflectance at grazing incidence (the layer's weight)
uniform float roughness;        // perceptual roughness of the specular lobe
uniform bool energy_compensation;  // Filament's multiple-scattering factor on the specular lobe
uniform int spec_samples;       // lookups per pixel of the specular lobe
uniform int refr_samples;       // lookups per pixel of the refraction
uniform vec3 kt;
uniform float ior;
uniform bool use_prt;
uniform float exposure;
in vec3 v_world;
in vec3 v_normal;
in vec3 v_prt;
in float v_depth;
layout(location = 0) out vec4 frag_color;
layout(location = 1) out float frag_depth;

// Orthonormal real SH (Condon-Shortley phase), row k = l(l+1)+m, as probeless.envmap.sh.sh_basis.
void sh_basis(vec3 d, out float Y[25]) {
    float z = clamp(d.z, -1.0, 1.0);
    float s = sqrt(max(0.0, 1.0 - z * z));
    float phi = (abs(d.x) + abs(d.y) > 1e-12) ? atan(d.y, d.x) : 0.0;
    float P[5][5];
    P[0][0] = 1.0;
    for (int m = 1; m < 5; ++m) P[m][m] = -float(2 * m - 1) * s * P[m - 1][m - 1];
    for (int m = 0; m < 4; ++m) P[m + 1][m] = float(2 * m + 1) * z * P[m][m];
    for (int m = 0; m < 5; ++m)
        for (int l = m + 2; l < 5; ++l)
            P[l][m] = (float(2 * l - 1) * z * P[l - 1][m] - float(l + m - 1) * P[l - 2][m]) / float(l - m);
    for (int l = 0; l < 5; ++l) {
        for (int m = 0; m <= l; ++m) {
            float ratio = 1.0;  // (l - m)! / (l + m)!
            for (int i = l - m + 1; i <= l + m; ++i) ratio /= float(i);
            float k = sqrt(float(2 * l + 1) / (4.0 * PI) * ratio);
            if (m == 0) {
                Y[l * (l + 1)] = k * P[l][0];
            } else {
                Y[l * (l + 1) + m] = sqrt(2.0) * k * cos(float(m) * phi) * P[l][m];
                Y[l * (l + 1) - m] = sqrt(2.0) * k * sin(float(m) * phi) * P[l][m];
            }
        }
    }
}

vec3 sh_irradiance(vec3 n) {
    float Y[25];
    sh_basis(n, Y);
    vec3 e = vec3(0.0);
    for (int k = 0; k < 25; ++k) e += sh_irr[k] * Y[k];
    return max(e, vec3(0.0));
}

// The surface under a sub-pixel sample: the osculating quadric of the pixel centre (position P, unit normal N, shape
// operator W = dN/dP from the screen derivatives), hit by the sample's exact camera ray. Flat triangles and their
// interpolated normals are its tangent plane only: at a curved object's rim a pixel's footprint in reflected
// directions then comes out 5-15 % too small, which a small bright light in the map turns into a 10 % error.
// D: the view ray scaled to camera depth 1, affine in the pixel coordinates (so its derivatives are exact).
vec3 frag_P, frag_N, frag_D, frag_dDdx, frag_dDdy;
mat3 frag_W;
void subpixel_frame(vec2 o, out vec3 ns, out vec3 is) {
    vec3 d = normalize(frag_D + o.x * frag_dDdx + o.y * frag_dDdy);
    vec3 e = camera_position - frag_P;
    vec3 et = e - dot(e, frag_N) * frag_N, dt = d - dot(d, frag_N) * frag_N;
    float a = 0.5 * dot(dt, frag_W * dt), b = dot(d, frag_N) + 0.5 * (dot(et, frag_W * dt) + dot(dt, frag_W * et));
    float c = dot(e, frag_N) + 0.5 * dot(et, frag_W * et);
    float disc = b * b - 4.0 * a * c;
    float t = -c / b;  // the tangent plane's hit (no real root: the ray passes the quadric; keep the plane)
    if (disc >= 0.0) {
        float q = -0.5 * (b + (b < 0.0 ? -1.0 : 1.0) * sqrt(disc));
        float t1 = c / q, t2 = abs(a) > 1e-20 ? q / a : -1.0;
        t = t1 > 0.0 && (t2 <= 0.0 || t1 < t2) ? t1 : (t2 > 0.0 ? t2 : t);
    }
    ns = normalize(frag_N + frag_W * (et + t * dt));
    is = d;
}
#define IBL_SUBPIXEL_FRAME(o, ns, is) subpixel_frame(o, ns, is)
#include "fresnel.glsl"
#include "ibl_specular.glsl"

#ifndef LIGHT_DENSITY
#define LIGHT_DENSITY 16.0
#endif
#ifndef MAX_LIGHT_GRID
#define MAX_LIGHT_GRID 8
#endif
#ifndef SPLIT_CURVATURE
#define SPLIT_CURVATURE 0.5
#endif
// The lights' single-scattering GGX reflection (Schlick ks -> f90), averaged over sub-pixel frames: as many as
// LIGHT_DENSITY per lobe solid angle in the pixel's footprint (a grid of 1 to MAX_LIGHT_GRID^2), so a lobe
// narrower than the footprint does not alias. Lights near the reflection direction of a lobe not much wider than
// they are act as their parts (a point is the wrong shape there); the others as points.
vec3 lights(vec3 N, vec3 I, vec3 dNdx, vec3 dNdy, vec3 dIdx, vec3 dIdy, float alpha) {
    vec3 rx, ry;
    ibl_footprint(N, I, dNdx, dNdy, dIdx, dIdy, rx, ry);
    float lobe = alpha;  // angular radius of the lobe about the mirror direction, roughly (1.3 alpha at half max) [rad]
    float frames = LIGHT_DENSITY * length(cross(rx, ry)) / (IBL_PI * lobe * lobe);
    int g = clamp(int(ceil(sqrt(frames))), 1, MAX_LIGHT_GRID);
    int m = g * g;  // frames on a g x g grid of cell centres (the midpoint rule: balanced even when g is small)
    // a light acts as its parts where the lobe's curvature across it, ~ size^2 / (alpha^2 + psi^2 / 4) at angle psi
    // from the mirror direction, exceeds SPLIT_CURVATURE; the footprint widens that cone
    float psi2 = 4.0 * (light_size * light_size / SPLIT_CURVATURE - alpha * alpha);
    bool split = light_split > 0 && psi2 > 0.0;
    float near = cos(min(sqrt(max(psi2, 0.0)) + light_size + max(length(rx), length(ry)), IBL_PI));
    vec3 R = reflect(I, N), sum = vec3(0.0);
    for (int j = 0; j < m; ++j) {
        vec3 ns, is;
        ibl_subpixel_frame((vec2(j % g, j / g) + 0.5) / float(g) - 0.5, N, I, dNdx, dNdy, dIdx, dIdy, ns, is);
        for (int k = 0; k < light_count; ++k) {
            if (split && dot(light_dir[k], R) > near) {
                for (int p = 0; p < light_split; ++p)
                    sum += texelFetch(light_parts, ivec2(p, light_count + k), 0).rgb
                           * ibl_ggx_cos(ns, -is, texelFetch(light_parts, ivec2(p, k), 0).xyz, alpha, ks, f90);
            } else {
                sum += light_power[k] * ibl_ggx_cos(ns, -is, light_dir[k], alpha, ks, f90);
            }
        }
    }
    return sum / float(m);
}

void main() {
    vec3 I = normalize(v_world - camera_position);
    vec3 N = normalize(v_normal);
    if (dot(N, I) > 0.0) N = -N;  // two-sided: open meshes show their inside
    vec3 dNdx = dFdx(N), dNdy = dFdy(N), dIdx = dFdx(I), dIdy = dFdy(I);
    vec3 dPdx = dFdx(v_world), dPdy = dFdy(v_world);
    mat2 g = mat2(dot(dPdx, dPdx), dot(dPdx, dPdy), dot(dPdx, dPdy), dot(dPdy, dPdy));
    float det = determinant(g);
    frag_P = v_world;
    frag_D = (v_world - camera_position) / v_depth;
    frag_dDdx = dFdx(frag_D);
    frag_dDdy = dFdy(frag_D);
    frag_N = N;
    frag_W = mat3(0.0);
    if (abs(det) > 1e-30) {  // W = [dN/dx dN/dy] G^-1 [dP/dx dP/dy]^T
        mat2 gi = inverse(g);
        frag_W = outerProduct(gi[0][0] * dNdx + gi[0][1] * dNdy, dPdx)
                 + outerProduct(gi[1][0] * dNdx + gi[1][1] * dNdy, dPdy);
    }
    vec3 color = vec3(0.0);
    if (any(greaterThan(kd, vec3(0.0))))
        color += kd * (use_prt ? max(v_prt, vec3(0.0)) : sh_irradiance(N)) / PI;
    if (any(greaterThan(ks, vec3(0.0))) || any(greaterThan(f90, vec3(0.0)))) {
        if (use_levels) {
            color += ks * textureLod(glossy, reflect(I, N), 0.0).rgb;
        } else if (sum_level >= 0) {
            vec3 spec = ibl_specular_sum(env, env_size, sum_level, N, I, roughness, ks, f90);
            if (energy_compensation) {
                vec2 ab = ibl_dfg(dfg, dot(N, -I), roughness);
                spec *= ibl_energy_compensation(ab, ks);
            }
            color += spec;
        } else if (split_sum) {
            color += ibl_specular_split(chain, chain_max_level, env_size, dfg, N, I, dNdx, dNdy, dIdx, dIdy, roughness,
                                        ks, f90, spec_samples, energy_compensation);
        } else {
            // the residual (its lights taken out: bounded contrast) needs no more lookups for the lobe's size
            vec3 spec = light_count > 0
                ? ibl_specular(residual, env_size, N, I, dNdx, dNdy, dIdx, dIdy, roughness, ks, f90, spec_samples, 0.0)
                : ibl_specular(env, env_size, N, I, dNdx, dNdy, dIdx, dIdy, roughness, ks, f90, spec_samples, 1.0);
            if (light_count > 0)
                spec += lights(N, I, dNdx, dNdy, dIdx, dIdy, max(roughness * roughness, IBL_MIN_ALPHA));
            if (energy_compensation) {
                vec2 ab = ibl_dfg(dfg, dot(N, -I), roughness);
                spec *= ibl_energy_compensation(ab, ks);
            }
            color += spec;
        }
    }
    if (any(greaterThan(kt, vec3(0.0))))
        color += kt * ibl_refraction(env, env_size, N, I, dNdx, dNdy, dIdx, dIdy, ior, refr_samples);
    frag_color = vec4(color * exposure, 1.0);
    frag_depth = v_depth;
}
