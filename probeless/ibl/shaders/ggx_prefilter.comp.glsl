#version 430
// One level of the GGX-prefiltered radiance chain (Karis 2013's split-sum radiance, n = v = r): every texel of
// `level` of `chain` (face size `size`) gets sum L(l) (n.l) / sum (n.l) over `samples` GGX half-vectors h
// (Hammersley; pdf of l = D(h) / 4), l = reflect(-n, h), each read from `source` (the map with its box mip chain) at
// the mip level whose texels match the sample's solid angle (Colbert & Krivanek 2007). Alpha = roughness^2.
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) uniform writeonly imageCube chain;
uniform samplerCube source;
uniform float source_size;   // face size of source's level 0 [texels]
uniform int size;            // face size of this level [texels]
uniform float roughness;     // perceptual roughness of this level
uniform int samples;

#include "fresnel.glsl"
#include "ibl_specular.glsl"

// World direction of texel (col, row) of `face` (probeless.messages.lighting's table).
vec3 texel_direction(int face, float col, float row) {
    float a = 2.0 * (col + 0.5) / float(size) - 1.0, b = 2.0 * (row + 0.5) / float(size) - 1.0;
    vec3 d;
    if (face == 0) d = vec3(1.0, -b, -a);
    else if (face == 1) d = vec3(-1.0, -b, a);
    else if (face == 2) d = vec3(a, 1.0, b);
    else if (face == 3) d = vec3(a, -1.0, -b);
    else if (face == 4) d = vec3(a, -b, 1.0);
    else d = vec3(-a, -b, -1.0);
    return normalize(d);
}

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (p.x >= size || p.y >= size) return;
    vec3 n = texel_direction(p.z, float(p.x), float(p.y));
    vec3 t = normalize(abs(n.z) < 0.999 ? cross(vec3(0.0, 0.0, 1.0), n) : cross(vec3(1.0, 0.0, 0.0), n));
    vec3 b = cross(n, t);
    float alpha = max(roughness * roughness, IBL_MIN_ALPHA);
    float a2 = alpha * alpha;
    vec3 sum = vec3(0.0);
    float weight = 0.0;
    for (int i = 0; i < samples; ++i) {
        vec2 u = ibl_hammersley(i, samples);
        float cos_h = sqrt((1.0 - u.x) / (1.0 + (a2 - 1.0) * u.x));
        float sin_h = sqrt(max(0.0, 1.0 - cos_h * cos_h));
        float phi = 2.0 * IBL_PI * u.y;
        vec3 h = sin_h * cos(phi) * t + sin_h * sin(phi) * b + cos_h * n;
        vec3 l = 2.0 * cos_h * h - n;
        float nl = dot(n, l);
        if (nl <= 0.0) continue;
        float pdf = ibl_ggx_d(alpha, cos_h) * 0.25;  // D(h) (n.h) / (4 v.h) with v = n
        float lod = max(ibl_lod(1.0 / (float(samples) * pdf), source_size), 0.0);
        sum += nl * textureLod(source, l, lod).rgb;
        weight += nl;
    }
    imageStore(chain, p, vec4(sum / max(weight, 1e-12), 1.0));
}
