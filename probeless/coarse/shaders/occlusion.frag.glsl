#version 430
// Atlas-space occlusion mask (paper 4.4): a texel is visible when its floor point lies in the
// visibility polygon (the floor-space mask). Wall texels are tested a little inside the room.
uniform sampler2D positions;   // RGBA32F: xyz world [m], w = surface index (-1 = none)
uniform sampler2D normals;     // RGBA32F: xyz inward unit normal
uniform sampler2D floor_mask;  // R8: 1 inside the visibility polygon
uniform vec2 mask_min;
uniform vec2 mask_size;
uniform float offset_m;        // how far inside the room wall texels are tested [m]
out float visible;
void main() {
    ivec2 ij = ivec2(gl_FragCoord.xy);
    vec4 p = texelFetch(positions, ij, 0);
    if (p.w < 0.0) { visible = 0.0; return; }
    vec2 q = p.xy + texelFetch(normals, ij, 0).xy * offset_m;
    visible = texture(floor_mask, (q - mask_min) / mask_size).r > 0.5 ? 1.0 : 0.0;
}
