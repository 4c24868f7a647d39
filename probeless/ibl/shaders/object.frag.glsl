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

#include "fresnel.glsl"
#include "ibl_specular.glsl"

void main() {
    vec3 I = normalize(v_world - camera_position);
    vec3 N = normalize(v_normal);
    if (dot(N, I) > 0.0) N = -N;  // two-sided: open meshes show their inside
    vec3 dNdx = dFdx(N), dNdy = dFdy(N), dIdx = dFdx(I), dIdy = dFdy(I);
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
            vec3 spec = light_count > 0
                ? ibl_specular(residual, env_size, N, I, dNdx, dNdy, dIdx, dIdy, roughness, ks, f90, spec_samples)
                : ibl_specular(env, env_size, N, I, dNdx, dNdy, dIdx, dIdy, roughness, ks, f90, spec_samples);
            float alpha = max(roughness * roughness, IBL_MIN_ALPHA);
            for (int i = 0; i < light_count; ++i)
                spec += light_power[i] * ibl_ggx_cos(N, -I, light_dir[i], alpha, ks, f90);
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
