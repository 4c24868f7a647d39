// Unpolarised Fresnel reflectance from a medium of index 1 into index eta2 (1 = total reflection).
float fresnel(float cos_i, float eta2) {
    float sin_t2 = (1.0 - cos_i * cos_i) / (eta2 * eta2);
    if (sin_t2 >= 1.0) return 1.0;
    float cos_t = sqrt(1.0 - sin_t2);
    float rs = (cos_i - eta2 * cos_t) / (cos_i + eta2 * cos_t);
    float rp = (eta2 * cos_i - cos_t) / (eta2 * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}
