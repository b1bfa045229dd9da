"""The viewer's parts that need no window: the style TOML writer (exact round trip), the panel's
parameter list and edits, the mouse camera control, the file watch, the CLI's errors."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flowkit.lines import Lines
from flowkit.render import Camera
from flowkit.render.style import (
    Band,
    ColorMap,
    LineStyle,
    Pattern,
    Shape,
    Style,
    StyleError,
    Transfer,
    TransferRange,
    WidthMap,
    dump_style,
    load_style,
    save_style,
    style_from_dict,
    style_to_dict,
)
from flowkit.view import orbit
from flowkit.view.edit import get_at, params, replace_at, with_color_attribute
from flowkit.view.watch import FileWatch

ROOT = Path(__file__).resolve().parent.parent
GRAY = ColorMap("gray", "speed", (0.0, 1.0))

RICH = Style(
    styles={
        "fast": LineStyle((
            Band(GRAY, WidthMap("speed", (0.0, 2.0), 1.0, 4.0), 0.0,
                 Shape("arrow", "time", 0.3), Pattern((0.1, 0.2, 0.30000000000000004, 1.0),
                                                       "arc_length", 0.7, 0.5, 2.0, 0.25)),
            Band((1.0, 1.0, 1.0, 0.5), 1.5, 0.05, Shape("custom", "arc_length", 2.0,
                                                        ((0.0, 0.0), (0.5, 1.0), (1.0, 0.25)))),
        )),
        "slow": LineStyle((Band((0.2, 0.4, 0.6, 1.0), 2.0,
                                pattern=Pattern(ColorMap("viridis", "T", (-1.0, 1e-9)))),)),
    },
    units="world", scale=0.5, background=None, antialias="smooth", samples=8, supersample=2,
    camera=Camera(azimuth=12.5, elevation=-3.0, distance=4.0, target=(0.1, 0.2, 0.3),
                  up=(0.0, 1.0, 0.0), fov=45.0, projection="orthographic", zoom=2.0),
    transfer=Transfer("speed", (TransferRange((-math.inf, 0.5), "slow"),
                                TransferRange((0.5, 1.0), None),
                                TransferRange((1.0, math.inf), "fast")), blend=0.1),
    phase=0.125,
)


@pytest.mark.parametrize("style", [RICH, *sorted((ROOT / "examples/styles").glob("*.toml"))],
                         ids=lambda s: s.name if isinstance(s, Path) else "rich")
def test_toml_writer_round_trips_exactly(style, tmp_path):
    style = load_style(style) if isinstance(style, Path) else style
    out = save_style(style, tmp_path / "s.toml")
    assert load_style(out) == style
    assert style_from_dict(tomllib.loads(dump_style(style))) == style
    assert not [p for p in tmp_path.iterdir() if p.name != "s.toml"]  # atomic: no temp left


COMMENTED = """\
# my halo style
version = 1
background = "#FFFFFF"   # upper case, not as flowkit writes it
antialias = "none"

[[bands]]  # core
color = [0, 0, 0]
width = 1.5

[[bands]]  # halo
color = "#ffffff"
width = 2.0
depth_offset = 0.01
"""


def test_save_keeps_comments_and_spelling(tmp_path):
    base = style_from_dict(tomllib.loads(COMMENTED))
    out = save_style(base, tmp_path / "same.toml", keep=COMMENTED)
    assert out.read_text() == COMMENTED  # unedited: the file as it was
    edited = replace_at(replace_at(base, ("styles", "default", "bands", 1, "width"), 3.5),
                        ("scale", ), 2.0)  # a key the file does not spell out
    text = save_style(edited, tmp_path / "s.toml", keep=COMMENTED).read_text()
    assert load_style(tmp_path / "s.toml") == edited
    for kept in ("# my halo style", "# upper case, not as flowkit writes it",
                 "[[bands]]  # core", "[[bands]]  # halo", "color = [0, 0, 0]",
                 'background = "#FFFFFF"'):
        assert kept in text, kept
    assert "width = 3.5" in text and "width = 2.0" not in text and "scale = 2.0" in text


@pytest.mark.parametrize("path", sorted((ROOT / "examples/styles").glob("*.toml")),
                         ids=lambda p: p.name)
def test_save_keeps_gallery_files(path, tmp_path):
    """Every gallery style, one parameter edited: read back equal, every comment line kept."""
    text = path.read_text()
    style = load_style(path)
    name = next(iter(style.styles))
    edited = replace_at(style, ("styles", name, "bands", 0, "depth_offset"),
                        style.styles[name].bands[0].depth_offset + 0.5)
    out = save_style(edited, tmp_path / path.name, keep=text)
    assert load_style(out) == edited
    comments = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("#")]
    assert comments and all(c in out.read_text() for c in comments)


def test_save_falls_back_when_the_layout_differs(tmp_path):
    """A file laid out unlike style_to_dict ([styles.default] instead of [[bands]]) cannot be
    edited in place once the edit changes the layout: the whole style is written instead."""
    text = COMMENTED.replace("[[bands]]", "[[styles.default.bands]]")
    base = style_from_dict(tomllib.loads(text))
    edited = replace_at(base, ("styles", "default", "bands", 0, "width"), 4.0)
    out = save_style(edited, tmp_path / "s.toml", keep=text)
    assert out.read_text() == dump_style(edited)  # the plain text: comments lost
    assert load_style(out) == edited


def test_toml_writer_forms():
    d = style_to_dict(RICH)
    assert d["background"] == "transparent" and "bands" not in d
    assert d["styles"]["slow"]["bands"][0]["color"] == "#336699"  # exact hex stays hex
    assert d["styles"]["fast"]["bands"][1]["color"] == [1.0, 1.0, 1.0, 0.5]
    assert d["transfer"]["ranges"][1] == {"range": [0.5, 1.0]}  # no style: not drawn
    assert "inf" in dump_style(RICH)
    plain = Style(styles={"default": LineStyle((Band((1.0, 0.0, 0.0, 1.0), 2.0),))})
    d = style_to_dict(plain)
    assert d["bands"][0]["color"] == "#ff0000" and "distance" not in d["camera"]


def test_params_cover_the_style():
    ps = {p.path: p for p in params(RICH)}
    fast, slow = ("styles", "fast", "bands"), ("styles", "slow", "bands")
    expected = {
        ("scale",): "float", ("phase",): "float",
        fast + (0, "color", "cmap"): "cmap", fast + (0, "color", "range"): "range",
        fast + (0, "color", "attribute"): "attribute",
        fast + (0, "width", "range"): "range", fast + (0, "width", "min"): "float",
        fast + (0, "width", "max"): "float", fast + (0, "depth_offset"): "float",
        fast + (0, "shape", "name"): "shape", fast + (0, "shape", "length"): "float",
        fast + (0, "pattern", "length"): "float", fast + (0, "pattern", "slope"): "float",
        fast + (0, "pattern", "curve"): "float", fast + (0, "pattern", "fraction"): "float",
        fast + (0, "pattern", "color"): "color",
        fast + (1, "color"): "color", fast + (1, "width"): "float",
        fast + (1, "depth_offset"): "float", fast + (1, "shape", "length"): "float",
        slow + (0, "pattern", "color", "cmap"): "cmap",
        slow + (0, "pattern", "color", "range"): "range",
        ("transfer", "ranges", 0, "range"): "range", ("transfer", "ranges", 2, "range"): "range",
        ("transfer", "blend"): "float",
    }
    for path, kind in expected.items():
        assert ps[path].kind == kind, path
        assert ps[path].value == get_at(RICH, path)
    assert fast + (1, "shape", "name") not in ps  # a custom shape has no name to pick
    assert ("background",) not in ps  # transparent: nothing to edit


def test_replace_at_rebuilds_and_validates():
    s = replace_at(RICH, ("styles", "fast", "bands", 1, "depth_offset"), 0.5)
    assert s.styles["fast"].bands[1].depth_offset == 0.5
    assert RICH.styles["fast"].bands[1].depth_offset == 0.05  # frozen: a new Style
    assert s.styles["slow"] is RICH.styles["slow"]
    with pytest.raises(StyleError, match="fraction"):
        replace_at(RICH, ("styles", "fast", "bands", 0, "pattern", "fraction"), 2.0)
    with pytest.raises(StyleError, match="cmap"):
        replace_at(RICH, ("styles", "fast", "bands", 0, "color", "cmap"), "no-such-map")


def test_colour_attribute_swaps_every_colour_map():
    s = with_color_attribute(RICH, "T", (2.0, 3.0))
    assert s.styles["fast"].bands[0].color == ColorMap("gray", "T", (2.0, 3.0))
    assert s.styles["slow"].bands[0].pattern.color == ColorMap("viridis", "T", (2.0, 3.0))
    assert s.styles["fast"].bands[1].color == RICH.styles["fast"].bands[1].color
    assert s.transfer == RICH.transfer  # the transfer function keeps its attribute


BOUNDS = np.array([[-1.0, 1.0], [-2.0, 2.0], [0.0, 0.5]])


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_pinning_keeps_the_view(projection):
    cam = Camera(azimuth=30, elevation=20, projection=projection)
    a, b = cam.setup(BOUNDS, 400, 300), orbit.pinned(cam, BOUNDS, (400, 300)).setup(BOUNDS, 400, 300)
    np.testing.assert_allclose(b.view, a.view, atol=1e-12)
    np.testing.assert_allclose(b.proj, a.proj, rtol=1e-12)


def test_orbit_zoom_pan():
    cam = Camera(azimuth=170, elevation=80)
    c = orbit.orbit(cam, -50, 50)  # +20 degrees azimuth wraps, elevation stops short of the pole
    assert c.azimuth == pytest.approx(-170) and c.elevation == orbit.MAX_ELEVATION
    size = (400, 300)
    z = orbit.zoom(cam, 3, BOUNDS, size)
    fit = orbit.pinned(cam, BOUNDS, size).distance
    assert z.distance == pytest.approx(fit * 0.9 ** 3)
    assert orbit.zoom(Camera(projection="orthographic"), -1, BOUNDS, size).zoom == pytest.approx(0.9)
    # pan: the bounds' centre's image moves with the mouse, in pixels
    def at(c):
        s = c.setup(BOUNDS, *size)
        clip = s.proj @ s.view @ np.r_[BOUNDS.mean(axis=1), 1.0]
        return np.array([(clip[0] / clip[3] + 1) / 2 * size[0], (1 - clip[1] / clip[3]) / 2 * size[1]])

    np.testing.assert_allclose(at(orbit.pan(cam, 30, -20, BOUNDS, size)) - at(cam), (30, -20),
                               atol=1e-6)
    o = orbit.pan(Camera(projection="orthographic"), 30, -20, BOUNDS, size)
    so, s0 = o.setup(BOUNDS, *size), Camera(projection="orthographic").setup(BOUNDS, *size)
    assert so.px_scale[1] == pytest.approx(s0.px_scale[1])  # orthographic pan keeps the scale


def test_file_watch(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text("a")
    w = FileWatch(f)
    assert not w.changed()
    tmp = tmp_path / "t"
    tmp.write_text("a")
    os.replace(tmp, f)  # an editor's save: same size, new file
    assert w.changed() and not w.changed()
    f.unlink()
    assert not w.changed()  # gone (mid-save): nothing to report yet
    f.write_text("bb")
    assert w.changed()


def test_cli_view_errors(tmp_path):
    """Without a display the CLI says what to do in one line; bad files are named."""
    from flowkit.io.lines_h5 import write_lines

    lines = tmp_path / "l.h5"
    write_lines(Lines(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]], [0, 2]), lines)
    style = tmp_path / "s.toml"
    style.write_text('version = 1\n[[bands]]\ncolor = "#000000"\n')
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    run = [sys.executable, "-m", "flowkit", "view", str(lines), "--style"]
    r = subprocess.run(run + [str(style)], env=env, capture_output=True, text=True, timeout=120,
                       check=False)
    assert r.returncode == 2 and "display" in r.stderr and "xvfb-run" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    style.write_text('version = 1\n[[bands]]\nwidth = "wide"\n')
    r = subprocess.run(run + [str(style)], env=env, capture_output=True, text=True, timeout=120,
                       check=False)
    assert r.returncode == 2 and str(style) in r.stderr and "width" in r.stderr


def test_viewer_refuses_a_style_the_lines_cannot_show(tmp_path):
    """Checked before any window opens: the file, the attribute and what there is."""
    from flowkit.view.app import Viewer

    style = tmp_path / "s.toml"
    style.write_text('version = 1\n[[bands]]\ncolor = { cmap = "gray", attribute = "T", '
                     'range = [0, 1] }\n')
    lines = Lines(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]], [0, 2], {"speed": np.ones(2)})
    with pytest.raises(StyleError, match=r"s\.toml.*'T'.*available: speed"):
        Viewer(lines, style)


def test_numbers_are_kept_as_the_panel_shows_them():
    from flowkit.view.panel import keep_unedited, number_format, shown, shown_color

    assert number_format(4.072) == "%.3f" and number_format(0.0005) == "%.7f"
    assert number_format(1234.5) == "%.3f" and number_format(0.0) == "%.3f"
    f32 = float(np.float32(4.072))  # what ImGui's float32 widget hands back
    assert f32 != 4.072 and shown(f32, "%.3f") == 4.072
    assert repr(shown(float(np.float32(0.0012346)), number_format(0.0012346))) == "0.001235"
    assert shown(math.inf, "%.3f") == math.inf
    c = shown_color([float(np.float32(64 / 255)), 1.0000001, -0.1, 0.5])
    assert c == (64 / 255, 1.0, 0.0, 128 / 255)
    style = replace_at(RICH, ("styles", "slow", "bands", 0, "color"), c[:3] + (1.0,))
    assert style_to_dict(style)["styles"]["slow"]["bands"][0]["color"] == "#40ff00"
    # a range or colour widget hands back every component: the untouched ones stay as they were
    old = (0.12345678, 1.0)
    new = [float(np.float32(0.12345678)), float(np.float32(2.5))]  # the upper bound dragged
    assert keep_unedited(new, old, lambda r: [shown(x, "%.3f") for x in r]) == (0.12345678, 2.5)
    assert keep_unedited([float(np.float32(0.3)), 0.2], (0.3, 0.1), shown_color) == (0.3, 51 / 255)


def test_history_steps_and_drags():
    from flowkit.view.history import History

    h = History(limit=60)
    for i in range(70):
        h.record(i)
    assert h.counts == (60, 0)
    h.record(70, key="w")
    h.record(71, key="w", merge=True)  # the same drag: no new step
    h.record(72, key="v", merge=True)  # another widget: a step
    assert h.counts == (60, 0)  # bounded: the oldest went
    assert h.undo("now") == 72 and h.undo(72) == 70 and h.counts == (58, 2)
    assert h.redo(70) == 72 and h.counts == (59, 1)
    h.record(99)  # a new edit drops what could be redone
    assert h.counts == (60, 0) and h.redo("x") is None
    h.clear()
    assert h.undo("x") is None


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_wheel_zoom_keeps_the_point_under_the_cursor(projection):
    cam = Camera(azimuth=30, elevation=20, projection=projection)
    size, at = (400, 300), (310.0, 80.0)
    s = orbit.pinned(cam, BOUNDS, size).setup(BOUNDS, *size)
    # the world point under the cursor on the target's depth plane
    ndc = np.array([2 * at[0] / size[0] - 1, 1 - 2 * at[1] / size[1]])
    target = BOUNDS.mean(axis=1)
    depth = (s.proj @ s.view @ np.r_[target, 1.0])
    p = np.linalg.inv(s.proj @ s.view) @ np.r_[ndc * depth[3], depth[2], depth[3]]
    z = orbit.zoom_at(cam, 2, BOUNDS, size, *at)
    s2 = z.setup(BOUNDS, *size)
    clip = s2.proj @ s2.view @ p
    px = ((clip[0] / clip[3] + 1) / 2 * size[0], (1 - clip[1] / clip[3]) / 2 * size[1])
    assert px == pytest.approx(at, abs=1e-6)
    # and it magnifies as the centred zoom does
    c = orbit.zoom(cam, 2, BOUNDS, size).setup(BOUNDS, *size)
    assert s2.px_scale[0] * z.distance + s2.px_scale[1] == pytest.approx(
        c.px_scale[0] * orbit.zoom(cam, 2, BOUNDS, size).distance + c.px_scale[1]
        if projection == "perspective" else c.px_scale[1], rel=1e-9)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_picker_finds_the_vertex_drawn_under_the_cursor(projection):
    """Against projecting every vertex: within 8 px, the front layer, the nearest there."""
    from flowkit.view.probe import Picker

    rng = np.random.default_rng(3)
    points = rng.uniform(-1, 1, (60000, 3)) * [1.0, 2.0, 0.5]  # dense: early exits
    points[5] = np.nan  # not finite: never picked
    picker = Picker(points)
    bounds = np.array([[-1.0, 1.0], [-2.0, 2.0], [-0.5, 0.5]])
    size = (320, 240)
    s = Camera(azimuth=40, elevation=30, projection=projection).setup(bounds, *size)
    clip = np.c_[points, np.ones(len(points))] @ (s.proj @ s.view).T
    sx = (clip[:, 0] / clip[:, 3] + 1) / 2 * size[0]
    sy = (1 - clip[:, 1] / clip[:, 3]) / 2 * size[1]
    depth = -(points @ s.view[2, :3] + s.view[2, 3])
    hits = 0
    for x, y in rng.uniform(0.2, 0.8, (60, 2)) * size:
        got = picker.pick(s, size, x, y, bounds)
        d2 = (sx - x) ** 2 + (sy - y) ** 2
        near = np.flatnonzero(d2 <= 64)
        if near.size == 0:
            assert got is None
            continue
        hits += 1
        px = s.px_scale[0] * depth[near].min() + s.px_scale[1]
        front = near[depth[near] <= depth[near].min() + 8 * px]  # within a pick radius in depth
        assert got == front[np.argmin(d2[front])]  # the nearest to the cursor there
    assert hits > 20
    assert picker.pick(s, size, -500, -500, bounds) is None  # off the scene


def test_probe_read_out():
    from flowkit.integrate.reasons import Reason
    from flowkit.view.probe import describe

    lines = Lines(np.arange(15.0).reshape(5, 3), [0, 2, 5],
                  {"speed": np.array([1.0, 2, 3, 4, 5]), "velocity": np.ones((5, 3))},
                  {"seed_id": np.array([4, 9]), "reason": np.array([2, 0], np.int8),
                   "n_accepted": np.array([10, 20], np.int32)}, {"direction": "backward"})
    out = describe(lines, 3, {"speed": "m/s", "position": "mm", "velocity": "1"})
    assert out == ["position (9, 10, 11) mm", "seed 9, line 1, vertex 2 of 3", "speed 4 m/s",
                   "velocity (1, 1, 1)", f"stopped (backward): {Reason(0).label}",
                   "n_accepted 20"]


def test_read_units(tmp_path):
    import h5py

    from flowkit.io.lines_h5 import read_units, write_lines

    lines = Lines(np.zeros((2, 3)), [0, 2], {"speed": np.ones(2), "T": np.ones(2)},
                  attrs={"length_units": "m"})
    path = write_lines(lines, tmp_path / "l.h5")
    with h5py.File(path, "r+") as f:
        f["VTKHDF/PointData/speed"].attrs["units"] = "m/s"
    assert read_units(path) == {"position": "m", "speed": "m/s"}


def test_domain_bounds_and_outline_edges():
    from flowkit.view.outline import box_edges, domain_bounds

    lines = Lines(np.zeros((2, 3)), [0, 2], attrs={"domain_bounds": "0.0 1.0 -2 2 0 0.5"})
    np.testing.assert_array_equal(domain_bounds(lines), [[0, 1], [-2, 2], [0, 0.5]])
    assert domain_bounds(Lines(np.zeros((2, 3)), [0, 2], attrs={"domain_bounds": "1 2"})) is None
    edges = box_edges(domain_bounds(lines)).reshape(12, 2, 3)
    d = np.abs(edges[:, 1] - edges[:, 0])
    assert ((d > 0).sum(axis=1) == 1).all()  # each edge along one axis
    assert sorted(d.max(axis=1)) == [0.5] * 4 + [1.0] * 4 + [4.0] * 4


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_orbiting_a_pinned_camera_keeps_the_scale(projection):
    """Fitted once, the scale stays while the view turns; refitting at every direction (what
    pinning prevents) changes it, since the projected bounds differ from every side."""
    size = (400, 300)

    def scale(cam):  # world size of a pixel at the target
        s = cam.setup(BOUNDS, *size)
        return s.px_scale[0] * np.linalg.norm(s.eye - s.target) + s.px_scale[1]

    cam = Camera(azimuth=30, elevation=20, projection=projection)
    p = orbit.pinned(cam, BOUNDS, size)
    assert orbit.is_pinned(p) and scale(p) == pytest.approx(scale(cam), rel=1e-12)
    pinned_scales, refit_scales = [], []
    for _ in range(12):
        p, cam = orbit.orbit(p, 75, 10), orbit.orbit(cam, 75, 10)
        pinned_scales.append(scale(p))
        refit_scales.append(scale(cam))
    assert np.ptp(pinned_scales) <= 1e-9 * pinned_scales[0]
    assert np.ptp(refit_scales) > 0.1 * refit_scales[0]


@pytest.mark.parametrize("view", ["+x", "-z", "iso"])
def test_a_named_view_pins_to_azimuth_and_elevation(view):
    """Pinned, a named view becomes the same view as azimuth/elevation, so the mouse orbits it."""
    cam, size = Camera(view=view), (400, 300)
    p = orbit.pinned(cam, BOUNDS, size)
    assert p.view is None and p.up is not None
    a, b = cam.setup(BOUNDS, *size), p.setup(BOUNDS, *size)
    np.testing.assert_allclose(b.view, a.view, atol=1e-12)
    np.testing.assert_allclose(b.proj, a.proj, rtol=1e-9)
    assert not np.allclose(orbit.orbit(p, 20, 0).setup(BOUNDS, *size).view, b.view)


def test_a_point_like_domain_is_framed_by_its_sphere():
    line = np.array([[-1.0, 1.0], [0.0, 0.0], [0.0, 0.0]])  # a straight line, seen end on
    for projection in ("perspective", "orthographic"):
        end_on = Camera(view="+x", projection=projection).setup(line, 400, 300)
        sphere = Camera(view="+x", projection=projection, fit="sphere").setup(line, 400, 300)
        np.testing.assert_allclose(end_on.proj, sphere.proj)
        np.testing.assert_allclose(end_on.eye, sphere.eye)
