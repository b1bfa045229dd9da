#version {{ glsl_version }}
// View-oriented strips from a geometry shader: segment p1-p2 with its drawn neighbours p0, p3
// (lines_adjacency; a missing neighbour has vs_valid 0) becomes a quad of the same strip that
// the vertex-stage path draws, with the same offsets at p1 and p2 (strip.glsl), so joins are
// continuous.
{% import "strip.glsl" as strip with context %}
layout(lines_adjacency) in;
layout(triangle_strip, max_vertices = 4) out;
in vec3 vs_view[];
in float vs_valid[];
in float vs_s[];
{% if hermite %}
out float g_s;
flat out vec2 g_seg;
{% endif %}
{% for k in range(n_attrs) %}
in vec2 vs_attr{{ k }}[];
out float v_attr{{ k }};
{% if k in hermite %}
flat out vec2 g_h{{ k }};
{% endif %}
{% endfor %}
{{ strip.code() }}

// the segment's Hermite terms, the same for its four vertices (see lines.vert)
float L = 0.0;
{% for k in hermite %}
vec2 h{{ k }};
{% endfor %}

void end_vertex(vec3 p, vec4 off, float sgn, int i) {
    strip_vertex(p, off, sgn);
{% for k in range(n_attrs) %}
    v_attr{{ k }} = vs_attr{{ k }}[i].x;
{% endfor %}
{% if hermite %}
    g_s = vs_s[i];
    g_seg = vec2(vs_s[1], L > 0.0 ? 1.0 / L : 0.0);
{% for k in hermite %}
    g_h{{ k }} = h{{ k }};
{% endfor %}
{% endif %}
    EmitVertex();
}

void main() {
    vec3 p1 = vs_view[1], p2 = vs_view[2];
    vec3 p0 = vs_valid[0] > 0.5 ? vs_view[0] : p1;
    vec3 p3 = vs_valid[3] > 0.5 ? vs_view[3] : p2;
    L = vs_s[2] - vs_s[1];
{% for k in hermite %}
    h{{ k }} = hermite_terms(vs_attr{{ k }}[1], vs_attr{{ k }}[2], L);
{% endfor %}
{% if transfer %}
{% set t = "vs_attr%d" % transfer_attr %}
    float t1 = {{ t }}[1].x, t2 = {{ t }}[2].x;
    float t0 = vs_valid[0] > 0.5 ? {{ t }}[0].x : t1, t3 = vs_valid[3] > 0.5 ? {{ t }}[3].x : t2;
    vec4 o1 = strip_offset(p0, p1, p2, strip_half(t0, t1, t2));
    vec4 o2 = strip_offset(p1, p2, p3, strip_half(t1, t2, t3));
{% elif narrow_bands %}
{% for k in narrow_slots %}
    float x{{ k }}1 = vs_attr{{ k }}[1].x, x{{ k }}2 = vs_attr{{ k }}[2].x;
    float x{{ k }}0 = vs_valid[0] > 0.5 ? vs_attr{{ k }}[0].x : x{{ k }}1;
    float x{{ k }}3 = vs_valid[3] > 0.5 ? vs_attr{{ k }}[3].x : x{{ k }}2;
{% endfor %}
    vec4 o1 = strip_offset(p0, p1, p2, narrow_half({% for k in narrow_slots %}vec3(x{{ k }}0, x{{ k }}1, x{{ k }}2){{ ", " if not loop.last else "" }}{% endfor %}));
    vec4 o2 = strip_offset(p1, p2, p3, narrow_half({% for k in narrow_slots %}vec3(x{{ k }}1, x{{ k }}2, x{{ k }}3){{ ", " if not loop.last else "" }}{% endfor %}));
{% else %}
    vec4 o1 = strip_offset(p0, p1, p2, u_half), o2 = strip_offset(p1, p2, p3, u_half);
{% endif %}
    end_vertex(p1, o1, 1.0, 1);
    end_vertex(p1, o1, -1.0, 1);
    end_vertex(p2, o2, 1.0, 2);
    end_vertex(p2, o2, -1.0, 2);
    EndPrimitive();
}
