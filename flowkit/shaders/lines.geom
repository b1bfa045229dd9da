#version {{ glsl_version }}
// Segment p1-p2 with neighbours p0, p3 (lines_adjacency) -> view-oriented strip.  The strip's
// side vector at a vertex depends only on that vertex and its neighbours, so consecutive
// segments share their edge: joins are continuous (mitred, limit 2).
layout(lines_adjacency) in;
layout(triangle_strip, max_vertices = 4) out;

uniform mat4 u_proj;
uniform float u_half;       // strip half-width, style units (scale x widest style's total width)
uniform float u_pixels;     // 1: style units are pixels, 0: world units
uniform vec2 u_px;          // world size of one pixel at view depth z: u_px.x * (-z) + u_px.y
uniform float u_persp;      // 1 perspective (view rays through the eye), 0 orthographic

in vec3 vs_view[];
{% for k in range(n_attrs) %}
in float vs_attr{{ k }}[];
out float g_attr{{ k }};
{% endfor %}
out float g_b;              // signed lateral position, style units (0 on the centre line)
out float g_z;              // view-space z of the fragment (for depth offsets)

vec3 to_eye(vec3 p) {       // unit vector from p towards the viewer
    return normalize(mix(vec3(0.0, 0.0, 1.0), -p, u_persp));
}

vec3 safe_dir(vec3 v, vec3 fallback) {
    float n = length(v);
    return n > 1e-12 ? v / n : fallback;
}

// Offset of vertex p (neighbours a before, c after) for a strip of half-width 1 world unit.
vec3 side(vec3 a, vec3 p, vec3 c, vec3 seg) {
    vec3 e = to_eye(p);
    vec3 t_in = safe_dir(p - a, seg), t_out = safe_dir(c - p, seg);
    vec3 t = safe_dir(t_in + t_out, seg);
    vec3 s = safe_dir(cross(t, e), safe_dir(cross(seg, e), vec3(1.0, 0.0, 0.0)));
    vec3 s_seg = safe_dir(cross(seg, e), s);
    return s / max(abs(dot(s, s_seg)), 0.5);   // mitre: keep the width normal to each segment
}

float world_half(vec3 p) {
    return u_half * mix(1.0, u_px.x * (-p.z) + u_px.y, u_pixels);
}

void emit(vec3 p, vec3 off, float sgn, int k) {
    vec3 q = p + sgn * off;
    gl_Position = u_proj * vec4(q, 1.0);
    g_b = sgn * u_half;
    g_z = q.z;
{% for k in range(n_attrs) %}
    g_attr{{ k }} = vs_attr{{ k }}[k];
{% endfor %}
    EmitVertex();
}

void main() {
    vec3 p0 = vs_view[0], p1 = vs_view[1], p2 = vs_view[2], p3 = vs_view[3];
    vec3 seg = safe_dir(p2 - p1, vec3(1.0, 0.0, 0.0));
    vec3 o1 = side(p0, p1, p2, seg) * world_half(p1);
    vec3 o2 = side(p1, p2, p3, seg) * world_half(p2);
    emit(p1, o1, 1.0, 1);
    emit(p1, o1, -1.0, 1);
    emit(p2, o2, 1.0, 2);
    emit(p2, o2, -1.0, 2);
    EndPrimitive();
}
