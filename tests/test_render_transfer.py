"""Line style transfer functions (paper 4): per fragment, an attribute's range picks a whole
named line style; a range without a style is not drawn; the strip is as wide as the widest
drawn style; the shader holds exactly the styles drawn."""

from __future__ import annotations

import numpy as np
import pytest
from line_probe import Probe, half_width

from flowkit.render import Band, LineStyle, Style, StyleError, load_style
from flowkit.render.shader_build import build_sources, shader_flags
from flowkit.render.style import Shape, Transfer, TransferRange

RED, BLUE, WHITE = (1, 0, 0, 1), (0, 0, 1, 1), (1, 1, 1, 1)
INF = float("inf")
STYLES = {"focus": LineStyle((Band(RED, 8.0),)),
          "context": LineStyle((Band(BLUE, 2.0),)),
          "unused": LineStyle((Band(WHITE, 30.0, shape=Shape("droplet", "q", 1.0)),))}


def tf_style(ranges, blend=0.0, **kw):
    return Style(styles=STYLES, transfer=Transfer("v", tuple(TransferRange(r, s) for r, s in ranges),
                                                  blend), background=WHITE, **kw)


def _line(n=41):
    # v = x^2 + x on [-1, 1]: non-linear, so the bound falls between vertices
    x = np.linspace(-1.0, 1.0, n)
    return Probe(n=n, v=x * x + x)


def _switch_columns(img, p, colour):
    cols = p.columns(margin=2)
    has = np.array([np.all(img[int(p.centre), c, :3] == np.array(colour[:3]) * 255) for c in cols])
    return cols[has]


@pytest.mark.parametrize("bound", [0.25, 0.9])
def test_style_switches_where_attribute_crosses_the_bound(bound):
    p = _line()
    img = p.render(tf_style([((-INF, bound), "focus"), ((bound, INF), "context")],
                            antialias="none"))
    red, blue = _switch_columns(img, p, RED), _switch_columns(img, p, BLUE)
    assert red.size and blue.size and red.max() < blue.min()
    # where v crosses the bound on the line: x^2 + x = bound
    x_cross = (-1 + np.sqrt(1 + 4 * bound)) / 2
    col_cross = p.c0 + (x_cross + 1) * p.px_per_world
    spacing_px = 2.0 / 40 * p.px_per_world  # one vertex spacing in pixels
    switch = 0.5 * (red.max() + 1 + blue.min())  # the boundary between the last red, first blue
    assert abs(switch - col_cross) <= spacing_px
    assert abs(switch - col_cross) <= 1.0  # per-fragment: in fact within a pixel
    # each side has its whole style: the focus is 16 px wide, the context 4 px
    assert half_width(img, int(red.min()) + 3) == 8.0 and half_width(img, int(blue.max()) - 3) == 2.0


def test_range_without_style_and_values_outside_all_ranges_are_not_drawn():
    p = _line()
    img = p.render(tf_style([((-INF, 0.0), "focus"), ((0.0, 0.8), None), ((1.2, 2.5), "context")],
                            antialias="none"))
    v = p.attr_at("v", p.columns())
    drawn = np.array([half_width(img, c) > 0 for c in p.columns()])
    inside = v < 0.0 - 0.05
    gap = ((v > 0.05) & (v < 0.75)) | ((v > 0.85) & (v < 1.15)) | (v > 2.55)
    assert np.all(drawn[inside]) and not np.any(drawn[gap])
    assert np.any(drawn[(v > 1.25) & (v < 2.45)])


def test_strip_is_as_wide_as_widest_drawn_style_and_only_drawn_styles_compile():
    s = tf_style([((-INF, 0.3), "focus"), ((0.3, INF), "context")])
    assert s.used_styles() == ["focus", "context"] and s.max_total_width == 8.0
    assert s.attributes() == ["v"]  # 'q' of the undrawn style is neither traced nor uploaded
    frag = build_sources(shader_flags(s, True))["fragment_shader"]
    assert "bool style0(" in frag and "bool style1(" in frag and "bool style2(" not in frag
    assert "shape_droplet" not in frag and "u_width2" not in frag  # the unused style's band
    assert "u_width0" in frag and "u_width1" in frag and frag.count("u_tf") >= 2
    only = Style(styles=STYLES, transfer=Transfer("v", (TransferRange((0, 1), "unused"),)))
    frag = build_sources(shader_flags(only, True))["fragment_shader"]
    assert "shape_droplet" in frag and "u_width0" not in frag and "bool style1(" not in frag
    assert only.max_total_width == 30.0
    # no transfer function: the first style only
    plain = build_sources(shader_flags(Style(styles=STYLES), True))["fragment_shader"]
    assert "u_tf" not in plain and "bool style1(" not in plain and "tv" not in plain
    # bounds are uniforms: moving them keeps the program
    moved = tf_style([((-INF, 0.7), "focus"), ((0.7, INF), "context")])
    assert shader_flags(moved, True) == shader_flags(s, True)
    # the strip stage narrows the strip to the widest style the point's ranges draw (context
    # styles and discarded stretches rasterize fewer fragments); only with a transfer function
    for stage in ("vertex", "geometry"):
        src = build_sources(shader_flags(s, True, stage))
        strip = src["geometry_shader" if stage == "geometry" else "vertex_shader"]
        assert "float strip_half(" in strip and "u_tfhalf1" in strip and "u_tfhalf2" not in strip
        assert "strip_half" not in build_sources(shader_flags(Style(styles=STYLES), True,
                                                              stage))["vertex_shader"]


def test_blend_mixes_colours_across_the_bound():
    p = _line()
    s = tf_style([((-INF, 0.25), "focus"), ((0.25, INF), "context")], blend=0.3,
                 antialias="none")
    frag = build_sources(shader_flags(s, True))["fragment_shader"]
    assert "smoothstep" in frag and "u_tfblend" in frag
    img = p.render(s)
    row = img[int(p.centre), :, :3].astype(int)
    cols = p.columns()
    v = p.attr_at("v", cols)
    near = cols[np.abs(v - 0.25) < 0.04]
    assert near.size and np.all((row[near, 0] > 60) & (row[near, 2] > 60))  # red and blue mixed
    far = cols[v < -0.2]
    assert np.all(row[far] == (255, 0, 0))


BAD = {
    "style": ('[[transfer.ranges]]\nrange = [0, 1]\nstyle = "nope"\n',
              ["range 1", "style = 'nope'", "'a'"]),
    "order": ('[[transfer.ranges]]\nrange = [1, 0]\nstyle = "a"\n', ["range = [1, 0]", "low < high"]),
    "overlap": (('[[transfer.ranges]]\nrange = [0, 1]\nstyle = "a"\n[[transfer.ranges]]\n'
                 'range = [0.5, 2]\nstyle = "b"\n'), ["range 2", "does not overlap range 1"]),
    "no_style": ('[[transfer.ranges]]\nrange = [0, 1]\n', ["at least one range that names"]),
    "attr": ('[[transfer.ranges]]\nrange = [0, 1]\nstyle = "a"\n', ["missing key 'attribute'"]),
    "blend": ('blend = -1\n[[transfer.ranges]]\nrange = [0, 1]\nstyle = "a"\n', ["blend = -1"]),
    "key": ('colour = 1\n[[transfer.ranges]]\nrange = [0, 1]\nstyle = "a"\n',
            ["unknown key 'colour'"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_transfer_gets_its_error(tmp_path, case):
    text, parts = BAD[case]
    head = ("version = 1\n[styles.a]\n[[styles.a.bands]]\nwidth = 2\n[styles.b]\n"
            "[[styles.b.bands]]\nwidth = 1\n[transfer]\n")
    if case != "attr":
        head += 'attribute = "v"\n'
    path = tmp_path / "t.toml"
    path.write_text(head + text)
    with pytest.raises(StyleError) as e:
        load_style(path)
    for part in [str(path), "[transfer]", *parts]:
        assert part in str(e.value), f"{part!r} not in {e.value}"


def test_transfer_from_toml_with_open_ranges(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text('version = 1\n[styles.a]\n[[styles.a.bands]]\nwidth = 2\n[styles.b]\n'
                    '[[styles.b.bands]]\nwidth = 1\n[transfer]\nattribute = "v"\nblend = 0.1\n'
                    '[[transfer.ranges]]\nrange = [-inf, 0]\nstyle = "b"\n'
                    '[[transfer.ranges]]\nrange = [0, inf]\nstyle = "a"\n')
    s = load_style(path)
    assert s.transfer == Transfer("v", (TransferRange((-INF, 0), "b"), TransferRange((0, INF), "a")),
                                  0.1)
    assert s.used_styles() == ["b", "a"]
