#version {{ glsl_version }}
// Apply the line style to the strip: find the band under the fragment from its lateral
// position, take the band's colour, push its depth back by the band's depth offset.
{% import "bands.glsl" as bands with context %}
uniform float u_scale;      // global width scale
{% if depth_offset %}
uniform mat4 u_proj;
{% endif %}
in float g_b;
in float g_z;
{% for k in range(n_attrs) %}
in float g_attr{{ k }};
{% endfor %}
out vec4 f_color;
{% for style in styles %}
{% for b in style %}
{{ bands.uniforms(b) }}
{%- endfor %}
{% endfor %}

{% for style in styles %}
{% set s = loop.index0 %}
// Line style {{ s }}: {{ style | length }} band(s).  False: the fragment lies outside the style.
bool style{{ s }}(float b, float fw, out vec4 color, out float depth) {
{% for band in style %}
    float e{{ loop.index0 }} = {% if not loop.first %}e{{ loop.index0 - 1 }} + {% endif %}u_scale * {{ bands.width_of(band) }};
{% endfor %}
{% set last = style | length - 1 %}
    if (b > e{{ last }}{% if smooth_edge %} + 0.5 * fw{% endif %}) return false;
{% for band in style %}
{% set i = loop.index0 %}
    {{ "} else " if not loop.first else "" }}if ({{ "true" if loop.last else "b <= e%d" % i }}) {
        color = {{ bands.color_of(band) }};
{% if smooth_bands and not loop.first %}
        color = mix(color, {{ bands.color_of(style[i - 1]) }}, clamp((e{{ i - 1 }} - b) / fw + 0.5, 0.0, 1.0));
{% endif %}
{% if smooth_bands and not loop.last %}
        color = mix(color, {{ bands.color_of(style[i + 1]) }}, clamp((b - e{{ i }}) / fw + 0.5, 0.0, 1.0));
{% endif %}
        depth = {{ "u_depth%d" % band.index if depth_offset else "0.0" }};
{% endfor %}
    }
{% if smooth_edge %}
    color.a *= clamp((e{{ last }} - b) / fw + 0.5, 0.0, 1.0);
{% endif %}
    return true;
}
{% endfor %}

void main() {
    float b = abs(g_b);
    float fw = max(fwidth(g_b), 1e-6);
    vec4 color;
    float depth;
    if (!style0(b, fw, color, depth)) discard;
{% if depth_offset %}
    // move the fragment `depth` view-space units away from the viewer; window depth from the
    // projection's z and w rows (valid for perspective and orthographic projections alike)
    float z = g_z - depth;
    float cz = u_proj[2][2] * z + u_proj[3][2];
    float cw = u_proj[2][3] * z + u_proj[3][3];
    gl_FragDepth = 0.5 * (gl_DepthRange.diff * (cz / cw)) + 0.5 * (gl_DepthRange.near + gl_DepthRange.far);
{% endif %}
    f_color = color;
}
