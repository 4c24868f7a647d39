#version 430
// Perspective view of the equirectangular frame (probeless.pano.view.view_equirect on the GPU):
// pixel (u, v) = gl_FragCoord - 0.5 (framebuffer row 0 = image row 0), ray = world_from_camera K^-1 (u, v, 1).
const float PI = 3.14159265358979;
uniform sampler2D frame;        // the LDR (or HDR) 360 frame, repeat in u, clamp in v, bilinear
uniform mat3 world_from_pixel;  // R K^-1
layout(location = 0) out vec4 frag_color;

vec2 equirect_uv(vec3 d) {
    d = normalize(d);
    float phi = (abs(d.x) + abs(d.y) > 1e-12) ? atan(d.y, d.x) : 0.0;
    float u = phi / (2.0 * PI);
    return vec2(u - floor(u), acos(clamp(d.z, -1.0, 1.0)) / PI);
}

void main() {
    vec3 ray = world_from_pixel * vec3(gl_FragCoord.xy - 0.5, 1.0);
    frag_color = vec4(textureLod(frame, equirect_uv(ray), 0.0).rgb, 1.0);
}
