#version 430
// Other virtual objects: flat-coloured spheres.
uniform mat4 clip_from_world;
uniform vec4 sphere;        // centre xyz, radius
in vec3 in_position;        // unit sphere
void main() { gl_Position = clip_from_world * vec4(sphere.xyz + sphere.w * in_position, 1.0); }
