{# The view-oriented strip, shared by both strip stages (lines.vert with strip_stage "vertex",
   lines.geom with "geometry"): uniforms, the mitred side offset at a point from its drawn
   neighbours, and the placement of one strip vertex.  Whichever stage builds the strip
   includes this once; the other stage holds none of it. #}
{% macro code() %}
uniform mat4 u_proj;
uniform float u_half;       // strip half-width, style units (scale x widest style's total width)
{% if transfer %}
{% for r in transfer %}
uniform vec2 u_tf{{ loop.index0 }};        // transfer range {{ loop.index0 }}: [x, y)
uniform float u_tfhalf{{ loop.index0 }};   // half-width of the style it draws (0: none)
{% endfor %}
uniform float u_tfblend;    // half-width of the colour blend zone around a bound
{% endif %}
uniform float u_pad;        // extra half-width in pixels: room for analytic edge smoothing
uniform float u_pixels;     // 1: style units are pixels, 0: world units
uniform vec2 u_px;          // world size of one pixel at view depth z: u_px.x * (-z) + u_px.y
uniform float u_persp;      // 1 perspective (view rays through the eye), 0 orthographic
out float g_b;              // signed lateral position, style units (0 on the centre line)
out float g_z;              // view-space z (for depth offsets)

vec3 safe_dir(vec3 v, vec3 fallback) {
    float n = length(v);
    return n > 1e-12 ? v / n : fallback;
}

{% if transfer %}
// Strip half-width (style units) at a point whose adjacent segments carry transfer values
// between those of the previous point, the point and the next: the widest style that a range
// met by them (blend zones included) draws; 0 where every such range discards.  The fragments
// of narrow context styles and of discarded stretches are then never rasterized.
float strip_half(float ta, float t, float tc) {
    float lo = min(min(ta, t), tc), hi = max(max(ta, t), tc);
    if (isnan(lo) || isnan(hi)) return u_half;
    float h = 0.0;
{% for r in transfer %}
{% set i = loop.index0 %}
    if (hi >= u_tf{{ i }}.x - u_tfblend && lo < u_tf{{ i }}.y + u_tfblend) h = max(h, u_tfhalf{{ i }});
{% endfor %}
    return h;
}
{% endif %}
{% if narrow_bands %}
uniform float u_scale;
uniform float u_phase;
{% for b in narrow_bands %}
{% if b.width == "map" %}
uniform vec4 u_wmap{{ b.index }};
{% else %}
uniform float u_width{{ b.index }};
{% endif %}
{% if b.shape not in ("none", "custom") %}
uniform float u_shapel{{ b.index }};
{% endif %}
{% endfor %}
{% for name in shapes %}
{{ shape_sources[name] }}
// largest shape_{{ name }}(s) for s = x / l + phase, x between the values in r (the point's and
// its neighbours': its two segments), widened by 1/1000 period against rounding
float shape_max_{{ name }}(vec3 r, float inv_l) {
    float a = min(min(r.x, r.y), r.z) * inv_l + u_phase - 1e-3;
    float b = max(max(r.x, r.y), r.z) * inv_l + u_phase + 1e-3;
    if (!(b - a < 1.0)) return 1.0;  // a whole period (or NaN)
    float fa = fract(a), fb = fa + (b - a);
    float m = max(shape_{{ name }}(fa), shape_{{ name }}(fract(b)));
{% for p in peaks[name] %}
    if ((fa <= {{ p }} && {{ p }} <= fb) || {{ p + 1.0 }} <= fb) m = max(m, shape_{{ name }}({{ p }}));
{% endfor %}
    return m;
}
{% endfor %}

// Strip half-width (style units) at a point: every band at its widest over the point's two
// segments (shapes at their largest f there), so the fragments the shapes leave empty are
// mostly never rasterized.  x<k>: attribute slot k at the previous point, the point, the next.
float narrow_half({% for k in narrow_slots %}vec3 x{{ k }}{{ ", " if not loop.last else "" }}{% endfor %}) {
    float h = 0.0;
{% for b in narrow_bands %}
{% set g = b.index %}
    h += {{ "max(u_wmap%d.z, u_wmap%d.w)" % (g, g) if b.width == "map" else "u_width%d" % g }}{% if b.shape not in ("none", "custom") %} * shape_max_{{ b.shape }}(x{{ b.shape_attr }}, u_shapel{{ g }}){% endif %};
{% endfor %}
    return u_scale * h;
}
{% endif %}

// Offset from view-space point p to the strip's + edge (xyz) and that half-width in style units
// (w), for a strip `hw` style units wide on each side.  a, c: the previous and next drawn
// points, equal to p where there is none.  The offset depends only on the point and its
// neighbours, so the strips of consecutive segments share their edge: joins are continuous
// (mitred, limit 2).
vec4 strip_offset(vec3 a, vec3 p, vec3 c, float hw) {
    vec3 e = normalize(mix(vec3(0.0, 0.0, 1.0), -p, u_persp));   // towards the viewer
    vec3 t_in = safe_dir(p - a, vec3(0.0)), t_out = safe_dir(c - p, vec3(0.0));
    vec3 t_seg = dot(t_in, t_in) > 0.0 ? t_in : safe_dir(t_out, vec3(1.0, 0.0, 0.0));
    vec3 t = safe_dir(t_in + t_out, t_seg);
    vec3 s_seg = safe_dir(cross(t_seg, e), vec3(1.0, 0.0, 0.0));
    vec3 s = safe_dir(cross(t, e), s_seg);
    s /= max(abs(dot(s, s_seg)), 0.5);  // mitre: the same for both segments (s bisects them)
    float px = u_px.x * (-p.z) + u_px.y;   // world size of a pixel at this depth
    float unit = mix(1.0, px, u_pixels);    // world size of one style unit
    float half_world = hw > 0.0 ? hw * unit + u_pad * px : 0.0;
    return vec4(half_world * s, half_world / unit);
}

// An attribute's cubic Hermite terms on a segment from (value, slope) a to b, L arc-length units
// long: a fragment at fraction u of the segment adds u (1 - u) ((1 - u) x + u y) to the linear
// interpolant, which then meets both values and both slopes.  The slopes are first limited as
// Fritsch-Carlson do (simplify._end_terms), so that the cubic is monotone on the segment and
// never leaves its end values (the strip widths assume that)
vec2 hermite_terms(vec2 a, vec2 b, float L) {
    float d = b.x - a.x;
    if (d == 0.0) return vec2(0.0);
    vec2 k = max(vec2(a.y, b.y) * (L / d), 0.0);
    float r = dot(k, k);
    if (r > 9.0) k *= 3.0 / sqrt(r);
    return vec2((k.x - 1.0) * d, (1.0 - k.y) * d);
}

// One strip vertex: p moved to side sgn (+1 / -1) by `off` (from strip_offset)
void strip_vertex(vec3 p, vec4 off, float sgn) {
    vec3 v = p + sgn * off.xyz;
    gl_Position = u_proj * vec4(v, 1.0);
    g_b = sgn * off.w;
    g_z = v.z;
}
{% endmacro %}
