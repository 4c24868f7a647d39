// (u, v) in [0, 1)^2 of direction d on an equirectangular image: u = azimuth atan2(y, x) / 2 pi
// (wrapped), v = polar angle from +z / pi (the probeless.pano convention).
vec2 equirect_uv(vec3 d) {
    d = normalize(d);
    float phi = (abs(d.x) + abs(d.y) > 1e-12) ? atan(d.y, d.x) : 0.0;
    float u = phi / 6.28318530717959;
    return vec2(u - floor(u), acos(clamp(d.z, -1.0, 1.0)) / 3.14159265358979);
}
