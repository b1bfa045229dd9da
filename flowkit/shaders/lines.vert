#version {{ glsl_version }}
// View-oriented strips without a geometry shader: each run of a line is one triangle strip with
// two vertices per kept point (side = gl_VertexID & 1).  The vertex gets the ids of its point and
// of the previous/next kept points (-1: none) as attributes and fetches their positions from
// u_points.  The side vector at a point depends only on the point and its neighbours, so the
// strip is continuous at joins (mitred, limit 2).
uniform sampler2D u_points;     // one texel per point: x, y, z
in int a_prev;
in int a_cur;
in int a_next;
{% for k in range(n_attrs) %}
uniform sampler2D u_attr{{ k }};  // attribute slot {{ k }}, one texel per point
out float g_attr{{ k }};
{% endfor %}
uniform mat4 u_view;
uniform mat4 u_proj;
uniform float u_half;       // strip half-width, style units (scale x widest style's total width)
uniform float u_pad;        // extra half-width in pixels: room for analytic edge smoothing
uniform float u_pixels;     // 1: style units are pixels, 0: world units
uniform vec2 u_px;          // world size of one pixel at view depth z: u_px.x * (-z) + u_px.y
uniform float u_persp;      // 1 perspective (view rays through the eye), 0 orthographic
out float g_b;              // signed lateral position, style units (0 on the centre line)
out float g_z;              // view-space z (for depth offsets)

ivec2 texel(int i) { return ivec2(i % {{ tex_width }}, i / {{ tex_width }}); }

vec3 safe_dir(vec3 v, vec3 fallback) {
    float n = length(v);
    return n > 1e-12 ? v / n : fallback;
}

// view-space position of point j, or `p` if there is none
vec3 neighbour(int j, vec3 p) {
    return j < 0 ? p : (u_view * vec4(texelFetch(u_points, texel(j), 0).xyz, 1.0)).xyz;
}

void main() {
    float sgn = (gl_VertexID & 1) == 0 ? 1.0 : -1.0;
    vec3 p = (u_view * vec4(texelFetch(u_points, texel(a_cur), 0).xyz, 1.0)).xyz;
    vec3 a = neighbour(a_prev, p), c = neighbour(a_next, p);
    vec3 e = normalize(mix(vec3(0.0, 0.0, 1.0), -p, u_persp));   // towards the viewer
    vec3 t_in = safe_dir(p - a, vec3(0.0)), t_out = safe_dir(c - p, vec3(0.0));
    vec3 t_seg = dot(t_in, t_in) > 0.0 ? t_in : safe_dir(t_out, vec3(1.0, 0.0, 0.0));
    vec3 t = safe_dir(t_in + t_out, t_seg);
    vec3 s_seg = safe_dir(cross(t_seg, e), vec3(1.0, 0.0, 0.0));
    vec3 s = safe_dir(cross(t, e), s_seg);
    s /= max(abs(dot(s, s_seg)), 0.5);  // mitre: the same for both segments (s bisects them)
    float px = u_px.x * (-p.z) + u_px.y;   // world size of a pixel at this depth
    float unit = mix(1.0, px, u_pixels);    // world size of one style unit
    float half_world = u_half * unit + u_pad * px;
    vec3 v = p + sgn * half_world * s;
    gl_Position = u_proj * vec4(v, 1.0);
    g_b = sgn * half_world / unit;
    g_z = v.z;
{% for k in range(n_attrs) %}
    g_attr{{ k }} = texelFetch(u_attr{{ k }}, texel(a_cur), 0).r;
{% endfor %}
}
