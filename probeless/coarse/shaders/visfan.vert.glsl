#version 430
// The 2-D visibility polygon as a triangle fan, drawn into the floor-space mask.
in vec2 in_xy;           // floor point [m, world]
uniform vec2 mask_min;   // world (x, y) of the mask's corner at texture coordinate (0, 0) [m]
uniform vec2 mask_size;  // world extent covered by the mask [m]
void main() {
    gl_Position = vec4((in_xy - mask_min) / mask_size * 2.0 - 1.0, 0.0, 1.0);
}
