#version 430
// Stores the distance from the shadow origin to the nearest caster [m].
uniform vec3 origin;

in vec3 v_world;
out float distance_m;

void main() {
    distance_m = length(v_world - origin);
}
