{# Per-band code: the band's uniforms and two functions, band<g>_width() (the band's width on one
   side, times its shape) and band<g>_color(lat, bw) (its colour, or its directional colour
   pattern, at lateral position lat in 0..1 across the band of width bw).  <g> is the band's
   global number; attribute slots come from the flags, never names. #}
{% macro color_uniforms(kind, prefix, g) %}
{% if kind == "cmap" %}
uniform sampler2D u_{{ prefix }}cmap{{ g }};     // colormap, {{ cmap_texels }} texels (nearest)
uniform vec2 u_{{ prefix }}crange{{ g }};        // t = attr * x + y maps the range to [0, 1]
{% else %}
uniform vec4 u_{{ prefix }}color{{ g }};
{% endif %}
{% endmacro %}

{% macro uniforms(b) %}
{{ color_uniforms(b.color, "", b.index) }}
{%- if b.width == "map" %}
uniform vec4 u_wmap{{ b.index }};          // t = clamp(attr * x + y); width = mix(z, w, t)
{% else %}
uniform float u_width{{ b.index }};
{% endif %}
{% if depth_offset %}
uniform float u_depth{{ b.index }};
{% endif %}
{% if b.shape != "none" %}
uniform float u_shapel{{ b.index }};       // 1 / shape length
{% endif %}
{% if b.shape == "custom" %}
uniform sampler2D u_curve{{ b.index }};    // user shape f(s), {{ curve_size }} texels, repeating
{% endif %}
{% if b.pattern %}
uniform vec4 u_pat{{ b.index }};           // 1 / length, slope a, curve c, fraction w
{{ color_uniforms(b.pattern_color, "p", b.index) }}
{%- endif %}
{% endmacro %}

{% macro color_value(kind, prefix, g, slot) -%}
{% if kind == "cmap" -%}
texture(u_{{ prefix }}cmap{{ g }}, vec2(clamp(g_attr{{ slot }} * u_{{ prefix }}crange{{ g }}.x + u_{{ prefix }}crange{{ g }}.y, 0.0, 1.0) * {{ (cmap_texels - 1) / cmap_texels }} + {{ 0.5 / cmap_texels }}, 0.5))
{%- else -%}
u_{{ prefix }}color{{ g }}
{%- endif %}
{%- endmacro %}

{% macro functions(b) %}
{% set g = b.index %}
float band{{ g }}_width() {
{% if b.width == "map" %}
    float w = mix(u_wmap{{ g }}.z, u_wmap{{ g }}.w, clamp(g_attr{{ b.width_attr }} * u_wmap{{ g }}.x + u_wmap{{ g }}.y, 0.0, 1.0));
{% else %}
    float w = u_width{{ g }};
{% endif %}
{% if b.shape == "custom" %}
    w *= texture(u_curve{{ g }}, vec2(fract(g_attr{{ b.shape_attr }} * u_shapel{{ g }} + u_phase), 0.5)).r;
{% elif b.shape != "none" %}
    w *= shape_{{ b.shape }}(fract(g_attr{{ b.shape_attr }} * u_shapel{{ g }} + u_phase));
{% endif %}
    return u_scale * w;
}

vec4 band{{ g }}_color(float lat, float bw) {
{% if b.pattern %}
    // f_d = ((x / l + a lat^c) mod 1) - w: own colour where f_d < 0, the second where >= 0
    // (the lateral term is compiled only as far as a and c need: a pow costs every fragment)
    vec4 p = u_pat{{ g }};
{% if b.pattern_lateral == "none" %}
    float u = g_attr{{ b.pattern_attr }} * p.x + u_phase;
    float fu = fw_attr{{ b.pattern_attr }} * p.x;
{% else %}
    float u = g_attr{{ b.pattern_attr }} * p.x + p.y * {{ "clamp(lat, 0.0, 1.0)" if b.pattern_lateral == "linear" else "pow(clamp(lat, 0.0, 1.0), p.z)" }} + u_phase;
    float fu = fw_attr{{ b.pattern_attr }} * p.x + abs(p.y) * fw_b / max(bw, 1e-6);
{% endif %}
    return mix({{ color_value(b.color, "", g, b.color_attr) }}, {{ color_value(b.pattern_color, "p", g, b.pattern_color_attr) }}, pattern_coverage(u, fu, p.w));
{% else %}
    return {{ color_value(b.color, "", g, b.color_attr) }};
{% endif %}
}
{% endmacro %}
