#version 430
// The dense model (points as splats, or a vertex-coloured mesh) seen by one cube face, colours + delta.
uniform mat4 clip_from_world;
uniform float splat_px_m;   // splat diameter [m] x focal length [px]: point size = splat_px_m / depth
uniform float max_px;
uniform vec3 delta;         // brightness change [camera LDR units]
uniform bool linear_hdr;    // colours are linear radiance (HDR, unbounded): not clamped to 1
in vec3 in_position;
in vec3 in_color;           // camera LDR units 0..1, or linear radiance >= 0 when linear_hdr
out vec3 v_color;
void main() {
    v_color = linear_hdr ? max(in_color + delta, 0.0) : clamp(in_color + delta, 0.0, 1.0);
    gl_Position = clip_from_world * vec4(in_position, 1.0);
    gl_PointSize = clamp(splat_px_m / max(gl_Position.w, 1e-4), 1.0, max_px);
}
