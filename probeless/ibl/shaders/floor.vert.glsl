#version 430
// The supporting plane, with the per-vertex shadow ratio (occluded / unoccluded irradiance, RGB).
uniform mat4 clip_from_world;
in vec3 in_position;
in vec3 in_ratio;
out vec3 v_ratio;
void main() {
    v_ratio = in_ratio;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
