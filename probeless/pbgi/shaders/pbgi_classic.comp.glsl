#version 430
// Classic PBGI (Ritschel et al. 2009; paper 001 §5.2): one invocation per (node, level-0 pixel) pair walks the
// node's sub-tree depth-first without a stack (bsh.traverse), refining while the node's solid angle exceeds
// omega_stop, culling what cannot be seen and splatting the cut into the pixel's micro-buffer.
// Classic runs it with (root, pixel) for every pixel (implicit_root); Hybrid with the pairs its mipmapped
// phase hands over.
//
// The walk is resumable: llvmpipe ends any shader invocation after 65535 loop iterations in all (Mesa's
// LP_MAX_TGSI_LOOP_ITERATIONS, a hang guard), so a walk stops after work_cap units of work (a visit or a splat
// texel), stores where it is in walk[k] and counts itself in n_unfinished; the host dispatches again until
// every walk is done. walk[k] = MB_EMPTY: not started.
layout(local_size_x = 64) in;
#include "pbgi_common.glsl"

layout(std430, binding = 3) readonly buffer Pairs { uvec2 pairs[]; };
layout(std430, binding = 6) buffer Counters { uint n_unfinished; uint unused; };
layout(std430, binding = 7) buffer Walks { uint walk[]; };

uniform uint n_pairs;
uniform bool implicit_root;   // pair k = (0, pixel_first + k) instead of pairs[k]
uniform uint pixel_first;
uniform uint work_cap;

void main() {
    uint k = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;
    if (k >= n_pairs) return;
    uvec2 pr = implicit_root ? uvec2(0u, pixel_first + k) : pairs[k];
    uint end = nodes[pr.x].skip;
    uint i = walk[k] == MB_EMPTY ? pr.x : walk[k];
    if (i >= end) return;
    GPixel g = gpix[pr.y];
    vec3 p = vec3(g.px, g.py, g.pz);
    vec3 n = vec3(g.nx, g.ny, g.nz);
    mat3 f = mb_frame(n);
    float k_stop = omega_k(omega_stop);
    uint work = 0u;
    while (i < end && work < work_cap) {
        Node a = nodes[i];
        work += 1u;
        if (culled(a, p, 0.0, n, vec2(1.0, 0.0))) { i = a.skip; continue; }
        if (a.right != NO_CHILD && subtends_more(length(node_center(a) - p), a.r, k_stop)) { i += 1u; continue; }
        work += splat(g.slot, p, f, i);
        i = a.skip;
    }
    walk[k] = i;
    if (i < end) atomicAdd(n_unfinished, 1u);
}
