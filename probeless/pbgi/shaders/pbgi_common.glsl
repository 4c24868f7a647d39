// Shared by the PBGI micro-buffer programs (probeless.pbgi.microbuffer): the BSH node and G-buffer pixel
// records, the visibility (culling) tests, the node solid angle (paper 001 Eq. 4) and the micro-buffer splat.
//
// Micro-buffer: M x M uints per receiver (level-0 G-buffer pixel), the hemisphere around its normal in the
// orthographic (Nusselt) projection: texel (x, y) looks along frame * (q.x, q.y, sqrt(1 - |q|^2)),
// q = ((x, y) + 0.5) / M * 2 - 1; texels with |q| >= 1 are unused. A texel holds the key
// (quantised log depth << (VOR_BITS + idx_bits)) | (nearness rank << idx_bits) | node slot, so atomicMin keeps the
// nearest surface (the depth test) and, among nodes of one surface (equal depth: neighbours on a wall, whose bounding
// disks overlap), the node whose centre is nearest the texel's ray: a Voronoi split of the overlaps instead of the
// lower slot number winning, which let the disks of bright patches (a lamp) spill over their dark neighbours.
// The depth is pushed back by rim_depth * rank (log units, microbuffer.RIM_DEPTH): a bounding disk's rim may lie
// beyond its points, so a nearer node's rim loses to a node a step behind that is hit near its centre (a decal a few
// mm in front of its wall no longer covers the wall beyond its edges); steps of more than rim_depth x distance
// occlude as before.
// MB_EMPTY = nothing landed there.

#define PBGI_PI 3.14159265358979
#define NO_CHILD 0xFFFFFFFFu
#define MB_EMPTY 0xFFFFFFFFu
#define VOR_BITS 3u

struct Node { float cx, cy, cz, r, red, green, blue; uint cone, skip, right; };  // 40 bytes (bsh.NODE_DTYPE)
struct GPixel {  // a G-buffer pixel of some mip level (48 bytes, microbuffer.GPIXEL_DTYPE)
    float px, py, pz, rho;      // mean position, radius of the level-0 positions under it [m, world]
    float nx, ny, nz, gamma;    // normal cone: axis, half-angle [rad] (0 at level 0)
    uint first, count, level, slot;  // children (previous level, global index), level, micro-buffer slot
};

layout(std430, binding = 0) readonly buffer Nodes { Node nodes[]; };
layout(std430, binding = 1) readonly buffer GPixels { GPixel gpix[]; };
layout(std430, binding = 2) buffer Micro { uint micro[]; };

uniform int M;               // micro-buffer side [texels]
uniform uint slot_base;      // first slot of this batch
uniform float omega_stop;    // splat when the node's solid angle <= this (4 x 2 pi / M^2, §5.3) [sr]
uniform uint idx_bits;       // low bits of a texel: node slot
uniform float log_dmin;      // depth quantisation: log of the nearest depth [log m]
uniform float log_drange;    // log(dmax) - log(dmin)
uniform float rim_depth;     // a splat's depth is pushed back by rim_depth * t [log m] at nearness rank t (texel_key)
uniform vec3 near_center;    // near_field: nodes wholly farther than near_radius from here are culled [m, world]
uniform float near_radius;   // <= 0: no near-field culling [m]
uniform vec2 cone_cs[256];   // (cos, sin) of the packed cone half-angles k pi / 255

vec3 node_center(Node a) { return vec3(a.cx, a.cy, a.cz); }

vec3 cone_axis(uint c) {  // octahedral decode of bsh.pack_cone's 12 + 12 bits
    vec2 q = vec2(float(c & 0xFFFu), float((c >> 12) & 0xFFFu)) / 4095.0 * 2.0 - 1.0;
    vec3 v = vec3(q, 1.0 - abs(q.x) - abs(q.y));
    if (v.z < 0.0) v.xy = (1.0 - abs(v.yx)) * vec2(v.x >= 0.0 ? 1.0 : -1.0, v.y >= 0.0 ? 1.0 : -1.0);
    return normalize(v);
}

// Eq. 4: the solid angle of the cone from a point at distance d around a sphere of radius r [sr].
float node_solid_angle(float d, float r) {
    if (d <= r) return 4.0 * PBGI_PI;
    return 2.0 * PBGI_PI * (1.0 - sqrt(d * d - r * r) / d);
}

float solid_angle_of_cone(float half_angle) { return 2.0 * PBGI_PI * (1.0 - cos(half_angle)); }

// Eq. 4 compared with a threshold without square roots: node_solid_angle(d, r) > omega exactly when
// r^2 > k d^2, k = 1 - (1 - omega / 2 pi)^2 (k = 1 when omega >= 2 pi: only d < r passes). See omega_k().
bool subtends_more(float d, float r, float k) { return r * r > k * d * d; }

float omega_k(float omega) {
    float c = max(0.0, 1.0 - omega / (2.0 * PBGI_PI));
    return 1.0 - c * c;
}

// True when node a cannot light any receiver in the pixel cone (p, rho, n, gamma): it lies below every receiver's
// horizon (Eq. 8, Figure 8), its normal cone faces away from every receiver (Figure 5), or, in near-field mode, it
// is wholly outside the near ball. Conservative: the node's angular radius beta is widened by the pixel's extent
// rho. Angles are compared through their sines and cosines (angle(x, y) > pi/2 + t  <=>  x.y < -sin t, t <= pi/2):
// llvmpipe evaluates acos/asin as long polynomials. cs_gamma = (cos, sin) of gamma.
bool culled(Node a, vec3 p, float rho, vec3 n, vec2 cs_gamma) {
    vec3 c = node_center(a);
    if (near_radius > 0.0 && length(c - near_center) - a.r > near_radius) return true;
    vec3 v = c - p;
    float d = length(v);
    float sb = (a.r + rho) / d;
    if (sb >= 1.0) return false;
    vec3 w = v / d;
    float cb = sqrt(1.0 - sb * sb);
    float s = sb * cs_gamma.x + cb * cs_gamma.y;  // sin(beta + gamma)
    if (cb * cs_gamma.x - sb * cs_gamma.y > 0.0 && dot(n, w) < -s) return true;  // beta + gamma < pi/2
    vec2 ca = cone_cs[a.cone >> 24];
    if (cb * ca.x - sb * ca.y <= 0.0) return false;  // alpha + beta >= pi/2: some point may face p
    return -dot(cone_axis(a.cone), w) < -(sb * ca.x + cb * ca.y);
}

// The micro-buffer's frame around unit normal n (columns t, b, n); shading uses the same one.
mat3 mb_frame(vec3 n) {
    vec3 t = abs(n.z) < 0.999 ? normalize(cross(vec3(0.0, 0.0, 1.0), n)) : vec3(1.0, 0.0, 0.0);
    return mat3(t, cross(n, t), n);
}

// The key's high bits: log depth d [m] and the nearness rank t in [0, 1] (0: the texel's ray meets the node's centre,
// 1: its rim), above the node slot's idx_bits.
uint texel_key(float d, float t, uint i) {
    float u = clamp((log(max(d, 1e-9)) + rim_depth * t - log_dmin) / log_drange, 0.0, 1.0);
    uint rank = min(uint(t * float(1u << VOR_BITS)), (1u << VOR_BITS) - 1u);
    uint depth = uint(u * float((1u << (32u - idx_bits - VOR_BITS)) - 1u));
    return (depth << (idx_bits + VOR_BITS)) | (rank << idx_bits) | i;
}

// Rasterise node slot i into the micro-buffer of `slot` at receiver p with frame f. A node whose normal cone is
// narrow (half-angle <= DISK_MAX_ANGLE: a near-flat patch) is splatted as a disk (centre, cone axis, its radius):
// a texel is covered when its ray meets the disk, at the depth where it meets the disk's plane (the paper's depth);
// other nodes as their sphere (a ray-sphere test, depth: the centre's distance). A sphere overestimates a flat
// patch seen obliquely by 1 / cos of the angle; the disk does not. If no texel centre is covered, the texel of the
// centre direction takes the node. Returns the texels tested (one loop over the bounding box of the sphere's cap:
// the classic walk counts them against llvmpipe's loop limit).
#define DISK_MAX_ANGLE 64u  // packed cone angle units of pi / 255: ~45 degrees
uint splat(uint slot, vec3 p, mat3 f, uint i) {
    Node a = nodes[i];
    vec3 c = node_center(a);
    vec3 v = c - p;
    float d = length(v);
    if (d <= a.r) return 0u;  // the receiver is inside the node: no direction to splat along
    vec3 l = transpose(f) * (v / d);
    float sinb = a.r / d;
    float cosb = sqrt(max(0.0, 1.0 - sinb * sinb));
    float h = sqrt(max(0.0, 2.0 - 2.0 * cosb));  // chord: bounds the cap's footprint in the projection
    float fm = float(M);
    ivec2 lo = clamp(ivec2(floor((l.xy - h + 1.0) * 0.5 * fm)), ivec2(0), ivec2(M - 1));
    ivec2 hi = clamp(ivec2(floor((l.xy + h + 1.0) * 0.5 * fm)), ivec2(0), ivec2(M - 1));
    bool disk = (a.cone >> 24) <= DISK_MAX_ANGLE;
    vec3 axis = transpose(f) * cone_axis(a.cone);  // in the micro-buffer frame
    vec3 lc = transpose(f) * v;                     // centre relative to p, micro-buffer frame
    float plane = dot(lc, axis);
    uint code = texel_key(d, 0.0, i);
    uint base = (slot - slot_base) * uint(M * M);
    int w = hi.x - lo.x + 1;
    int cells = w * (hi.y - lo.y + 1);
    bool hit = false;
    for (int k = 0; k < cells; ++k) {
        int x = lo.x + k % w, y = lo.y + k / w;
        vec2 q = (vec2(x, y) + 0.5) / fm * 2.0 - 1.0;
        float s = dot(q, q);
        if (s >= 1.0) continue;
        vec3 t = vec3(q, sqrt(1.0 - s));
        float ct = dot(t, l);
        if (ct < cosb) continue;  // outside the bounding sphere's cap
        uint key = texel_key(d, (1.0 - ct) / max(1.0 - cosb, 1e-12), i);
        if (disk) {  // the ray must meet the disk's plane within its radius
            float den = dot(t, axis);
            float dist = abs(den) > 1e-6 ? plane / den : -1.0;
            vec3 x3 = dist * t - lc;
            float rr = dot(x3, x3);
            if (dist <= 0.0 || rr > a.r * a.r) continue;
            key = texel_key(dist, sqrt(rr) / max(a.r, 1e-12), i);
        }
        atomicMin(micro[base + uint(y * M + x)], key);
        hit = true;
    }
    if (!hit && l.z > 0.0) {
        ivec2 t = clamp(ivec2(floor((l.xy + 1.0) * 0.5 * fm)), ivec2(0), ivec2(M - 1));
        vec2 q = (vec2(t) + 0.5) / fm * 2.0 - 1.0;
        if (dot(q, q) < 1.0) atomicMin(micro[base + uint(t.y * M + t.x)], code);
    }
    return uint(cells);
}
