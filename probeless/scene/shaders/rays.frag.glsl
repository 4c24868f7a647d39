#version 430
// Radiance along per-pixel camera rays: rotate each ray to the world and sample the environment cube.
uniform sampler2D rays;          // (H, W) RGB32F unit rays in the camera frame, zero = invalid
uniform samplerCube environment; // radiance seen from the camera centre (world-frame cube)
uniform mat3 world_from_camera;

out vec4 frag;

void main() {
    vec3 r = texelFetch(rays, ivec2(gl_FragCoord.xy), 0).xyz;
    frag = dot(r, r) < 0.25 ? vec4(0.0) : vec4(texture(environment, world_from_camera * r).rgb, 1.0);
}
