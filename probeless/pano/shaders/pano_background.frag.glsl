#version 430
// Perspective view of the equirectangular frame (probeless.pano.view.view_equirect on the GPU):
// pixel (u, v) = gl_FragCoord - 0.5 (framebuffer row 0 = image row 0), ray = world_from_camera K^-1 (u, v, 1).
uniform sampler2D frame;        // the LDR (or HDR) 360 frame, repeat in u, clamp in v, bilinear
uniform mat3 world_from_pixel;  // R K^-1
layout(location = 0) out vec4 frag_color;

#include "equirect.glsl"

void main() {
    vec3 ray = world_from_pixel * vec3(gl_FragCoord.xy - 0.5, 1.0);
    frag_color = vec4(textureLod(frame, equirect_uv(ray), 0.0).rgb, 1.0);
}
