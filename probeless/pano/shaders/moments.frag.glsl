#version 430
// Radiance moments of each coarse texel: integral of L(w) w dOmega over the source pixels it covers
// (partly covered ones by their covered fraction), one output per direction axis (rgb), and the
// same of w alone (a). With them the cosine integral over a texel wholly above a normal's horizon
// is the pixel sum itself: n.x mx + n.y my + n.z mz, weight n . (mx.a, my.a, mz.a).
uniform sampler2D src;  // the equirect frame, full resolution
uniform vec2 scale;     // source pixels per coarse texel, (x, y)
layout(location = 0) out vec4 mx;
layout(location = 1) out vec4 my;
layout(location = 2) out vec4 mz;

const float PI = 3.14159265358979;

#include "equirect.glsl"

void main() {
    vec2 lo = floor(gl_FragCoord.xy) * scale;
    vec2 hi = lo + scale;
    ivec2 size = textureSize(src, 0);
    ivec2 a = ivec2(floor(lo));
    ivec2 b = min(ivec2(ceil(hi - 1e-4)), size);
    float dt = PI / float(size.y), dp = 2.0 * PI / float(size.x);
    vec4 ax = vec4(0.0), ay = vec4(0.0), az = vec4(0.0);
    for (int y = a.y; y < b.y; ++y) {
        float t = (float(y) + 0.5) * dt;
        float st = sin(t);
        float wy = (min(hi.y, float(y + 1)) - max(lo.y, float(y))) * dp * 2.0 * st * sin(dt / 2.0);
        for (int x = a.x; x < b.x; ++x) {
            float ph = (float(x) + 0.5) * dp;
            float g = wy * (min(hi.x, float(x + 1)) - max(lo.x, float(x)));
            vec4 l = g * vec4(texelFetch(src, ivec2(x, y), 0).rgb, 1.0);
            vec3 w = equirect_direction(t, ph);
            ax += l * w.x;
            ay += l * w.y;
            az += l * w.z;
        }
    }
    mx = ax;
    my = ay;
    mz = az;
}
