#version 430
// A virtual object in world coordinates; in_prt = shadowed PRT radiance per vertex (T . L, linear).
uniform mat4 clip_from_world;
uniform mat4 camera_from_world;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_prt;
out vec3 v_world;
out vec3 v_normal;
out vec3 v_prt;
out float v_depth;
void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_prt = in_prt;
    v_depth = (camera_from_world * vec4(in_position, 1.0)).z;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
