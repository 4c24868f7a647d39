#version 430
// One iteration of the Mipmapped / Hybrid PBGI traversal (paper 001 §5.2.1–5.2.2, Figure 7) over
// (node, G-buffer pixel) pairs; compute shaders with append buffers stand in for the geometry shader and
// transform feedback. For each live pair (conservative culling with the pixel's cone first):
//   level > 0: refine the node (two pairs) while it subtends more than the pixel's normal cone and than the
//              splat threshold, seen from the far side of the pixel (so every level-0 pixel below would refine it
//              too: the cut equals Classic's); in Hybrid only while it also subtends at least omega_tr;
//              otherwise refine the pixel (one pair per non-empty child pixel);
//   level 0:   Mipmapped: splat, or refine the node as Classic does; Hybrid: hand the pair to Classic.
layout(local_size_x = 64) in;
#include "pbgi_common.glsl"

layout(std430, binding = 3) readonly buffer PairsIn { uvec2 pairs_in[]; };
layout(std430, binding = 4) writeonly buffer PairsOut { uvec2 pairs_out[]; };
layout(std430, binding = 5) writeonly buffer PairsClassic { uvec2 pairs_classic[]; };
layout(std430, binding = 6) buffer Counters { uint n_out; uint n_classic; };

uniform uint n_pairs;
uniform uint pair_offset;
uniform uint cap_out;        // capacity of pairs_out / pairs_classic [pairs]; more is counted, not written
uniform uint cap_classic;
uniform bool hybrid;
uniform float omega_tr;      // Hybrid: node refinement in the mipmapped phase stops below this [sr]

// One atomicAdd per invocation, not per pair: the counter is the one contended word.
void emit_children(uvec2 pr, uint right) {
    uint k = atomicAdd(n_out, 2u);
    if (k + 1u < cap_out) {
        pairs_out[k] = uvec2(pr.x + 1u, pr.y);
        pairs_out[k + 1u] = uvec2(right, pr.y);
    }
}

void emit_pixels(uint node, uint first, uint count) {
    uint k = atomicAdd(n_out, count);
    for (uint c = 0u; c < count; ++c) {
        if (k + c < cap_out) pairs_out[k + c] = uvec2(node, first + c);
    }
}

void main() {
    uint k = pair_offset + gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;
    if (k >= n_pairs) return;
    uvec2 pr = pairs_in[k];
    Node a = nodes[pr.x];
    GPixel g = gpix[pr.y];
    vec3 p = vec3(g.px, g.py, g.pz);
    vec3 n = vec3(g.nx, g.ny, g.nz);
    if (culled(a, p, g.rho, n, vec2(cos(g.gamma), sin(g.gamma)))) return;
    bool inner = a.right != NO_CHILD;
    float d = length(node_center(a) - p);
    if (g.level > 0u) {
        float om = node_solid_angle(d + g.rho, a.r);
        bool refine = inner && om > max(solid_angle_of_cone(g.gamma), omega_stop) && (!hybrid || om >= omega_tr);
        if (refine) emit_children(pr, a.right);
        else emit_pixels(pr.x, g.first, g.count);
        return;
    }
    if (hybrid) {
        uint j = atomicAdd(n_classic, 1u);
        if (j < cap_classic) pairs_classic[j] = pr;
    } else if (inner && subtends_more(d, a.r, omega_k(omega_stop))) {
        emit_children(pr, a.right);
    } else {
        splat(g.slot, p, mb_frame(n), pr.x);
    }
}
