#version 430
uniform sampler2D atlas;  // uploaded bottom row first, so OpenGL uvs (v up) address it
in vec2 v_uv;
out vec4 frag;
void main() { frag = vec4(texture(atlas, v_uv).rgb, 1.0); }
