#version {{ glsl_version }}
// Positions to view space; attributes pass through (only those the style reads).
uniform mat4 u_view;
in vec3 a_pos;
{% for k in range(n_attrs) %}
in float a_attr{{ k }};
out float vs_attr{{ k }};
{% endfor %}
out vec3 vs_view;

void main() {
    vs_view = (u_view * vec4(a_pos, 1.0)).xyz;
{% for k in range(n_attrs) %}
    vs_attr{{ k }} = a_attr{{ k }};
{% endfor %}
}
