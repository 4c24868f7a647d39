#version 430
// G-buffer of the virtual objects: position (w = 1 where covered), unit normal facing the camera, material
// (base colour, roughness; metalness, BRDF model, object index + 1), maps sampled by the mesh UVs.
in vec3 v_position;
in vec3 v_normal;
in vec2 v_uv;
layout(location = 0) out vec4 out_position;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_base;
layout(location = 3) out vec4 out_params;

uniform vec3 camera_position;
uniform vec3 base_color;
uniform float roughness;
uniform float metalness;
uniform int model;
uniform int object_index;
uniform bool has_base_map;
uniform bool has_roughness_map;
uniform bool has_metalness_map;
uniform sampler2D base_map;       // linear RGB
uniform sampler2D roughness_map;  // linear, red channel
uniform sampler2D metalness_map;

void main() {
    vec2 st = vec2(v_uv.x, 1.0 - v_uv.y);  // OBJ v runs up the image; texture rows run down
    vec3 n = normalize(v_normal);
    if (dot(n, camera_position - v_position) < 0.0) n = -n;  // back faces of open meshes
    vec3 base = has_base_map ? texture(base_map, st).rgb : base_color;
    float r = has_roughness_map ? texture(roughness_map, st).r : roughness;
    float m = has_metalness_map ? texture(metalness_map, st).r : metalness;
    out_position = vec4(v_position, 1.0);
    out_normal = vec4(n, 0.0);
    out_base = vec4(base, r);
    out_params = vec4(m, float(model), float(object_index + 1), 0.0);
}
