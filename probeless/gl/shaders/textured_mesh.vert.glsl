#version 430
// A textured mesh seen through clip_from_world (pinhole preview or one cube face): position + uv.
uniform mat4 clip_from_world;
in vec3 in_position;
in vec2 in_uv;
out vec2 v_uv;
void main() {
    v_uv = in_uv;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
