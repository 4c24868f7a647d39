// Image-based specular lighting from a cubemap with a full (GL-built, trilinear) mip chain: a GGX lobe by
// importance sampling the visible normals (Heitz 2018) with filtered lookups (Colbert & Krivanek 2007: each sample
// reads the mip level whose texels match its share of the lobe's solid angle), Schlick Fresnel per sample, Smith
// masking, and the multiple-scattering energy compensation of Filament (1 + f0 (1 / E_ss - 1), E_ss from the DFG
// table). Samples are spread over the pixel's footprint too (a grid of sub-pixel cells, as many lookups as the
// footprint covers texels: ibl_sample_count), so mirrors (alpha 0) and refractions are antialiased.
// Roughness is perceptual: GGX alpha = roughness^2. Directions are world directions, I from the eye to the surface.
// An include file: no #version, no #include; the includer declares nothing of it.

const float IBL_PI = 3.14159265358979;
const float IBL_MIN_ALPHA = 1e-4;
const float IBL_LOD_BIAS = 0.0;
#ifndef IBL_DENSITY
#define IBL_DENSITY 16.0
#endif
#ifndef IBL_MAX_SAMPLES
#define IBL_MAX_SAMPLES 2048
#endif

// Low-discrepancy point i of n in [0, 1)^2 (Hammersley).
vec2 ibl_hammersley(int i, int n) {
    return vec2((float(i) + 0.5) / float(n), float(bitfieldReverse(uint(i))) * 2.3283064365386963e-10);
}

// Sub-pixel offset of sample i in [-0.5, 0.5)^2 (the R2 sequence, uncorrelated with the Hammersley points).
vec2 ibl_subpixel(int i) {
    return fract(vec2(0.5) + float(i) * vec2(0.7548776662466927, 0.5698402909980532)) - 0.5;
}

// The unit normal ns and unit view ray is (eye -> surface) at sub-pixel offset o [px] of the pixel whose centre has
// N, I and screen derivatives dN, dI. A fragment shader that knows the surface better defines
// IBL_SUBPIXEL_FRAME(o, ns, is) (object.frag.glsl: the surface's osculating quadric hit by the offset's own camera
// ray, right also where the normal turns fast across a pixel, e.g. at a sphere's rim); otherwise the derivatives
// extrapolate linearly. Beyond the silhouette (the surface turned away): the pixel centre.
void ibl_subpixel_frame(vec2 o, vec3 N, vec3 I, vec3 dNdx, vec3 dNdy, vec3 dIdx, vec3 dIdy, out vec3 ns, out vec3 is) {
#ifdef IBL_SUBPIXEL_FRAME
    IBL_SUBPIXEL_FRAME(o, ns, is);
#else
    ns = normalize(N + o.x * dNdx + o.y * dNdy);
    is = normalize(I + o.x * dIdx + o.y * dIdy);
#endif
    if (dot(ns, -is) <= 1e-4) {
        ns = N;
        is = I;
    }
}

// The mirror direction at sub-pixel offset o (ibl_subpixel_frame).
vec3 ibl_subpixel_reflect(vec2 o, vec3 N, vec3 I, vec3 dNdx, vec3 dNdy, vec3 dIdx, vec3 dIdy) {
    vec3 ns, is;
    ibl_subpixel_frame(o, N, I, dNdx, dNdy, dIdx, dIdy, ns, is);
    return reflect(is, ns);
}

// The pixel's footprint in mirror directions: the changes rx, ry of the mirror direction across the pixel.
void ibl_footprint(vec3 N, vec3 I, vec3 dNdx, vec3 dNdy, vec3 dIdx, vec3 dIdy, out vec3 rx, out vec3 ry) {
    rx = ibl_subpixel_reflect(vec2(0.5, 0.0), N, I, dNdx, dNdy, dIdx, dIdy)
         - ibl_subpixel_reflect(vec2(-0.5, 0.0), N, I, dNdx, dNdy, dIdx, dIdy);
    ry = ibl_subpixel_reflect(vec2(0.0, 0.5), N, I, dNdx, dNdy, dIdx, dIdy)
         - ibl_subpixel_reflect(vec2(0.0, -0.5), N, I, dNdx, dNdy, dIdx, dIdy);
}

// Lookups for a pixel whose reflected directions (footprint and lobe) cover `omega` sr of a cube of face size
// `size`: IBL_DENSITY a level-0 texel, at least n_min, at most IBL_MAX_SAMPLES. A fixed count under-samples large
// footprints (a small object's pixels, a rim), where a few filtered lookups blur a small bright light into the
// wrong pixels; the total over an object stays bounded by the texels it reflects.
int ibl_sample_count(float omega, float size, int n_min) {
    float texel = 4.0 * IBL_PI / (6.0 * size * size);
    return clamp(int(ceil(IBL_DENSITY * omega / texel)), max(n_min, 1), max(n_min, IBL_MAX_SAMPLES));
}

// Smith G1 of GGX for a direction at cosine c to the normal.
float ibl_smith_g1(float alpha, float c) {
    float a2 = alpha * alpha;
    return 2.0 * c / (c + sqrt(a2 + (1.0 - a2) * c * c));
}

// A visible normal (local frame, z = normal) for the view direction v (local, v.z > 0) from u in [0, 1)^2.
vec3 ibl_sample_vndf(vec3 v, float alpha, vec2 u) {
    vec3 vh = normalize(vec3(alpha * v.x, alpha * v.y, v.z));
    float lensq = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = lensq > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(lensq) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u.x), phi = 2.0 * IBL_PI * u.y;
    float p1 = r * cos(phi), p2 = r * sin(phi);
    float s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    return normalize(vec3(alpha * nh.x, alpha * nh.y, max(1e-6, nh.z)));
}

// GGX D(h) with c = n.h.
float ibl_ggx_d(float alpha, float c) {
    float a2 = alpha * alpha;
    float den = c * c * (a2 - 1.0) + 1.0;
    return a2 / (IBL_PI * den * den);
}

// Single-scattering GGX BRDF times n.l for unit N, v (towards the eye), l (towards the light), Schlick f0 -> f90.
vec3 ibl_ggx_cos(vec3 N, vec3 v, vec3 l, float alpha, vec3 f0, vec3 f90) {
    float nl = dot(N, l), nv = max(dot(N, v), 1e-4);
    if (nl <= 0.0) return vec3(0.0);
    vec3 h = normalize(v + l);
    float m = 1.0 - max(dot(v, h), 0.0);
    vec3 F = f0 + (f90 - f0) * (m * m * m * m * m);
    return F * (ibl_ggx_d(alpha, max(dot(N, h), 0.0)) * ibl_smith_g1(alpha, nv) * ibl_smith_g1(alpha, nl) / (4.0 * nv));
}

// Mip level of a lookup whose texel should cover solid angle omega [sr] in a cube of face size `size`.
float ibl_lod(float omega, float size) {
    float texel = 4.0 * IBL_PI / (6.0 * size * size);
    return 0.5 * log2(max(omega, 1e-12) / texel);
}

// Mip level of sub-pixel lookups spaced by `spread` radians (the texel at a face centre subtends 2 / size rad).
float ibl_footprint_lod(float spread, float size) {
    return log2(max(spread * size * 0.5, 1e-6));
}

// (A, B) of the DFG table (probeless.ibl.dfg: 32 x 32 entries at i / 31) for n.v = mu and perceptual roughness.
vec2 ibl_dfg(sampler2D dfg, float mu, float roughness) {
    vec2 x = clamp(vec2(mu, roughness), 0.0, 1.0);
    return texture(dfg, (x * 31.0 + 0.5) / 32.0).rg;
}

// Single-scattering GGX reflection of the environment towards the eye, Schlick Fresnel f0 -> f90, over the pixel's
// footprint (dN, dI: screen derivatives of the normal and of the view ray): ibl_sample_count lookups for the
// footprint plus lobe_share times the lobe's solid angle (pi alpha^2; 0 for a map whose bright texels were taken out
// as lights), at least n_min. Rough lobes read the mip of each sample's solid angle, all lookups at least the level
// of the cell spacing.
vec3 ibl_specular(samplerCube env, float size, vec3 N, vec3 I, vec3 dNdx, vec3 dNdy, vec3 dIdx, vec3 dIdy,
                  float roughness, vec3 f0, vec3 f90, int n_min, float lobe_share) {
    float alpha = max(roughness * roughness, IBL_MIN_ALPHA);
    vec3 rx, ry;
    ibl_footprint(N, I, dNdx, dNdy, dIdx, dIdy, rx, ry);
    float fp = length(cross(rx, ry));  // the footprint's solid angle [sr]
    int n = ibl_sample_count(fp + lobe_share * IBL_PI * alpha * alpha, size, n_min);
    // the pixel as a g x g grid of cells (g^2: the footprint's share of n), each read at its centre by n / g^2 lobe
    // samples (Hammersley points, shifted per cell): the midpoint rule over the footprint, which unlike scattered
    // sub-pixel points stays balanced for a small bright light at any count
    int g = clamp(int(sqrt(float(ibl_sample_count(fp, size, 1)))), 1, int(sqrt(float(n))));
    int cells = g * g, per = max(1, n / cells);
    n = cells * per;
    float lod_fp = ibl_footprint_lod(max(length(rx), length(ry)) / float(g), size);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < n; ++i) {
        int c = i % cells;
        vec4 u = vec4((vec2(c % g, c / g) + 0.5) / float(g),
                      fract(ibl_hammersley(i / cells, per) + ibl_subpixel(c) + 0.5));
        vec3 ns, is;
        ibl_subpixel_frame(u.xy - 0.5, N, I, dNdx, dNdy, dIdx, dIdy, ns, is);
        vec3 vs = -is;
        vec3 t = normalize(abs(ns.z) < 0.999 ? cross(vec3(0.0, 0.0, 1.0), ns) : cross(vec3(1.0, 0.0, 0.0), ns));
        vec3 b = cross(ns, t);
        vec3 vl = vec3(dot(vs, t), dot(vs, b), dot(vs, ns));
        vec3 hl = ibl_sample_vndf(vl, alpha, u.zw);
        vec3 h = hl.x * t + hl.y * b + hl.z * ns;
        float vh = max(dot(vs, h), 0.0);
        vec3 l = 2.0 * vh * h - vs;
        float nl = dot(ns, l);
        if (nl <= 0.0) continue;
        float pdf = ibl_smith_g1(alpha, vl.z) * ibl_ggx_d(alpha, hl.z) / (4.0 * vl.z);  // of l [1/sr]
        float lod = max(ibl_lod(1.0 / (float(n) * pdf), size) + IBL_LOD_BIAS, lod_fp);
        float m = 1.0 - vh;
        vec3 F = f0 + (f90 - f0) * (m * m * m * m * m);
        sum += F * ibl_smith_g1(alpha, nl) * textureLod(env, l, lod).rgb;
    }
    return sum / float(n);
}

// Split-sum GGX reflection (Karis 2013) from a prefiltered chain (probeless.ibl.prefilter: level k >= 1 prefiltered
// for roughness 2^(-(max_level - k) / 2), read trilinearly at lod = max_level + 2 log2(roughness)): for each of n sub-pixel samples, the
// chain along the dominant direction mix(r, n, alpha^2) (Filament) times the environment BRDF f0 A + f90 B of the DFG
// table (s = n.v, t = roughness), times Filament's multiple-scattering factor when `compensate`. Lookups never read
// finer than the sub-pixel spacing (size: face size of level 0).
vec3 ibl_specular_split(samplerCube chain, float max_level, float size, sampler2D dfg, vec3 N, vec3 I,
                        vec3 dNdx, vec3 dNdy, vec3 dIdx, vec3 dIdy, float roughness, vec3 f0, vec3 f90, int n,
                        bool compensate) {
    float alpha = max(roughness * roughness, IBL_MIN_ALPHA);
    vec3 R = reflect(I, N);
    float spread = max(length(reflect(I + dIdx, normalize(N + dNdx)) - R),
                       length(reflect(I + dIdy, normalize(N + dNdy)) - R)) / sqrt(float(n));
    float lod = max(max_level + 2.0 * log2(max(roughness, 1e-3)), ibl_footprint_lod(spread, size));
    vec3 sum = vec3(0.0);
    for (int i = 0; i < n; ++i) {
        vec3 ns, is;
        ibl_subpixel_frame(ibl_subpixel(i), N, I, dNdx, dNdy, dIdx, dIdy, ns, is);
        vec3 r = reflect(is, ns);
        vec3 d = normalize(mix(r, ns, alpha * alpha));
        vec2 ab = ibl_dfg(dfg, dot(ns, -is), roughness);
        vec3 e = f0 * ab.x + f90 * ab.y;
        if (compensate) e *= 1.0 + f0 * (1.0 / max(ab.x + ab.y, 1e-3) - 1.0);
        sum += e * textureLod(chain, d, lod).rgb;
    }
    return sum / float(n);
}

// World direction of the centre of texel (col, row) of `face` in a cube of face size s (probeless.messages.lighting).
vec3 ibl_texel_direction(int face, int col, int row, int s) {
    float a = 2.0 * (float(col) + 0.5) / float(s) - 1.0, b = 2.0 * (float(row) + 0.5) / float(s) - 1.0;
    if (face == 0) return vec3(1.0, -b, -a);
    if (face == 1) return vec3(-1.0, -b, a);
    if (face == 2) return vec3(a, 1.0, b);
    if (face == 3) return vec3(a, -1.0, -b);
    if (face == 4) return vec3(a, -b, 1.0);
    return vec3(-a, -b, -1.0);
}

// Single-scattering GGX reflection as an exact sum over the texels of mip `level` (face size s = size >> level) of
// env: sum L_t f(v, l_t) (n.l_t) dw_t, f = F D G1(v) G1(l) / (4 (n.v) (n.l)), Schlick F f0 -> f90. No sampling: a
// small, very bright light (a window, a lamp, the sun) weighs exactly its share, which no fixed sample pattern does.
vec3 ibl_specular_sum(samplerCube env, float size, int level, vec3 N, vec3 I, float roughness, vec3 f0, vec3 f90) {
    float alpha = max(roughness * roughness, IBL_MIN_ALPHA);
    int s = max(1, int(size) >> level);
    vec3 v = -I;
    float nv = max(dot(N, v), 1e-4);
    float gv = ibl_smith_g1(alpha, nv) / (4.0 * nv);
    float texel = 2.0 / float(s);
    vec3 sum = vec3(0.0);
    for (int face = 0; face < 6; ++face) {
        for (int row = 0; row < s; ++row) {
            for (int col = 0; col < s; ++col) {
                vec3 d = ibl_texel_direction(face, col, row, s);
                float r2 = dot(d, d);
                vec3 l = d * inversesqrt(r2);
                float nl = dot(N, l);
                if (nl <= 0.0) continue;
                vec3 h = normalize(v + l);
                float vh = max(dot(v, h), 0.0);
                float m = 1.0 - vh;
                vec3 F = f0 + (f90 - f0) * (m * m * m * m * m);
                float w = ibl_ggx_d(alpha, max(dot(N, h), 0.0)) * gv * ibl_smith_g1(alpha, nl) * texel * texel
                          / (r2 * sqrt(r2));
                sum += w * F * textureLod(env, l, float(level)).rgb;
            }
        }
    }
    return sum;
}

// Filament's multiple-scattering compensation of the single-scattering lobe: 1 + f0 (1 / E_ss - 1), E_ss the
// directional albedo of a white (f0 = f90 = 1) GGX surface, dfg(n.v, roughness) = (A, B) with E_ss = A + B.
vec3 ibl_energy_compensation(vec2 dfg, vec3 f0) {
    return 1.0 + f0 * (1.0 / max(dfg.x + dfg.y, 1e-3) - 1.0);
}

// The environment along the refracted rays of n sub-pixel samples, each mixed with its reflection by the exact
// dielectric Fresnel factor `fresnel(cos, ior)` (fresnel.glsl, which the includer includes).
vec3 ibl_refraction(samplerCube env, float size, vec3 N, vec3 I, vec3 dNdx, vec3 dNdy, vec3 dIdx, vec3 dIdy,
                    float ior, int n) {
    vec3 T = refract(I, N, 1.0 / ior);
    float spread = max(length(refract(normalize(I + dIdx), normalize(N + dNdx), 1.0 / ior) - T),
                       length(refract(normalize(I + dIdy), normalize(N + dNdy), 1.0 / ior) - T)) / sqrt(float(n));
    float lod_t = ibl_footprint_lod(spread, size);
    float spread_r = max(length(reflect(I + dIdx, normalize(N + dNdx)) - reflect(I, N)),
                         length(reflect(I + dIdy, normalize(N + dNdy)) - reflect(I, N))) / sqrt(float(n));
    float lod_r = ibl_footprint_lod(spread_r, size);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < n; ++i) {
        vec3 ns, is;
        ibl_subpixel_frame(ibl_subpixel(i), N, I, dNdx, dNdy, dIdx, dIdy, ns, is);
        float F = fresnel(clamp(-dot(is, ns), 0.0, 1.0), ior);
        vec3 through = F < 1.0 ? textureLod(env, refract(is, ns, 1.0 / ior), lod_t).rgb : vec3(0.0);
        sum += (1.0 - F) * through + F * textureLod(env, reflect(is, ns), lod_r).rgb;
    }
    return sum / float(n);
}

