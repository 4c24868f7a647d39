#version 430
// Texture update (paper 4.3): every atlas texel is projected into the fisheye frame; visible texels
// take the fisheye colour and the frame time, the others keep their value plus the brightness
// change delta (paper 4.6). The fisheye is the runtime model: an ideal unified-sphere (omnidir) camera.
uniform sampler2D positions;   // RGBA32F: xyz world [m], w = surface index (-1 = none)
uniform sampler2D previous;    // RGBA32F atlas: rgb camera LDR units [0..1], a = last seen [s] (-1 = never)
uniform sampler2D occlusion;   // R8 atlas-space: 1 = visible from the fisheye's floor position
uniform sampler2D fisheye;     // RGB8 undistorted fisheye frame, row 0 = image top
uniform mat4 fisheye_from_world;
uniform mat3 K;                // fisheye camera matrix (column-major as GLSL expects)
uniform float xi;              // unified-sphere offset
uniform float cos_half_fov;    // cos(fov / 2): texels further from the optical axis are out of view
uniform vec2 image_size;       // fisheye (width, height) [px]
uniform vec3 delta;            // brightness change for texels this frame does not update
uniform float t_s;             // this frame's time [s]
out vec4 texel;
void main() {
    ivec2 ij = ivec2(gl_FragCoord.xy);
    vec4 old = texelFetch(previous, ij, 0);
    vec4 p = texelFetch(positions, ij, 0);
    if (p.w < 0.0) { texel = old; return; }
    vec3 c = (fisheye_from_world * vec4(p.xyz, 1.0)).xyz;
    vec3 s = normalize(c);
    bool seen = s.z >= cos_half_fov && texelFetch(occlusion, ij, 0).r > 0.5;
    vec3 px = K * vec3(s.xy / (s.z + xi), 1.0);
    seen = seen && px.x >= -0.5 && px.y >= -0.5 && px.x <= image_size.x - 0.5 && px.y <= image_size.y - 0.5;
    if (seen) {
        texel = vec4(texture(fisheye, (px.xy + 0.5) / image_size).rgb, t_s);
    } else {
        texel = vec4(old.rgb + delta, old.a);
    }
}
