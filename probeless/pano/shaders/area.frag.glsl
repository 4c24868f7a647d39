#version 430
// Area-weighted downsampling (cv2.INTER_AREA): each output texel averages the source texels it
// covers, partly covered ones by their covered fraction. Source texel (x, y) spans [x, x + 1).
uniform sampler2D src;
uniform vec2 scale;  // source texels per output texel, (x, y)
out vec4 avg;

void main() {
    vec2 lo = floor(gl_FragCoord.xy) * scale;
    vec2 hi = lo + scale;
    ivec2 size = textureSize(src, 0);
    ivec2 a = ivec2(floor(lo));
    ivec2 b = min(ivec2(ceil(hi - 1e-4)), size);  // -1e-4: a rounding-error sliver is no texel
    vec3 acc = vec3(0.0);
    float wsum = 0.0;
    for (int y = a.y; y < b.y; ++y) {
        float wy = min(hi.y, float(y + 1)) - max(lo.y, float(y));
        for (int x = a.x; x < b.x; ++x) {
            float w = wy * (min(hi.x, float(x + 1)) - max(lo.x, float(x)));
            acc += w * texelFetch(src, ivec2(x, y), 0).rgb;
            wsum += w;
        }
    }
    avg = vec4(acc / wsum, 1.0);
}
