#version 430
// Shadow caster pass (world position to one cube face of a light's shadow map) and depth pre-pass.
uniform mat4 clip_from_world;
invariant gl_Position;  // also the depth pre-pass of shading: must match shade.vert.glsl bit for bit

in vec3 in_position;
out vec3 v_world;

void main() {
    v_world = in_position;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
