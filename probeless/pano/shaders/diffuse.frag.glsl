#version 430
// Paper 002 Algorithm 1: each output texel (normal n) sums weight * radiance over every input
// texel and divides by the weight sum (BY_WEIGHTS) or by pi. The weight of an input texel is the
// integral of max(0, n . w) over it: n . m (m = exact integral of w over the texel) when the texel
// lies wholly above n's horizon, SUB x SUB sub-texel midpoints when it straddles the horizon, 0
// below. PAPER_WEIGHTS instead uses the paper's literal cos(latitude) * max(0, n . centre).
// MOMENTS: texels above the horizon contribute n . (radiance moments), exact for any radiance
// inside the texel, and straddling sub-texels take their own radiance from the fine level.
uniform sampler2D env;      // input HDR, in_w x in_h
uniform sampler2D moment;   // per input texel: m.xyz, sin(angular radius bound)
uniform sampler2D centre;   // per input texel: centre direction xyz, cos(latitude)
uniform sampler2D normals;  // per output texel: its direction
uniform sampler2D mx, my, mz;  // MOMENTS: per input texel, integral of (L, 1) w dOmega, one axis each
uniform sampler2D fine;     // MOMENTS: the frame at SUB x the input size
out vec4 diffuse;

const float PI = 3.14159265358979;

#include "equirect.glsl"

// (sum of w L, sum of w) over the SUB x SUB sub-texels of input texel p
vec4 straddling(ivec2 p, ivec2 size, vec3 n, vec3 texel) {
    float dt = PI / float(size.y), dp = 2.0 * PI / float(size.x);
    vec4 acc = vec4(0.0);
    for (int k = 0; k < SUB; ++k) {
        float t = (float(p.y) + (float(k) + 0.5) / float(SUB)) * dt;
        float st = sin(t);
        float omega = (dp / float(SUB)) * 2.0 * st * sin(dt / (2.0 * float(SUB)));  // cos t0 - cos t1
        for (int l = 0; l < SUB; ++l) {
            float ph = (float(p.x) + (float(l) + 0.5) / float(SUB)) * dp;
            float w = omega * max(dot(n, equirect_direction(t, ph)), 0.0);
#if MOMENTS
            texel = texelFetch(fine, p * SUB + ivec2(l, k), 0).rgb;
#endif
            acc += w * vec4(texel, 1.0);
        }
    }
    return acc;
}

void main() {
    vec3 n = texelFetch(normals, ivec2(gl_FragCoord.xy), 0).xyz;
    ivec2 size = textureSize(centre, 0);
    vec4 acc = vec4(0.0);  // rgb: sum of weight * radiance, a: sum of weights
    for (int y = 0; y < size.y; ++y) {
        for (int x = 0; x < size.x; ++x) {
            ivec2 p = ivec2(x, y);
            vec4 c = texelFetch(centre, p, 0);
            float nc = dot(n, c.xyz);
#if PAPER_WEIGHTS
            acc += c.w * max(nc, 0.0) * vec4(texelFetch(env, p, 0).rgb, 1.0);
#else
            vec4 m = texelFetch(moment, p, 0);
            if (nc <= -m.w) continue;
            if (nc < m.w) {
                acc += straddling(p, size, n, MOMENTS != 0 ? vec3(0.0) : texelFetch(env, p, 0).rgb);
            } else {
#if MOMENTS
                acc += n.x * texelFetch(mx, p, 0) + n.y * texelFetch(my, p, 0) + n.z * texelFetch(mz, p, 0);
#else
                acc += dot(n, m.xyz) * vec4(texelFetch(env, p, 0).rgb, 1.0);
#endif
            }
#endif
        }
    }
    diffuse = vec4(acc.rgb / (BY_WEIGHTS != 0 ? acc.a : PI), 1.0);
}
