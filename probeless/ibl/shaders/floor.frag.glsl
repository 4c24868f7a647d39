#version 430
in vec3 v_ratio;
out vec4 frag;
void main() { frag = vec4(clamp(v_ratio, 0.0, 1.0), 1.0); }
