#version 430
uniform bool round_splats;
in vec3 v_color;
out vec4 frag;
void main() {
    if (round_splats && length(gl_PointCoord - vec2(0.5)) > 0.5) discard;
    frag = vec4(v_color, 1.0);
}
