#version 430
// The textured coarse model seen by one cube face.
uniform mat4 clip_from_world;
in vec3 in_position;
in vec2 in_uv;
out vec2 v_uv;
void main() {
    v_uv = in_uv;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
