#version {{ glsl_version }}
// Apply the line style to the strip: pick the line style (transfer function), find the band
// under the fragment from its lateral position and the bands' (shaped) widths, take the band's
// colour (or colour pattern), push its depth back by the band's depth offset.
{% import "bands.glsl" as bands with context %}
uniform float u_scale;      // global width scale
{% if depth_offset %}
uniform mat4 u_proj;
{% endif %}
{% if uses_phase %}
uniform float u_phase;      // added to every shape's and pattern's s (animation), in periods
{% endif %}
{% for r in transfer %}
uniform vec2 u_tf{{ loop.index0 }};        // transfer range {{ loop.index0 }}: [x, y)
{% endfor %}
{% if transfer_blend %}
uniform float u_tfblend;    // half-width of the colour blend zone around a bound
{% endif %}
in float g_b;
in float g_z;
{% if hermite %}
in float g_s;               // arc parameter along the line
flat in vec2 g_seg;         // this segment: arc at its start, 1 / its arc length
{% endif %}
{% for k in range(n_attrs) %}
in float v_attr{{ k }};       // attribute slot {{ k }} interpolated linearly,
{% if k in hermite %}
flat in vec2 g_h{{ k }};      // its cubic's terms on this segment,
{% endif %}
float g_attr{{ k }};          // its value here, set first thing in main()
{% endfor %}
out vec4 f_color;
{% for style in styles %}
{% for b in style %}
{{ bands.uniforms(b) }}
{%- endfor %}
{% endfor %}
{% if pattern_slots %}
float fw_b;                 // screen derivatives, taken in main() (uniform control flow)
{% for k in pattern_slots %}
float fw_attr{{ k }};
{% endfor %}

// fraction of a pixel footprint [u - fu/2, u + fu/2] where fract(u) >= w (box-filtered stripes)
float pattern_ramp(float u, float w) { return floor(u) * (1.0 - w) + max(fract(u) - w, 0.0); }
float pattern_coverage(float u, float fu, float w) {
    float h = 0.5 * max(fu, 1e-5);
    return clamp((pattern_ramp(u + h, w) - pattern_ramp(u - h, w)) / (2.0 * h), 0.0, 1.0);
}
{% endif %}
{% for name in shapes %}
{{ shape_sources[name] }}
{%- endfor %}
{% for style in styles %}
{% for b in style %}
{{ bands.functions(b) }}
{%- endfor %}
{% endfor %}

{% for style in styles %}
{% set s = loop.index0 %}
// Line style {{ s }}: {{ style | length }} band(s).  False: the fragment lies outside the style.
bool style{{ s }}(float b, float fw, out vec4 color, out float depth) {
{% for band in style %}
    float e{{ loop.index0 }} = {% if not loop.first %}e{{ loop.index0 - 1 }} + {% endif %}band{{ band.index }}_width();
{% endfor %}
{% set last = style | length - 1 %}
    if (b > e{{ last }}{% if smooth_edge %} + 0.5 * fw{% endif %}) return false;
{% if smooth_bands and style | length > 1 %}
    // every band's colour once, at the fragment's lateral position clamped to the band (a
    // software rasterizer runs both sides of a branch, so "only near a boundary" saves nothing)
{% for band in style %}
{% set i = loop.index0 %}
{% set lo = "0.0" if loop.first else "e%d" % (i - 1) %}
    vec4 c{{ i }} = band{{ band.index }}_color(clamp((b - {{ lo }}) / max(e{{ i }} - {{ lo }}, 1e-6), 0.0, 1.0), e{{ i }} - {{ lo }});
{% endfor %}
{% endif %}
{% for band in style %}
{% set i = loop.index0 %}
{% set lo = "0.0" if loop.first else "e%d" % (i - 1) %}
    {{ "} else " if not loop.first else "" }}if ({{ "true" if loop.last else "b <= e%d" % i }}) {
{% if smooth_bands and style | length > 1 %}
        color = c{{ i }};
{% else %}
        color = band{{ band.index }}_color((b - {{ lo }}) / max(e{{ i }} - {{ lo }}, 1e-6), e{{ i }} - {{ lo }});
{% endif %}
{% if smooth_bands and not loop.first %}
        // within half a pixel of a band boundary: blend with the neighbour
        if (b < e{{ i - 1 }} + 0.5 * fw) color = mix(color, c{{ i - 1 }}, clamp((e{{ i - 1 }} - b) / fw + 0.5, 0.0, 1.0));
{% endif %}
{% if smooth_bands and not loop.last %}
        if (b > e{{ i }} - 0.5 * fw) color = mix(color, c{{ i + 1 }}, clamp((b - e{{ i }}) / fw + 0.5, 0.0, 1.0));
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
{% if hermite %}
    // attributes: cubic Hermite along the arc between the drawn points (what the level of
    // detail measures its errors against), not only the rasterizer's linear interpolation
    // (kept for slots that are linear along the arc)
    float u = clamp((g_s - g_seg.x) * g_seg.y, 0.0, 1.0);
{% endif %}
{% for k in range(n_attrs) %}
    g_attr{{ k }} = v_attr{{ k }}{% if k in hermite %} + u * (1.0 - u) * ((1.0 - u) * g_h{{ k }}.x + u * g_h{{ k }}.y){% endif %};
{% endfor %}
    float b = abs(g_b);
    float fw = max(fwidth(g_b), 1e-6);
{% if pattern_slots %}
    fw_b = fw;
{% for k in pattern_slots %}
    fw_attr{{ k }} = fwidth(g_attr{{ k }});
{% endfor %}
{% endif %}
    vec4 color;
    float depth;
{% if transfer %}
    // line style transfer function: the attribute's range picks the whole line style.  Each
    // drawn style is evaluated once, before the ranges (which a software rasterizer would
    // otherwise evaluate in every branch, blends included)
{% for style in styles %}
    vec4 sc{{ loop.index0 }};
    float sd{{ loop.index0 }};
    bool si{{ loop.index0 }} = style{{ loop.index0 }}(b, fw, sc{{ loop.index0 }}, sd{{ loop.index0 }});
{% endfor %}
    float tv = g_attr{{ transfer_attr }};
{% for r in transfer %}
{% set i = loop.index0 %}
    {{ "else " if not loop.first else "" }}if (tv >= u_tf{{ i }}.x && tv < u_tf{{ i }}.y) {
{% if r.style < 0 %}
        discard;  // a range without a style is not drawn
{% else %}
        if (!si{{ r.style }}) discard;
        color = sc{{ r.style }};
        depth = sd{{ r.style }};
{% for nb, t in [(r.prev, "1.0 - smoothstep(u_tf%d.x - u_tfblend, u_tf%d.x + u_tfblend, tv)" % (i, i)), (r.next, "smoothstep(u_tf%d.y - u_tfblend, u_tf%d.y + u_tfblend, tv)" % (i, i))] %}
{% if nb >= 0 %}
        // blend the colour towards the adjacent range's style near the common bound
        if (si{{ nb }}) color = mix(color, sc{{ nb }}, {{ t }});
{% endif %}
{% endfor %}
{% endif %}
    }
{% endfor %}
    else discard;  // in no range
{% else %}
    if (!style0(b, fw, color, depth)) discard;
{% endif %}
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
