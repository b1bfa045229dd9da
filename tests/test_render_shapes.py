"""Shape mapping functions (paper 3.3): rendered band widths along a straight line follow
width x f(s), s = (x / l) mod 1, within a pixel; inner-band shapes move the outer bands; user
shapes are baked control points; the shader holds exactly the shapes used."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from line_probe import Probe, half_width
from render_scenes import style

from flowkit.render import Band, StyleError, load_style
from flowkit.render.shader_build import build_sources, shader_flags
from flowkit.render.shapes import CURVE_SIZE, SHAPE_NAMES, ShapeCurve, shape_function
from flowkit.render.style import Shape

BLACK, RED, WHITE = (0, 0, 0, 1), (1, 0, 0, 1), (1, 1, 1, 1)
W = 20.0  # band half-width in pixels
L = 0.5  # shape length in world units (arc length)
USER = ((0.0, 0.0), (0.3, 1.0), (0.3, 0.4), (0.8, 0.6), (1.0, 0.0))


def _profile(shape: Shape, n=201):
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n))
    img = p.render(style(Band(BLACK, W, shape=shape), background=WHITE, antialias="none"))
    cols = p.columns()
    s = np.mod(p.attr_at("arc_length", cols) / shape.length, 1.0)
    measured = np.array([half_width(img, c) for c in cols])
    return s, measured, shape_function(shape.name, shape.points)(s) * W


@pytest.mark.parametrize("name", SHAPE_NAMES + ("custom",))
def test_band_width_profile_matches_shape_function_within_a_pixel(name):
    shape = Shape(name, "arc_length", L, USER if name == "custom" else ())
    s, measured, want = _profile(shape)
    # the half-width counts whole pixels on each side: within one pixel of W f(s)
    err = np.abs(measured - want)
    assert err.max() <= 0.75 and err.mean() < 0.3, f"{name}: worst at s={s[err.argmax()]:.3f}: {measured[err.argmax()]} vs {want[err.argmax()]:.2f}"
    assert measured.max() >= W - 1 and (name == "arrow" or measured.min() <= 1 or name == "sine")
    assert len(np.unique(np.round(s, 2))) > 50  # the profile was sampled over whole periods


def test_arrow_profile_has_shaft_head_and_tip():
    s, measured, _ = _profile(Shape("arrow", "arc_length", L))
    shaft = measured[(s > 0.05) & (s < 0.4)]
    head = measured[(s > 0.46) & (s < 0.5)]
    tip = measured[s > 0.97]
    assert np.all(np.abs(shaft - 0.35 * W) <= 1.0)
    assert np.all(head >= W - 2) and np.all(tip <= 1.0)  # full width behind the head, tip ahead


def test_inner_band_shape_moves_outer_band():
    n = 201
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n))
    img = p.render(style(Band(BLACK, W, shape=Shape("diamond", "arc_length", L)), Band(RED, 5.0),
                         background=WHITE, antialias="none"))
    cols = p.columns()
    f = shape_function("diamond")(np.mod(p.attr_at("arc_length", cols) / L, 1.0))
    black = np.array([np.sum(np.all(img[:, c, :3] == (0, 0, 0), axis=1)) / 2 for c in cols])
    total = np.array([half_width(img, c) for c in cols])
    assert np.abs(black - W * f).max() <= 1.0
    assert np.abs(total - (W * f + 5.0)).max() <= 1.0  # the red band rides on the diamond


def test_user_shape_is_baked_piecewise_linear():
    curve = ShapeCurve(USER)
    baked = curve.baked()
    assert baked.shape == (CURVE_SIZE,) and baked.dtype == np.float32
    s = (np.arange(CURVE_SIZE) + 0.5) / CURVE_SIZE
    assert np.allclose(baked, np.interp(s, *np.array(USER).T), atol=1e-6)


def _frag(s):
    return build_sources(shader_flags(s, True))["fragment_shader"]


def test_shader_holds_exactly_the_shapes_used():
    plain = _frag(style(Band(BLACK, 2.0)))
    for word in ("shape_", "u_shapel", "u_curve", "u_phase", "fract("):
        assert word not in plain, word
    two = _frag(style(Band(BLACK, 2.0, shape=Shape("arrow", "time", 1.0)),
                      Band(RED, 1.0, shape=Shape("tadpole", "arc_length", 2.0)),
                      Band(WHITE, 1.0, shape=Shape("arrow", "arc_length", 3.0))))
    assert two.count("float shape_arrow(") == 1 and two.count("float shape_tadpole(") == 1
    for other in set(SHAPE_NAMES) - {"arrow", "tadpole"}:
        assert f"shape_{other}" not in two, other
    assert "u_curve" not in two and "sampler2D" not in two  # built-ins are code, no texture
    user = _frag(style(Band(BLACK, 2.0, shape=Shape("custom", "arc_length", 1.0, USER))))
    assert "uniform sampler2D u_curve0;" in user and "shape_" not in user
    # the same flags whatever the numbers: user points and lengths are uniforms/textures
    other = style(Band(BLACK, 3.0, shape=Shape("custom", "T", 7.0, ((0, 1), (1, 0)))))
    assert shader_flags(other, True) == shader_flags(
        style(Band(BLACK, 2.0, shape=Shape("custom", "arc_length", 1.0, USER))), True)


BAD = {
    "unknown": ('shape = { name = "star" }', ["shape.name = 'star'", "'arrow'", "points"]),
    "length": ('shape = { name = "arrow", length = 0 }', ["shape.length = 0", "> 0"]),
    "points_s": ('shape = { points = [[0, 0], [0.6, 1], [0.5, 0], [1, 0]] }',
                 ["shape.points[2][0] = 0.5", ">= the previous"]),
    "points_f": ('shape = { points = [[0, 0], [1, 1.5]] }', ["shape.points[1][1] = 1.5", "<= 1"]),
    "points_ends": ('shape = { points = [[0.1, 0], [1, 1]] }', ["shape.points", "s from 0 to 1"]),
    "builtin_points": ('shape = { name = "dash", points = [[0, 0], [1, 1]] }',
                       ["shape.name = 'dash'", "'custom'"]),
    "key": ('shape = { name = "dash", lenght = 2 }', ["unknown key 'lenght'", "length"]),
    "attr": ('shape = { name = "dash", attribute = "a b" }', ["shape.attribute = 'a b'"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_shape_gets_its_error(tmp_path, case):
    line, parts = BAD[case]
    path = tmp_path / "s.toml"
    path.write_text(f"version = 1\n[[bands]]\nwidth = 2\n{line}\n")
    with pytest.raises(StyleError) as e:
        load_style(path)
    for part in [str(path), "band 1", *parts]:
        assert part in str(e.value), f"{part!r} not in {e.value}"


def test_shape_from_toml(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('version = 1\n[[bands]]\nwidth = 2\nshape = { name = "arrow", attribute = '
                    '"time", length = 0.25 }\n[[bands]]\nshape = { points = [[0, 1], [1, 0]] }\n')
    s = load_style(path)
    a, b = s.line_style.bands
    assert a.shape == Shape("arrow", "time", 0.25)
    assert b.shape == Shape("custom", "arc_length", 1.0, ((0.0, 1.0), (1.0, 0.0)))
    assert s.attributes() == ["time", "arc_length"]


@pytest.mark.parametrize("name", SHAPE_NAMES)
def test_strip_narrowed_by_shapes_keeps_the_picture(name, monkeypatch):
    # with every vertex drawn (5 points per period, so each point's two segments cover part of
    # a period) the strip stage narrows the strip to the shapes' widest over each point's
    # segments; a halo band outside the shaped core is moved by it.  The picture is the one
    # drawn on the full-width strip, in both strip stages.
    from line_probe import CAM, SIZE

    from flowkit.render import LineRenderer, render_lines, renderer

    n = 41
    p = Probe(n=n, arc_length=np.linspace(0.0, 2.0, n))
    st = style(Band(BLACK, 8.0, shape=Shape(name, "arc_length", L)), Band(RED, 3.0),
               background=WHITE)
    src = build_sources(shader_flags(st, True))["vertex_shader"]
    assert f"shape_max_{name}" in src and "narrow_half" in src
    narrowed = {s: render_lines(p.lines, st, SIZE, CAM, strips=s) for s in ("vertex", "geometry")}
    with LineRenderer(p.lines, tolerance=0.0) as r:
        narrowed["every vertex"] = r.render(st, SIZE, CAM)
    flags = renderer.shader_flags
    monkeypatch.setattr(renderer, "shader_flags",
                        lambda *a, **k: dataclasses.replace(flags(*a, **k), narrow=False))
    with LineRenderer(p.lines, tolerance=0.0) as r:
        full = r.render(st, SIZE, CAM)
        assert not r.prepare(st)[0].narrow_bands
    assert np.any(full[..., 1] == 0) and np.any(full[..., 2] == 0)  # red halo and black core
    for k, img in narrowed.items():
        d = np.abs(img.astype(int) - full.astype(int)).max(axis=2)
        assert np.mean(d <= 2) > 0.999 and np.sum(d > 2) <= 10, (k, np.sum(d > 2))
