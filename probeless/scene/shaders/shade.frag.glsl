#version 430
// Diffuse shading of probeless.scene.geometry: n x n point samples per area light, a cube shadow
// map per light, ambient, emissive panels. Defines: NUM_LIGHTS, LIGHT_SAMPLES.
// Two-sided lighting: the normal is flipped towards the eye, so single-sided geometry seen from
// behind is lit like its other side (and nothing is culled).
const float PI = 3.14159265358979;
const float EPS_D2 = 1e-4;  // inverse-square epsilon [m^2] (1 cm)

uniform vec3 eye;
uniform vec3 color;
uniform vec3 emission;       // already scaled by the panel's light
uniform int emissive;
uniform sampler2D albedo_tex;
uniform vec3 ambient;        // sum_i s_i ambient_i
uniform float shadow_texel;  // angular size of a shadow texel at a face centre [rad]

#if NUM_LIGHTS > 0
uniform vec3 light_center[NUM_LIGHTS];
uniform vec3 light_u[NUM_LIGHTS];       // half-extent vectors [m]
uniform vec3 light_v[NUM_LIGHTS];
uniform vec3 light_normal[NUM_LIGHTS];
uniform vec3 light_power[NUM_LIGHTS];   // s_i radiance_i area_i / n^2
uniform vec3 shadow_origin[NUM_LIGHTS];
uniform samplerCube shadow_maps[NUM_LIGHTS];  // distance to the nearest caster [m]
#endif

in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in float v_depth;
out vec4 frag;

#if NUM_LIGHTS > 0
float visibility(int i, vec3 x, vec3 n) {
    vec3 to_x = x - shadow_origin[i];
    float dist = length(to_x);
    float cos_t = max(dot(n, -to_x) / max(dist, 1e-6), 0.0);
    float tan_t = min(sqrt(max(1.0 - cos_t * cos_t, 0.0)) / max(cos_t, 1e-3), 20.0);
    float texel = dist * shadow_texel;
    // Normal offset by one texel footprint plus a slope-scaled bias keeps surfaces off their own map.
    vec3 lookup = to_x + n * texel;
    float bias = 0.002 + 1.5 * texel * tan_t;
    float caster = texture(shadow_maps[i], lookup).r;
    return length(lookup) - bias <= caster ? 1.0 : 0.0;
}
#endif

void main() {
    if (emissive == 1) {
        frag = vec4(emission, v_depth);
        return;
    }
    vec3 albedo = color * texture(albedo_tex, v_uv).rgb;
    vec3 n = normalize(v_normal);
    if (dot(n, eye - v_world) < 0.0) n = -n;
    vec3 irradiance = vec3(0.0);
#if NUM_LIGHTS > 0
    for (int i = 0; i < NUM_LIGHTS; ++i) {
        if (all(equal(light_power[i], vec3(0.0)))) continue;
        if (visibility(i, v_world, n) == 0.0) continue;
        float geom = 0.0;
        for (int a = 0; a < LIGHT_SAMPLES; ++a) {
            for (int b = 0; b < LIGHT_SAMPLES; ++b) {
                vec2 g = (vec2(a, b) + 0.5) * (2.0 / LIGHT_SAMPLES) - 1.0;
                vec3 d = light_center[i] + g.x * light_u[i] + g.y * light_v[i] - v_world;
                float d2 = dot(d, d);
                float inv = inversesqrt(max(d2, 1e-12));
                float cos_l = max(-dot(light_normal[i], d) * inv, 0.0);
                float cos_s = max(dot(n, d) * inv, 0.0);
                geom += cos_l * cos_s / max(d2, EPS_D2);
            }
        }
        irradiance += light_power[i] * geom;
    }
#endif
    frag = vec4(albedo / PI * irradiance + albedo * ambient, v_depth);
}
