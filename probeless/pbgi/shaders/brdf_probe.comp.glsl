#version 430
// Test probe of brdf.glsl (tests/pbgi/test_brdf.py): one invocation per record of 20 floats.
// In: n (0-2), wi (3-5), wo (6-8), base (9-11), roughness (12), metalness (13), model (14), u (15-16), alpha (17).
// Out: brdf_eval rgb (0-2), ggx_pdf_reflect (3), ggx_sample_half (4-6), hammersley(i, count) (7-8),
// tangent_frame columns t, b, n (9-17).
#include "brdf.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Inputs { float inp[]; };
layout(std430, binding = 1) writeonly buffer Outputs { float outp[]; };
uniform uint count;

vec3 in3(uint k) { return vec3(inp[k], inp[k + 1u], inp[k + 2u]); }

void out3(uint k, vec3 v) { outp[k] = v.x; outp[k + 1u] = v.y; outp[k + 2u] = v.z; }

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    uint k = 20u * i;
    vec3 n = in3(k), wi = in3(k + 3u), wo = in3(k + 6u), base = in3(k + 9u);
    float alpha = inp[k + 17u];
    out3(k, brdf_eval(int(inp[k + 14u] + 0.5), base, inp[k + 12u], inp[k + 13u], n, wi, wo));
    outp[k + 3u] = ggx_pdf_reflect(alpha, n, wi, wo);
    out3(k + 4u, ggx_sample_half(vec2(inp[k + 15u], inp[k + 16u]), alpha));
    vec2 p = hammersley(i, count);
    outp[k + 7u] = p.x; outp[k + 8u] = p.y;
    mat3 f = tangent_frame(n);
    out3(k + 9u, f[0]); out3(k + 12u, f[1]); out3(k + 15u, f[2]);
    outp[k + 18u] = 0.0; outp[k + 19u] = 0.0;
}
