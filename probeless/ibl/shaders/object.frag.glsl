#version 430
// Image-based shading: kd * diffuse + ks * glossy reflection + kt * Fresnel-weighted refraction.
// Cubemaps hold linear radiance and are sampled with the world direction (messages/lighting.py).
const float PI = 3.14159265358979;
uniform samplerCube env;        // mirror radiance, with mip chain
uniform samplerCube glossy;     // specular lobe source (env or a prefiltered level)
uniform float glossy_lod;       // mip level to read the specular lobe at
uniform vec3 sh_irr[25];        // SH radiance coefficients times the cosine-lobe A_l (irradiance)
uniform vec3 camera_position;
uniform vec3 kd;
uniform vec3 ks;
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

void main() {
    vec3 I = normalize(v_world - camera_position);
    vec3 N = normalize(v_normal);
    if (dot(N, I) > 0.0) N = -N;  // two-sided: open meshes show their inside
    vec3 R = reflect(I, N);
    vec3 color = vec3(0.0);
    if (any(greaterThan(kd, vec3(0.0))))
        color += kd * (use_prt ? max(v_prt, vec3(0.0)) : sh_irradiance(N)) / PI;
    if (any(greaterThan(ks, vec3(0.0))))
        color += ks * textureLod(glossy, R, glossy_lod).rgb;
    if (any(greaterThan(kt, vec3(0.0)))) {
        float F = fresnel(clamp(-dot(I, N), 0.0, 1.0), ior);
        vec3 T = refract(I, N, 1.0 / ior);
        vec3 through = F < 1.0 ? textureLod(env, T, 0.0).rgb : vec3(0.0);
        color += kt * ((1.0 - F) * through + F * textureLod(env, R, 0.0).rgb);
    }
    frag_color = vec4(color * exposure, 1.0);
    frag_depth = v_depth;
}
