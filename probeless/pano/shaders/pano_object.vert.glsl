#version 430
// A virtual object in world coordinates (z up, the equirect frame).
uniform mat4 clip_from_world;
in vec3 in_position;
in vec3 in_normal;
out vec3 v_world;
out vec3 v_normal;
void main() {
    v_world = in_position;
    v_normal = in_normal;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
