#version 430
// A splat is the front half of a sphere of radius v_radius_m around its point: inside the disk,
// the fragment depth is depth - radius * sqrt(1 - (d / r)^2), so where equal splats of one surface
// overlap, the one whose centre is nearest the pixel wins (a Voronoi tiling of the surface), and
// surfaces further apart than a radius occlude each other as they should. Depth is written
// linearly, (z - near) / (far - near), for an even precision over the range.
uniform float near;
uniform float far;
in vec3 v_color;
flat in int v_id;
flat in float v_depth;
flat in float v_radius_m;
flat in float v_radius_px;
flat in vec2 v_centre_px;
layout(location = 0) out vec4 out_color;
layout(location = 1) out int out_id;
layout(location = 2) out float out_depth;
void main() {
    float d = length(gl_FragCoord.xy - v_centre_px);
    if (d >= v_radius_px) discard;
    float q = d / v_radius_px;
    float z = v_depth - v_radius_m * sqrt(max(1.0 - q * q, 0.0));
    gl_FragDepth = clamp((z - near) / (far - near), 0.0, 1.0);
    out_color = vec4(v_color, 1.0);
    out_id = v_id;
    out_depth = v_depth;
}
