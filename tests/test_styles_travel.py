"""Styles that travel: lengths relative to the scene, ranges from the data, every shipped style
drawing alike on a dataset and on a copy 100 times larger (and 50 K warmer), and the gallery
readable on a tall, thin buoyant cavity it was not made for."""

from __future__ import annotations

import dataclasses
import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest
from render_scenes import FACE_ON, straight, style

from flowkit import trace
from flowkit.fields.analytic import ABCFlow
from flowkit.fields.field import Field
from flowkit.fields.grid import Grid
from flowkit.integrate import seeds
from flowkit.lines import Lines
from flowkit.render import Band, LineRenderer, StyleError, load_style
from flowkit.render.lengths import SceneScale, parse, resolve_lengths
from flowkit.render.ranges import fixed_ranges
from flowkit.render.renderer import default_style
from flowkit.render.style import ColorMap, WidthMap, style_from_dict
from flowkit.scene.model import load_scene

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("make_gallery", ROOT / "scripts" / "make_gallery.py")
make_gallery = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_gallery)

SIZE = (240, 135)
ATTRS = ("speed", "T", "time", "arc_length", "distance_to_seed")


def example_styles() -> dict[str, object]:
    """Every style under examples/: the style files and the scene's (referenced or inline);
    and what ``flowkit render`` draws without a style."""
    out = {p.relative_to(ROOT).as_posix(): load_style(p)
           for p in sorted((ROOT / "examples").rglob("*.toml")) if "[field]" not in p.read_text()}
    out["no --style"] = default_style(["speed"])
    for p in sorted((ROOT / "examples").glob("*scene*.toml")):
        for name, s in load_scene(p).styles.items():
            out[f"{p.name}:{name}"] = s
    return out


def cavity() -> Field:
    """A tall, thin buoyant cavity (0.076 x 2.18 x 0.52 m, y up): one convection roll in the
    y-z plane, slower near the side walls, speeds to 0.28 m/s, T 288..308 K rising upwards."""
    L = np.array([0.076, 2.18, 0.52])
    x, y, z = (np.linspace(0, L[i], n) for i, n in enumerate((7, 44, 14)))
    X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
    walls = 0.3 + 0.7 * np.sin(np.pi * X / L[0])
    a = 0.28 * L[2] / np.pi
    v = np.stack([0.01 * np.sin(2 * np.pi * Y / L[1]) * np.sin(np.pi * X / L[0]),
                  walls * a * np.pi / L[2] * np.sin(np.pi * Y / L[1]) * np.cos(np.pi * Z / L[2]),
                  -walls * a * np.pi / L[1] * np.cos(np.pi * Y / L[1]) * np.sin(np.pi * Z / L[2])],
                 axis=-1)
    T = 288.0 + 20.0 * Y / L[1] + 0.5 * np.sin(np.pi * Z / L[2])
    return Field(Grid.from_axes(x, y, z), v, {"T": T}, units={"U": "m/s", "T": "K"},
                 length_units="m", source="cavity")


@pytest.fixture(scope="module")
def cavity_lines() -> Lines:
    return trace(cavity(), seeds.box((0.012, 0.15, 0.05), (0.064, 2.03, 0.47), (2, 5, 3)),
                 direction="both", max_length=3.0, spacing=0.01, attributes=ATTRS)


def copy_of(field: Field, k: float = 1.0, warmer: float = 0.0) -> Field:
    """``field`` with every length and speed times ``k`` (so times are equal) and its
    temperature ``warmer``."""
    g = field.grid
    grid = Grid(g.x * k, g.y * k, g.z * k, tuple(p * k for p in g.period), g.uniform)
    scalars = {n: np.asarray(v) + (warmer if n == "T" else 0.0) for n, v in field.scalars.items()}
    return Field(grid, np.asarray(field.vector) * k, scalars, units=dict(field.units),
                 length_units=field.length_units, source=f"{field.source} x{k:g} +{warmer:g} K")


def _room(k=1.0, warmer=0.0) -> Lines:
    from flowkit.datasets import hotroom

    return trace(copy_of(hotroom(), k, warmer), k * seeds.box((2.0, 0.5, 2.0), (8.0, 2.5, 8.0),
                                                              (3, 2, 3)),
                 direction="both", max_length=8.0 * k, spacing=0.08 * k, stagnation=1e-4 * k,
                 attributes=ATTRS)


def _abc(k=1.0, warmer=0.0) -> Lines:
    lines = trace(copy_of(ABCFlow().to_field(shape=(24, 24, 24)), k),
                  k * seeds.box((1, 1, 1), (5, 5, 5), (2, 2, 2)), direction="both",
                  max_length=6.0 * k, spacing=0.05 * k,
                  attributes=tuple(a for a in ATTRS if a != "T"))
    lines.point_data["T"] = 300.0 + warmer + lines.points[:, 2] / k  # rising along z
    return lines


@pytest.fixture(scope="module")
def datasets() -> dict[str, dict[str, Lines]]:
    """Per dataset, the lines traced on it, on a copy 100 times larger and one 50 K warmer."""
    return {name: {"base": make(), "x100": make(100.0), "+50 K": make(warmer=50.0)}
            for name, make in (("room", _room), ("abc", _abc))}


def _differ(a, b) -> float:
    return float(np.mean(np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 8))


@pytest.mark.parametrize("data", ["room", "abc"])
def test_every_example_style_draws_alike_on_a_copy_100_times_larger_or_50_k_warmer(datasets,
                                                                                  data):
    base = datasets[data]["base"]
    copies = {k: v for k, v in datasets[data].items() if k != "base"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (a style made for one flow may clip another's T)
        with LineRenderer(base) as r:
            ref = {n: r.render(s, SIZE) for n, s in example_styles().items()}
        for what, lines in copies.items():
            with LineRenderer(lines) as r:
                for name, s in example_styles().items():
                    d = _differ(ref[name], r.render(s, SIZE))
                    assert d <= 0.01, f"{data} {what}: {name} differs in {d:.1%} of the pixels"


def test_gallery_styles_on_a_tall_thin_cavity_draw_lines_and_legends_cover_the_data(
        cavity_lines):
    with LineRenderer(cavity_lines) as r:
        for p in make_gallery.style_paths():
            s = load_style(p)
            img = r.render(s, (320, 180))
            bg = np.array(s.background[:3]) * 255
            drawn = np.mean(np.abs(img[:, :, :3] - bg).max(axis=2) > 30)
            assert 0.05 <= drawn <= 0.6, f"{p.name}: lines on {drawn:.0%} of the image"
            resolved = r.resolve(s)
            for n in resolved.used_styles():
                for b in resolved.styles[n].bands:
                    pc = b.pattern.color if b.pattern is not None else None
                    for m in (b.color, b.width, pc):
                        if isinstance(m, (ColorMap, WidthMap)):
                            v = cavity_lines.point_data[m.attribute]
                            lo, hi = m.range
                            inside = np.mean((v >= lo - 1e-9 * abs(lo)) & (v <= hi + 1e-9 * abs(hi)))
                            assert inside >= 0.98, f"{p.name}: legend of {m.attribute} holds " \
                                f"{inside:.0%} of the data"


def test_shipped_styles_set_no_fixed_colour_or_width_range():
    for name, s in example_styles().items():
        assert not list(fixed_ranges(s)), f"{name}: a range fixed in numbers"


def test_a_fixed_range_that_clips_is_reported_once_naming_key_range_and_data():
    lines = straight((0, 0, 0), (1, 0, 0), n=50, T=np.linspace(288, 308, 50))
    clip = style_from_dict({"version": 1, "bands": [
        {"width": 2, "color": {"cmap": "gray", "attribute": "T", "range": [300.1, 300.9]}}]})
    fits = dataclasses.replace(clip, styles={"default": dataclasses.replace(
        clip.line_style, bands=(Band(ColorMap("gray", "T", (288.0, 308.0)), 2.0),))})
    with LineRenderer(lines) as r, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r.render(clip, (64, 32), FACE_ON)
        r.render(clip, (64, 32), FACE_ON, overlays=True)
        r.render(fits, (64, 32), FACE_ON)
    msgs = [str(w.message) for w in caught]
    assert len(msgs) == 1, msgs
    assert "band 1 color.range = [300.1, 300.9]" in msgs[0] and "96%" in msgs[0]
    assert "288 .. 308" in msgs[0]


def test_relative_lengths_resolve_against_the_scene():
    assert parse("1/200d") == (0.005, "d") and parse("2.5px") == (2.5, "px")
    assert parse("0.05 m") == (0.05, "m") and parse("0.1z") == (0.1, "z")
    assert parse("3 furlongs") is None and parse("1/0d") is None
    sc = SceneScale(diagonal=4.0, depth=2.0, per_pixel=0.01, length_units="mm", speed=0.5)
    s = style(Band((0, 0, 0, 1), "1/200d"), Band((1, 1, 1, 1), "3px", depth_offset="0.1z"))
    got = resolve_lengths(s, sc).line_style.bands
    assert got[0].width == pytest.approx(2.0)  # 0.02 world units at 0.01 per pixel
    assert got[1].width == 3.0 and got[1].depth_offset == pytest.approx(0.2)
    world = style(Band((0, 0, 0, 1), "0.05 m", depth_offset="0.05 m"), units="world")
    assert resolve_lengths(world, sc).line_style.bands[0].width == pytest.approx(50.0)  # mm
    arrow = style_from_dict({"version": 1, "bands": [{"width": 2, "shape": {
        "name": "arrow", "attribute": "time", "length": "1/8d"}}]})
    assert resolve_lengths(arrow, sc).line_style.bands[0].shape.length == pytest.approx(1.0)
    with pytest.raises(StyleError, match=r"band 1: width = '2 furlongs' is not allowed"):
        style_from_dict({"version": 1, "bands": [{"width": "2 furlongs"}]})
    bad = style_from_dict({"version": 1, "bands": [{"width": 2, "shape": {
        "name": "dash", "attribute": "speed", "length": "1/8d"}}]})
    with pytest.raises(StyleError, match="'speed' is not a length or a time"):
        resolve_lengths(bad, sc)


def test_pixel_lengths_draw_as_numbers_and_diagonal_lengths_follow_the_zoom():
    lines = straight((-1, 0, 0), (1, 0, 0), n=20)
    with LineRenderer(lines) as r:
        a = r.render(style(Band((0, 0, 0, 1), 3.0), background=(1, 1, 1, 1)), (80, 60), FACE_ON)
        b = r.render(style(Band((0, 0, 0, 1), "3px"), background=(1, 1, 1, 1)), (80, 60), FACE_ON)
        assert np.array_equal(a, b)
        thin = r.render(style(Band((0, 0, 0, 1), "1/40d"), background=(1, 1, 1, 1)),
                        (80, 60), FACE_ON)
        wide = r.render(style(Band((0, 0, 0, 1), "1/40d"), background=(1, 1, 1, 1)),
                        (80, 60), dataclasses.replace(FACE_ON, zoom=3.0))
    ink = [np.any(img[:, :, :3] < 128, axis=2).any(axis=1).sum() for img in (thin, wide)]
    assert ink[1] >= 2.5 * ink[0] > 0  # a world length grows with the zoom, pixels would not
