#version 430
// G-buffer of the virtual objects (paper 001 §5.2): world position, normal and UV per vertex.
uniform mat4 clip_from_world;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
out vec3 v_position;
out vec3 v_normal;
out vec2 v_uv;

void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
