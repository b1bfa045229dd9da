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
uniform sampler2D u_points;     // one texel per point: x, y, z
uniform mat4 u_view;
{% if vertex_strips %}
in int a_prev;
{% endif %}
in int a_cur;
{% if vertex_strips %}
in int a_next;
{% else %}
out vec3 vs_view;
out float vs_valid;
{% endif %}
{% set attr_out = "g_attr" if vertex_strips else "vs_attr" %}
{% for k in range(n_attrs) %}
uniform sampler2D u_attr{{ k }};  // attribute slot {{ k }}, one texel per point
out float {{ attr_out }}{{ k }};
{% endfor %}
{% if vertex_strips %}
{{ strip.code() }}
{% endif %}

ivec2 texel(int i) { return ivec2(i % {{ tex_width }}, i / {{ tex_width }}); }

vec3 view_point(int j) { return (u_view * vec4(texelFetch(u_points, texel(j), 0).xyz, 1.0)).xyz; }
{% if vertex_strips %}

// view-space position of point j, or `p` if there is none
vec3 neighbour(int j, vec3 p) { return j < 0 ? p : view_point(j); }

{% if transfer or narrow_bands %}
// attribute value of point j, or `v` if there is none
float neighbour_value(sampler2D attr, int j, float v) {
    return j < 0 ? v : texelFetch(attr, texel(j), 0).r;
}

// slot k's values at the previous point, this one and the next
{% for k in ([transfer_attr] if transfer else narrow_slots) %}
vec3 around{{ k }}() {
    float v = texelFetch(u_attr{{ k }}, texel(a_cur), 0).r;
    return vec3(neighbour_value(u_attr{{ k }}, a_prev, v), v, neighbour_value(u_attr{{ k }}, a_next, v));
}
{% endfor %}
{% endif %}

void main() {
    vec3 p = view_point(a_cur);
{% if transfer %}
    vec3 t = around{{ transfer_attr }}();
    float hw = strip_half(t.x, t.y, t.z);
{% elif narrow_bands %}
    float hw = narrow_half({% for k in narrow_slots %}around{{ k }}(){{ ", " if not loop.last else "" }}{% endfor %});
{% else %}
    float hw = u_half;
{% endif %}
    strip_vertex(p, strip_offset(neighbour(a_prev, p), p, neighbour(a_next, p), hw),
                 (gl_VertexID & 1) == 0 ? 1.0 : -1.0);
{% for k in range(n_attrs) %}
    g_attr{{ k }} = texelFetch(u_attr{{ k }}, texel(a_cur), 0).r;
{% endfor %}
}
{% else %}

void main() {
    int j = max(a_cur, 0);
    vs_view = view_point(j);
    vs_valid = a_cur < 0 ? 0.0 : 1.0;
{% for k in range(n_attrs) %}
    vs_attr{{ k }} = texelFetch(u_attr{{ k }}, texel(j), 0).r;
{% endfor %}
}
{% endif %}
