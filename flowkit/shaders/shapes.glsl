{# Built-in shape mapping functions f(s), s in [0, 1) increasing downstream; exact copies of
   flowkit/render/shapes.py (the tests compare rendered widths with those).  Only the shapes a
   style uses are emitted. #}
{% macro define(name) %}
{% if name == "dash" %}
float shape_dash(float s) { return s < {{ dash_on }} ? 1.0 : 0.0; }
{% elif name == "arrow" %}
float shape_arrow(float s) { return s < {{ arrow_head }} ? {{ arrow_shaft }} : (1.0 - s) / {{ 1.0 - arrow_head }}; }
{% elif name == "tadpole" %}
float shape_tadpole(float s) {
    float d = (s - 0.75) / 0.2;
    float head = sqrt(clamp(1.0 - d * d, 0.0, 1.0));
    return max(head, s < 0.75 ? 0.3 * s / 0.75 : 0.0);
}
{% elif name == "droplet" %}
float shape_droplet(float s) { float u = s / 0.9; return s < 0.9 ? sin(3.14159265 * u * u) : 0.0; }
{% elif name == "diamond" %}
float shape_diamond(float s) { return clamp(1.0 - abs(s - 0.5) / 0.45, 0.0, 1.0); }
{% elif name == "sine" %}
float shape_sine(float s) { return 0.5 + 0.5 * sin(6.28318531 * s); }
{% endif %}
{% endmacro %}
