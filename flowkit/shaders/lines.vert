#version {{ glsl_version }}
{% import "strip.glsl" as strip with context %}
{% set vertex_strips = strip_stage == "vertex" %}
{% if vertex_strips %}
// View-oriented strips without a geometry shader: each run of a line is one triangle strip with
// two vertices per kept point (side = gl_VertexID & 1).  The vertex gets the ids of its point and
// of the previous/next kept points (-1: none) as attributes and fetches their positions from
// u_points.
{% else %}
// One drawn point for lines.geom (lines_adjacency), which builds the strips: its view-space
// position, whether it exists (id -1: no neighbour there) and its attributes.
{% endif %}
uniform sampler2D u_points;     // one texel per point: x, y, z, arc length from its run's start
uniform mat4 u_view;
{% if vertex_strips %}
in int a_prev;
{% endif %}
in int a_cur;
{% if vertex_strips %}
in int a_next;
{% if hermite %}
out float g_s;                  // arc parameter (the attributes' interpolation parameter)
flat out vec2 g_seg;            // the segment ending at this point: its start's arc, 1 / arc length
{% endif %}
{% else %}
out vec3 vs_view;
out float vs_valid;
out float vs_s;
{% endif %}
{% for k in range(n_attrs) %}
uniform sampler2D u_attr{{ k }};  // attribute slot {{ k }}, one texel per point: value, slope
{% if vertex_strips %}
out float v_attr{{ k }};          // its value here
{% if k in hermite %}
flat out vec2 g_h{{ k }};         // its cubic's terms on the segment ending here (hermite_terms)
{% endif %}
{% else %}
out vec2 vs_attr{{ k }};
{% endif %}
{% endfor %}
{% if vertex_strips %}
{{ strip.code() }}
{% endif %}

ivec2 texel(int i) { return ivec2(i % {{ tex_width }}, i / {{ tex_width }}); }

vec4 point_texel(int j) { return texelFetch(u_points, texel(j), 0); }
vec3 to_view(vec3 x) { return (u_view * vec4(x, 1.0)).xyz; }
{% if vertex_strips %}

{% set around_slots = [transfer_attr] if transfer else narrow_slots %}

void main() {
    vec4 tc = point_texel(a_cur);
    vec4 ta = a_prev < 0 ? tc : point_texel(a_prev);
    vec3 p = to_view(tc.xyz);
    vec3 a = a_prev < 0 ? p : to_view(ta.xyz);
    vec3 c = a_next < 0 ? p : to_view(point_texel(a_next).xyz);
    // attribute slots (value, slope) here and at the previous point
{% for k in range(n_attrs) %}
    vec2 x{{ k }} = texelFetch(u_attr{{ k }}, texel(a_cur), 0).rg;
{% if k in hermite or k in around_slots %}
    vec2 xa{{ k }} = a_prev < 0 ? x{{ k }} : texelFetch(u_attr{{ k }}, texel(a_prev), 0).rg;
{% endif %}
{% endfor %}
{% for k in around_slots %}
    // slot {{ k }} at the previous point, this one and the next (the point's two segments)
    vec3 around{{ k }} = vec3(xa{{ k }}.x, x{{ k }}.x, a_next < 0 ? x{{ k }}.x : texelFetch(u_attr{{ k }}, texel(a_next), 0).r);
{% endfor %}
{% if transfer %}
    float hw = strip_half(around{{ transfer_attr }}.x, around{{ transfer_attr }}.y, around{{ transfer_attr }}.z);
{% elif narrow_bands %}
    float hw = narrow_half({% for k in narrow_slots %}around{{ k }}{{ ", " if not loop.last else "" }}{% endfor %});
{% else %}
    float hw = u_half;
{% endif %}
    strip_vertex(p, strip_offset(a, p, c, hw), (gl_VertexID & 1) == 0 ? 1.0 : -1.0);
{% for k in range(n_attrs) %}
    v_attr{{ k }} = x{{ k }}.x;
{% endfor %}
{% if hermite %}
    // this point provokes the two triangles of the segment from the previous one (flat values
    // come from a triangle's last vertex), so it hands the fragments that segment's terms
    float L = tc.w - ta.w;
    g_s = tc.w;
    g_seg = vec2(ta.w, L > 0.0 ? 1.0 / L : 0.0);
{% for k in hermite %}
    g_h{{ k }} = hermite_terms(xa{{ k }}, x{{ k }}, L);
{% endfor %}
{% endif %}
}
{% else %}

void main() {
    int j = max(a_cur, 0);
    vec4 t = point_texel(j);
    vs_view = to_view(t.xyz);
    vs_s = t.w;
    vs_valid = a_cur < 0 ? 0.0 : 1.0;
{% for k in range(n_attrs) %}
    vs_attr{{ k }} = texelFetch(u_attr{{ k }}, texel(j), 0).rg;
{% endfor %}
}
{% endif %}
