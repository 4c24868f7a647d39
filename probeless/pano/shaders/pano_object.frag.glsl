#version 430
// Image-based shading from one equirectangular HDR frame (paper 002):
// kd * diffuse_map(N) + ks * (mirror or glossy ring sampling around R) + kt * Fresnel-weighted refraction.
// Equirect convention (probeless.pano.equirect): z up, v = theta / pi (row 0 = zenith),
// u = phi / 2 pi with phi from +x towards -y (clockwise seen from above). Every lookup uses textureLod
// with an explicit level, so the jump of u at the seam never reaches a derivative.
#ifndef MAX_RING_SAMPLES
#define MAX_RING_SAMPLES 64
#endif
const float PI = 3.14159265358979;
uniform sampler2D env;          // HDR frame, full mip chain, repeat in u, clamp in v
uniform sampler2D diffuse_map;  // outgoing radiance of a white Lambertian surface, bilinear
uniform vec3 camera_position;
uniform vec3 kd;
uniform vec3 ks;
uniform vec3 kt;
uniform float ior;
uniform int n_samples;          // ring samples of the glossy lobe; 0 = mirror
uniform float ring_angle[MAX_RING_SAMPLES];    // from R [rad]
uniform float ring_azimuth[MAX_RING_SAMPLES];  // about R [rad]
uniform float ring_weight[MAX_RING_SAMPLES];   // sum 1
uniform float ring_lod[MAX_RING_SAMPLES];      // mip level
in vec3 v_world;
in vec3 v_normal;
layout(location = 0) out vec4 frag_color;

#include "equirect.glsl"

vec3 env_at(vec3 d, float lod) { return textureLod(env, equirect_uv(d), lod).rgb; }

// Ring samples about R in the frame of probeless.pano.glossy.tangent_frame.
vec3 glossy(vec3 r) {
    vec3 up = abs(r.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
    vec3 t = normalize(cross(up, r));
    vec3 b = cross(r, t);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < n_samples; ++k) {
        float a = ring_angle[k], az = ring_azimuth[k];
        vec3 d = cos(a) * r + sin(a) * (cos(az) * t + sin(az) * b);
        sum += ring_weight[k] * env_at(d, ring_lod[k]);
    }
    return sum;
}

#include "fresnel.glsl"

void main() {
    vec3 I = normalize(v_world - camera_position);
    vec3 N = normalize(v_normal);
    if (dot(N, I) > 0.0) N = -N;  // two-sided: open meshes show their inside
    vec3 R = reflect(I, N);
    vec3 color = vec3(0.0);
    if (any(greaterThan(kd, vec3(0.0))))
        color += kd * textureLod(diffuse_map, equirect_uv(N), 0.0).rgb;
    if (any(greaterThan(ks, vec3(0.0))))
        color += ks * (n_samples > 0 ? glossy(R) : env_at(R, 0.0));
    if (any(greaterThan(kt, vec3(0.0)))) {
        float F = fresnel(clamp(-dot(I, N), 0.0, 1.0), ior);
        vec3 through = F < 1.0 ? env_at(refract(I, N, 1.0 / ior), 0.0) : vec3(0.0);
        color += kt * ((1.0 - F) * through + F * env_at(R, 0.0));
    }
    frag_color = vec4(color, 1.0);
}
