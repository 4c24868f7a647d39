#version 430
// Copies a rendered square face into one face of a cube texture (defines FORMAT: rgba32f | r32f).
layout(local_size_x = 8, local_size_y = 8) in;
layout(FORMAT, binding = 0) uniform writeonly imageCube cube;
uniform sampler2D face_image;
uniform int face;
uniform int size;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size || p.y >= size) return;
    imageStore(cube, ivec3(p, face), texelFetch(face_image, p, 0));
}
