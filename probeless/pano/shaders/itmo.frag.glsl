#version 430
// Per-pixel inverse tone mapping of an 8-bit frame (normalised sampler: stored values / 255).
// OP 0 = paper 002 Eq. 1-3 on the stored values; 1 = Landis on (optionally gamma-decoded) values;
// 2 = sRGB decode only; 3 = stored values as they are.
uniform sampler2D ldr;
uniform int op;
uniform bool linearize;      // Landis: value^decode_gamma first
uniform float decode_gamma;
uniform float max_lum;       // Landis: luminance that Ld = 1 maps to
uniform float threshold;     // Landis: R, start of the expanded range
uniform float alpha;         // Landis: exponent of the blend
out vec4 hdr;

const vec3 PAPER = vec3(0.3, 0.59, 0.11);
const vec3 REC709 = vec3(0.2126, 0.7152, 0.0722);

vec3 paper(vec3 c) {
    float l = dot(c, PAPER);
    float l2 = l * l, l4 = l2 * l2;
    return c * (10.0 * (l4 * l4 * l2) + 1.8);  // products, not pow(): exact-ish for l = 0 too
}

vec3 landis(vec3 c) {
    if (linearize) c = pow(c, vec3(decode_gamma));
    float ld = dot(c, REC709);
    float k = pow(max(ld - threshold, 0.0) / (1.0 - threshold), alpha);
    float lw = (1.0 - k) * ld + k * max_lum * ld;
    return ld > 0.0 ? c * (lw / ld) : vec3(0.0);
}

vec3 srgb_decode(vec3 c) {
    return mix(pow((c + 0.055) / 1.055, vec3(2.4)), c / 12.92, lessThanEqual(c, vec3(0.04045)));
}

void main() {
    vec3 c = texelFetch(ldr, ivec2(gl_FragCoord.xy), 0).rgb;
    vec3 o = op == 0 ? paper(c) : op == 1 ? landis(c) : op == 2 ? srgb_decode(c) : c;
    hdr = vec4(o, 1.0);
}
