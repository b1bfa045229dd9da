{# Per-band code, one macro per visual property.  Issue-6 features hook in here: a shape
   multiplies width_of(), a colour pattern chooses inside color_of(). #}
{% macro uniforms(b) %}
{% if b.color == "cmap" %}
uniform sampler2D u_cmap{{ b.index }};     // colormap LUT ({{ lut_size }} x 1)
uniform vec2 u_crange{{ b.index }};        // t = attr * x + y maps the range to [0, 1]
{% else %}
uniform vec4 u_color{{ b.index }};
{% endif %}
{% if b.width == "map" %}
uniform vec4 u_wmap{{ b.index }};          // t = clamp(attr * x + y); width = mix(z, w, t)
{% else %}
uniform float u_width{{ b.index }};
{% endif %}
{% if depth_offset %}
uniform float u_depth{{ b.index }};
{% endif %}
{% endmacro %}

{% macro width_of(b) -%}
{% if b.width == "map" -%}
mix(u_wmap{{ b.index }}.z, u_wmap{{ b.index }}.w, clamp(g_attr{{ b.width_attr }} * u_wmap{{ b.index }}.x + u_wmap{{ b.index }}.y, 0.0, 1.0))
{%- else -%}
u_width{{ b.index }}
{%- endif %}
{%- endmacro %}

{% macro color_of(b) -%}
{% if b.color == "cmap" -%}
texture(u_cmap{{ b.index }}, vec2(clamp(g_attr{{ b.color_attr }} * u_crange{{ b.index }}.x + u_crange{{ b.index }}.y, 0.0, 1.0) * {{ (lut_size - 1) / lut_size }} + {{ 0.5 / lut_size }}, 0.5))
{%- else -%}
u_color{{ b.index }}
{%- endif %}
{%- endmacro %}
