#version 430
// Unlighted point splats with ids (paper 001, section 4.1): each point a round splat of world radius
// radius_scale * spacing, its screen size falling with distance; the point id is gl_VertexID
// (with an index buffer: the index, i.e. the point's row in the vertex buffer).
uniform mat4 clip_from_world;
uniform mat4 camera_from_world;  // rows: camera axes; camera z = depth along the optical axis [m]
uniform float focal_px;          // splat radius [px] = radius [m] * focal_px / depth
uniform float radius_scale;
uniform float max_px;            // largest point size drawn [px]
uniform vec2 viewport;           // (width, height) [px]
in vec3 in_position;
in vec3 in_color;
in float in_spacing;
out vec3 v_color;
flat out int v_id;
flat out float v_depth;          // the point's depth [m]
flat out float v_radius_m;       // the splat's world radius [m]
flat out float v_radius_px;      // its screen radius [px], at least the half-diagonal of a pixel
flat out vec2 v_centre_px;       // its centre in window coordinates [px]
void main() {
    v_color = in_color;
    v_id = gl_VertexID + 1;      // 0 = background
    gl_Position = clip_from_world * vec4(in_position, 1.0);
    v_depth = (camera_from_world * vec4(in_position, 1.0)).z;
    v_radius_m = radius_scale * in_spacing;
    float r = v_radius_m * focal_px / max(v_depth, 1e-6);
    v_radius_px = max(r, 0.7072);
    v_centre_px = (gl_Position.xy / gl_Position.w * 0.5 + 0.5) * viewport;
    gl_PointSize = clamp(2.0 * v_radius_px + 2.0, 1.0, max_px);
}
