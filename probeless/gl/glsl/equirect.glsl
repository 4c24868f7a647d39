// The probeless.pano.equirect convention: z up, v = polar angle from +z / pi (row 0 = zenith), u = longitude
// phi / 2 pi with phi measured from +x towards -y (clockwise seen from above, as real panoramas, Blender and
// Mitsuba: turning right moves right in the image).

// (u, v) in [0, 1)^2 of direction d on an equirectangular image.
vec2 equirect_uv(vec3 d) {
    d = normalize(d);
    float phi = (abs(d.x) + abs(d.y) > 1e-12) ? atan(-d.y, d.x) : 0.0;
    float u = phi / 6.28318530717959;
    return vec2(u - floor(u), acos(clamp(d.z, -1.0, 1.0)) / 3.14159265358979);
}

// Unit direction at polar angle t (from +z) and longitude phi (= u * 2 pi) [rad].
vec3 equirect_direction(float t, float phi) {
    float s = sin(t);
    return vec3(s * cos(phi), -s * sin(phi), cos(t));
}
