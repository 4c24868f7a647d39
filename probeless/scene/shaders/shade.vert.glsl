#version 430
// Scene surfaces for shading: world position, normal, uv, and the depth along the view axis.
uniform mat4 clip_from_world;
invariant gl_Position;  // the shading pass depth-tests against a pre-pass drawn with the shadow program
uniform vec4 depth_row;  // third row of view_from_world: z along the optical axis

in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;

out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
out float v_depth;

void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    v_depth = dot(depth_row, vec4(in_position, 1.0));
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
