#version 430
// The dense model (points as splats, or a vertex-coloured mesh) seen by one cube face, colours + delta.
// Points with a normal that face away from the eye or are seen nearly edge-on (n . v < min_facing) are
// clipped away: such splats would show surfaces the model cannot resolve (a box's sides seen through its
// missing top, as dark specks); a zero normal means unknown and is always drawn.
uniform mat4 clip_from_world;
uniform float splat_px_m;   // splat diameter [m] x focal length [px]: point size = splat_px_m / depth
uniform float max_px;
uniform vec3 delta;         // brightness change [camera LDR units]
uniform bool linear_hdr;    // colours are linear radiance (HDR, unbounded): not clamped to 1
uniform bool coverage;      // draw every point white (the observed mask)
uniform vec3 eye;           // the cube's centre [m, world]
uniform float min_facing;   // cosine below which a point with a normal is dropped
in vec3 in_position;
in vec3 in_color;           // camera LDR units 0..1, or linear radiance >= 0 when linear_hdr
in vec3 in_normal;          // unit normal [world], or 0 = unknown
out vec3 v_color;
void main() {
    v_color = coverage ? vec3(1.0) : (linear_hdr ? max(in_color + delta, 0.0) : clamp(in_color + delta, 0.0, 1.0));
    gl_Position = clip_from_world * vec4(in_position, 1.0);
    gl_PointSize = clamp(splat_px_m / max(gl_Position.w, 1e-4), 1.0, max_px);
    if (dot(in_normal, in_normal) > 0.25 && dot(normalize(in_normal), normalize(eye - in_position)) < min_facing) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // outside the clip volume: the point is not drawn
    }
}
