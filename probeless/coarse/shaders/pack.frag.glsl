#version 430
// The float atlas as RGBA8 for publishing: rgb clamped to [0, 1]; a = 1 where observed directly.
uniform sampler2D atlas;
out vec4 packed_texel;
void main() {
    vec4 t = texelFetch(atlas, ivec2(gl_FragCoord.xy), 0);
    packed_texel = vec4(clamp(t.rgb, 0.0, 1.0), t.a >= 0.0 ? 1.0 : 0.0);
}
