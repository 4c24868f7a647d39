#version 430
uniform vec3 color;
out vec4 frag;
void main() { frag = vec4(color, 1.0); }
