"""The interactive viewer in a real glfw window on a virtual display (Xvfb, started by
conftest.py's ``display``), with synthetic input: pixels of the scene checked on llvmpipe.

One window serves the tests (a new GL context recompiles every program); each test starts from
the base style file and the style's camera.  Xvfb missing: skipped on a developer's machine, a
failure in CI (CI set), where .ci/run installs it.
"""

from __future__ import annotations

import os
import time
import tomllib

import numpy as np
import pytest
from render_scenes import project

from flowkit.lines import Lines
from flowkit.render.style import load_style
from flowkit.view import orbit

SIZE = (640, 360)
BASE = """\
version = 1
background = "#000000"
antialias = "none"

[camera]
azimuth = -90
elevation = 0
projection = "orthographic"

[[bands]]
color = { cmap = "gray", attribute = "speed", range = [0.0, 1.0] }
width = 3.0

[[bands]]
color = "#ff0000"
width = 2.0
"""
RED, GREEN = (255, 0, 0), (0, 255, 0)


def write(path, text: str) -> None:
    """Save like an editor that writes a temp file and renames it."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


DOMAIN = [[-1.0, 1.0], [-0.5, 0.5], [-0.5, 0.5]]  # the field's box, recorded in the file


@pytest.fixture(scope="module")
def lines_file(tmp_path_factory):
    """One straight line along x written to a lines file, with units on some attributes."""
    import h5py

    from flowkit.integrate.reasons import Reason
    from flowkit.io.lines_h5 import write_lines

    n = 64  # face-on it spans the image, end-on it is a dot
    t = np.linspace(0.0, 1.0, n)
    lines = Lines(np.c_[2 * t - 1, 0 * t, 0 * t], [0, n], {"speed": t, "temp": 1.0 - t},
                  {"seed_id": np.array([7]), "reason": np.array([Reason.MAX_LENGTH], np.int8),
                   "reason_backward": np.array([Reason.OUT_OF_DOMAIN], np.int8)},
                  {"direction": "both", "length_units": "m", "domain_bounds": " ".join(str(v) for r in DOMAIN for v in r)})
    path = write_lines(lines, tmp_path_factory.mktemp("lines") / "line.h5")
    with h5py.File(path, "r+") as f:
        f["VTKHDF/PointData/speed"].attrs["units"] = "m/s"
    return path


@pytest.fixture(scope="module")
def viewer(display, tmp_path_factory, lines_file):
    from flowkit.io.lines_h5 import read_lines, read_units
    from flowkit.view.app import Viewer

    d = tmp_path_factory.mktemp("viewer")
    style = d / "style.toml"
    style.write_text(BASE)
    v = Viewer(read_lines(lines_file), style, size=SIZE, vsync=False, screenshot_dir=d,
               units=read_units(lines_file))
    yield v
    v.close()


@pytest.fixture
def fresh(viewer):
    """The viewer with the base style file, its camera, no error, a drawn frame, no undo
    history; the panel hidden (the scene is the whole window), axes on, outline and probe off."""
    import glfw

    write(viewer.style_path, BASE)
    viewer.step()
    viewer.reset_camera()
    viewer.history.clear()
    viewer.show_panel, viewer.show_axes, viewer.show_outline = False, True, False
    viewer.show_legend = True
    viewer.probe, viewer.probe_pinned, viewer._hover = None, False, None
    glfw.set_window_should_close(viewer.window, False)
    viewer.step()
    assert viewer.error is None and viewer.style == load_style(viewer.style_path)
    assert viewer.scene_size == SIZE
    return viewer


def scene(v) -> np.ndarray:
    return v.renderer.read()[:, :, :3].astype(int)


def lit(img) -> np.ndarray:
    return img.sum(axis=2) > 0


def count(img, rgb) -> int:
    return int(np.all(np.abs(img - rgb) <= 2, axis=2).sum())


def test_window_shows_scene_and_panel(fresh):
    import glfw

    fresh.on_key(glfw.KEY_H)  # the panel: the scene is the window right of it
    fresh.step()
    img = fresh.step(read_screen=True)[:, :, :3].astype(int)
    h, w = img.shape[:2]
    x0 = fresh.scene_origin
    assert (w, h) == fresh.size == SIZE and 200 <= x0 <= 400
    assert fresh.scene_size == (SIZE[0] - x0, SIZE[1])
    # right of the panel the window shows the scene, overlays included, as drawn offscreen
    np.testing.assert_array_equal(img[:, x0:], fresh.image()[:, :, :3])
    # the panel covers the left: it differs from the (black there) scene ...
    assert lit(img[10:100, 10:x0 - 10]).mean() > 0.3
    # ... and the whole line is right of it: the scene is centred in its viewport
    cols = np.flatnonzero(lit(scene(fresh)).any(axis=0))
    assert (cols.min() + cols.max()) / 2 == pytest.approx(fresh.scene_size[0] / 2, abs=2)
    assert fresh.frame_time > 0 and fresh.scene_time > 0
    glfw.set_window_size(fresh.window, 500, 300)  # the scene follows the window's size
    try:
        for _ in range(20):  # the X server applies the resize asynchronously
            img = fresh.step(read_screen=True)
            if img.shape[:2] == (300, 500):
                break
        assert img.shape[:2] == (300, 500) and fresh.size == (500, 300)
        x0 = fresh.scene_origin
        np.testing.assert_array_equal(img[:, x0:, :3], fresh.image()[:, :, :3])
        fresh.on_key(glfw.KEY_H)  # hidden: the scene has the whole window
        img = fresh.step(read_screen=True)
        assert fresh.scene_origin == 0 and fresh.scene_size == (500, 300)
        np.testing.assert_array_equal(img[:, :, :3], fresh.image()[:, :, :3])
    finally:
        glfw.set_window_size(fresh.window, *SIZE)
        for _ in range(20):
            fresh.step()
            if fresh.size == SIZE:
                break


def test_orbit_turns_the_line(fresh):
    def extent():
        cols = np.flatnonzero(lit(scene(fresh)).any(axis=0))
        return cols.max() + 1 - cols.min(), (cols.max() + 1 + cols.min()) / 2

    width, centre = extent()
    assert width > 0.5 * SIZE[0]  # face on: the line along x spans the image
    fresh.on_drag(-60 / 0.4, 0)  # drag left: azimuth -90 -> -30, the line seen at 60 degrees
    fresh.step()
    assert fresh.camera.azimuth == pytest.approx(-30.0)
    w2, c2 = extent()
    assert w2 == pytest.approx(width * 0.5, abs=2) and c2 == pytest.approx(centre, abs=1)
    fresh.on_drag(0, 40 / 0.4)  # drag down: the eye goes up 40 degrees; x stays horizontal
    fresh.step()
    assert fresh.camera.elevation == pytest.approx(40.0)
    # the line now slopes across rows as projecting its ends says (+- the 5 px band half-width)
    ends = project(fresh.renderer.bounds, fresh.camera, SIZE, [[-1, 0, 0], [1, 0, 0]])
    rows = np.flatnonzero(lit(scene(fresh)).any(axis=1))
    dx, drop = np.abs(ends[1] - ends[0])
    cap = 10 * dx / np.hypot(dx, drop)  # the strip's width across, seen in rows
    assert drop > 50 and rows.max() + 1 - rows.min() == pytest.approx(drop + cap, abs=2)


def test_zoom_pan_and_reset(fresh):
    def extent():
        cols = np.flatnonzero(lit(scene(fresh)).any(axis=0))
        return cols.min(), cols.max()

    lo, hi = extent()
    fresh.on_scroll(-2)  # orthographic: reduce to 0.9**2 (the fitted line spans 90 %)
    fresh.step()
    lo2, hi2 = extent()
    assert (hi2 - lo2) / (hi - lo) == pytest.approx(0.81, rel=0.03)
    fresh.on_drag(40, 0, button=1)  # right drag pans: the scene follows the mouse
    fresh.step()
    lo3, hi3 = extent()
    assert lo3 - lo2 == pytest.approx(40, abs=2) and hi3 - hi2 == pytest.approx(40, abs=2)
    fresh.on_key(__import__("glfw").KEY_R)
    fresh.step()
    assert extent() == (lo, hi)


def test_named_view_keys_fit_once_then_orbit_at_that_scale(fresh):
    import glfw

    def width():
        cols = np.flatnonzero(lit(scene(fresh)).any(axis=0))
        return cols.max() + 1 - cols.min()

    face_on = width()
    fresh.on_key(glfw.KEY_1)  # +x: the line end on (framed by its sphere), hardly a dot
    fresh.step()
    assert fresh.camera.view is None and lit(scene(fresh)).sum() < 100
    per_px = fresh.camera.setup(fresh.renderer.bounds, *SIZE).px_scale[1]
    fresh.on_drag(90 / 0.4, 0)  # a quarter turn: face on again, at the scale of that fit
    fresh.step()
    assert fresh.camera.setup(fresh.renderer.bounds, *SIZE).px_scale[1] == per_px
    assert width() == pytest.approx(2.0 / per_px, abs=6) and width() < 0.8 * face_on
    fresh.on_key(glfw.KEY_R)  # the style's camera, fitted again
    fresh.step()
    assert width() == face_on


def test_real_callbacks_drive_the_camera(fresh):
    """glfw callbacks reach the handlers when the panel does not take the mouse."""
    import glfw

    x, y = 560, 300  # right of the panel
    fresh._cursor_cb(fresh.window, x, y)
    fresh.step()
    fresh._button_cb(fresh.window, glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
    fresh._cursor_cb(fresh.window, x + 25, y - 10)
    fresh._button_cb(fresh.window, glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)
    assert fresh.camera.azimuth == pytest.approx(-90 - 0.4 * 25)
    assert fresh.camera.elevation == pytest.approx(-0.4 * 10)
    fresh._key_cb(fresh.window, glfw.KEY_R, 0, glfw.PRESS, 0)
    assert fresh.camera == orbit.pinned(fresh.style.camera, fresh.renderer.bounds, SIZE)
    fresh._key_cb(fresh.window, glfw.KEY_ESCAPE, 0, glfw.PRESS, 0)
    assert fresh.should_close


def test_style_file_colour_edit_is_uniform_only(fresh):
    before = scene(fresh)
    halo = count(before, RED)
    assert halo > 100 and count(before, GREEN) == 0
    compiles, uniforms = fresh.renderer.programs.compiles, fresh.updates["uniforms"]
    write(fresh.style_path, BASE.replace("#ff0000", "#00ff00"))
    fresh.step()  # the next frame already shows it
    after = scene(fresh)
    assert count(after, RED) == 0 and count(after, GREEN) == halo
    assert fresh.last_update == "uniforms" and fresh.updates["uniforms"] == uniforms + 1
    assert fresh.renderer.programs.compiles == compiles


def test_style_file_flag_change_recompiles(fresh):
    compiles, recompiles = fresh.renderer.programs.compiles, fresh.updates["recompile"]
    # the halo becomes colour-mapped too: other template flags, another program
    edited = BASE.replace('"#ff0000"', '{ cmap = "gray", attribute = "temp", range = [0.0, 1.0] }')
    write(fresh.style_path, edited)
    fresh.step()
    assert fresh.last_update == "recompile" and fresh.updates["recompile"] == recompiles + 1
    assert fresh.renderer.programs.compiles == compiles + 1
    img = scene(fresh)
    assert count(img, RED) == 0
    rows = np.flatnonzero(lit(img).any(axis=1))
    edge = img[rows.min()]  # the outermost row is halo: grey from temp = 1 - x (left bright)
    cols = np.flatnonzero(lit(img[rows.min():rows.min() + 1]).any(axis=0))
    left, right = edge[cols.min() + 2], edge[cols.max() - 2]
    assert left[0] == left[1] == left[2] and left[0] > 230 and right[0] < 25


def test_broken_style_keeps_last_image_and_reports(fresh, capsys):
    fresh.show_panel = True
    fresh.step()
    good = scene(fresh)
    for broken, words in ((BASE.replace("width = 2.0", "width = -2.0"), ("width", "-2.0")),
                          (BASE + "[[bands\n", ("not valid TOML",)),
                          (BASE.replace('"gray"', '"no-such-map"'), ("cmap", "no-such-map"))):
        write(fresh.style_path, broken)
        screen = fresh.step(read_screen=True)
        assert not fresh.should_close
        assert str(fresh.style_path) in fresh.error and all(w in fresh.error for w in words)
        err = capsys.readouterr().err
        assert all(w in err for w in words), (err, fresh.error)  # printed on the console
        np.testing.assert_array_equal(scene(fresh), good)  # the last good style stays
        # the panel shows the error in its red text colour
        red_text = (screen[:, :, 0] > 200) & (screen[:, :, 1] < 140) & (screen[:, :, 2] < 130)
        assert red_text[:, :340].sum() > 30
    write(fresh.style_path, BASE.replace("#ff0000", "#00ff00"))  # fixed: it applies again
    fresh.step()
    assert fresh.error is None and count(scene(fresh), GREEN) > 100


def test_missing_attribute_is_a_reported_error(fresh):
    write(fresh.style_path, BASE.replace('attribute = "speed"', 'attribute = "vorticity"'))
    fresh.step()
    assert "vorticity" in fresh.error and "speed" in fresh.error  # names what there is
    assert fresh.style.line_style.bands[0].color.attribute == "speed"


def test_panel_edit_has_immediate_effect(fresh):
    halo = count(scene(fresh), RED)
    assert fresh.edit(("styles", "default", "bands", 1, "width"), 4.0) == "uniforms"
    fresh.step()
    assert count(scene(fresh), RED) == pytest.approx(2 * halo, rel=0.1)  # 2 px -> 4 px a side
    assert fresh.edit(("styles", "default", "bands", 1, "width"), -1.0) is None  # refused
    assert "width" in fresh.error and fresh.style.line_style.bands[1].width == 4.0


def test_save_style_round_trips(fresh, tmp_path):
    out = fresh.save_style(tmp_path / "saved.toml")  # nothing changed: the file's own tables
    assert tomllib.loads(out.read_text()) == tomllib.loads(BASE)
    assert load_style(out) == fresh.style
    fresh.edit(("styles", "default", "bands", 1, "color"), (0.25, 0.5, 0.125, 1.0))
    fresh.edit(("styles", "default", "bands", 0, "color", "range"), (0.1, 0.9))
    out = fresh.save_style(tmp_path / "edited.toml")
    assert load_style(out) == fresh.style and fresh.style != load_style(fresh.style_path)
    fresh.save_style()  # onto the watched file: reloading it changes nothing
    fresh.step()
    assert fresh.last_update == "uniforms" and fresh.file_style == fresh.style
    assert fresh.error is None


def legend_pixels(v) -> np.ndarray:
    """The picture inside the legend's box, and the scene (no overlays) there."""
    x0, y0, x1, y1 = v.overlays.box("legend")
    return v.image()[y0:y1, x0:x1, :3].astype(int), scene(v)[y0:y1, x0:x1]


def test_colour_key_cycles_attribute_and_the_legend_follows(fresh):
    import glfw

    img = scene(fresh)
    row = int(np.flatnonzero(lit(img).any(axis=1)).mean())
    cols = np.flatnonzero(lit(img[row:row + 1]).any(axis=0))
    left, right = img[row, cols.min() + 2, 0], img[row, cols.max() - 2, 0]
    assert left < 25 and right > 230  # speed = x: dark to bright
    # the renderer's legend, in a corner of the scene the line leaves free (not the axes')
    x0, y0, x1, y1 = fresh.overlays.box("legend")
    assert (x0 < 30 or x1 > SIZE[0] - 30) and y0 < 30 and y1 < SIZE[1] / 2
    legend, under = legend_pixels(fresh)
    assert not lit(under).any()  # nothing drawn under it ...
    assert lit(legend).mean() > 0.15  # ... its bar and text are (its panel is the black background)
    # the gray bar's ends: dark on the left, bright on the right
    bar = legend[:, :, 0][(np.abs(legend - legend[..., :1]) <= 1).all(axis=2)]
    assert bar.min() < 20 and bar.max() > 235
    fresh.on_key(glfw.KEY_C)
    fresh.step()
    assert fresh.style.line_style.bands[0].color.attribute == "temp"
    assert fresh.style.line_style.bands[0].color.range is None  # automatic: temp's own range
    assert fresh.color_map(resolved=True).range == (0.0, 1.0)
    img = scene(fresh)
    assert img[row, cols.min() + 2, 0] > 230 and img[row, cols.max() - 2, 0] < 25
    legend2, _ = legend_pixels(fresh)  # "temp", no units, instead of "speed [m/s]"
    assert legend2.shape != legend.shape or (legend2 != legend).any()
    fresh.on_key(glfw.KEY_L)  # off: the scene alone there
    fresh.step()
    assert fresh.overlays.box("legend") is None
    np.testing.assert_array_equal(fresh.image()[y0:y1, x0:x1, :3], scene(fresh)[y0:y1, x0:x1])
    fresh.on_key(glfw.KEY_L)
    fresh.on_key(glfw.KEY_C)
    assert fresh.style.line_style.bands[0].color.attribute == "speed"
    fresh.step()
    np.testing.assert_array_equal(legend_pixels(fresh)[0], legend)  # back as it was


def test_legend_sits_in_the_scene_right_of_the_panel(fresh):
    import glfw

    fresh.on_key(glfw.KEY_H)
    fresh.step()
    screen = fresh.step(read_screen=True)[:, :, :3].astype(int)
    x0, y0, x1, y1 = fresh.overlays.box("legend")
    dx = fresh.scene_origin
    assert dx > 200 and x1 <= fresh.scene_size[0]
    np.testing.assert_array_equal(screen[y0:y1, dx + x0:dx + x1], legend_pixels(fresh)[0])


AUTO = BASE.replace(', range = [0.0, 1.0] }', ' }')


def test_automatic_ranges_in_the_panel_and_the_saved_file(fresh, tmp_path):
    """A style without a range (and one with percentiles): drawn, shown resolved in the panel
    (which draws without error), set, and back to automatic, saved without frozen numbers."""
    write(fresh.style_path, AUTO)
    fresh.show_panel = True
    for _ in range(2):
        fresh.step()
    assert fresh.error is None and fresh.color_map().range is None
    assert fresh.color_map(resolved=True).range == (0.0, 1.0)
    fresh.show_panel = False  # the scene as wide as the window: the line across it
    fresh.step()
    img = scene(fresh)
    row = int(np.flatnonzero(lit(img).any(axis=1)).mean())
    cols = np.flatnonzero(lit(img[row:row + 1]).any(axis=0))
    assert img[row, cols.min() + 2, 0] < 25 and img[row, cols.max() - 2, 0] > 230
    fresh.set_color_range((0.25, 0.5))
    fresh.step()
    assert fresh.color_map().range == (0.25, 0.5)
    fresh.set_color_range(None)  # "data range": automatic again
    fresh.step()
    assert fresh.color_map().range is None and fresh.style == fresh.file_style
    fresh.set_color_range((0.25, 0.5))
    fresh.set_color_range(None)
    out = fresh.save_style(tmp_path / "auto.toml")
    assert "range" not in out.read_text() and load_style(out) == fresh.style
    # percentiles: resolved for the panel, kept by "data range" and by C
    write(fresh.style_path, BASE.replace('range = [0.0, 1.0]', 'range = "p10..p90"'))
    fresh.show_panel = True
    fresh.step()
    lo, hi = fresh.color_map(resolved=True).range
    assert lo == pytest.approx(0.1) and hi == pytest.approx(0.9)
    fresh.set_color_range((0.0, 2.0))
    fresh.set_color_range(None)
    assert fresh.color_map().range == "p10..p90"
    fresh.cycle_color_attribute()
    assert fresh.color_map() == fresh.style.line_style.bands[0].color
    assert fresh.color_map().range == "p10..p90" and fresh.color_map().attribute == "temp"
    fresh.step()
    assert fresh.error is None
    text = fresh.save_style(tmp_path / "pct.toml").read_text()
    assert 'range = "p10..p90"' in text and "temp" in text


def test_screenshot_key_writes_png(fresh):
    import glfw
    from PIL import Image

    fresh.on_key(glfw.KEY_S)
    fresh.on_key(glfw.KEY_S)
    shots = sorted(fresh.screenshot_dir.glob("flowkit-view-*.png"))
    assert [p.name for p in shots][-2:] == ["flowkit-view-000.png", "flowkit-view-001.png"]
    with Image.open(shots[-1]) as im:
        img = np.asarray(im)
    assert img.shape == (SIZE[1], SIZE[0], 4)
    np.testing.assert_array_equal(img, fresh.image())  # the scene with its overlays
    x0, y0, x1, y1 = fresh.overlays.box("axes")
    assert (img[y0:y1, x0:x1] != fresh.renderer.read()[y0:y1, x0:x1]).any()
    assert not list(fresh.screenshot_dir.glob(".*.tmp.png"))  # atomic: no temp left


def test_benchmark_runs(display, monkeypatch, capsys):
    """benchmarks/bench_viewer.py at a tiny size: every kind of change lands as it says."""
    from pathlib import Path

    monkeypatch.setenv("MESA_SHADER_CACHE_DISABLE", "true")  # restored after the test
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_viewer

    assert bench_viewer.main(["--lines", "10", "--vertices", "40", "--repeat", "1",
                              "--size", "200x150", "--probes", "5"]) == 0
    out = capsys.readouterr().out
    for kind in bench_viewer.KINDS:  # each timed change asserted its update kind in the run
        assert kind in out
    assert f"{bench_viewer.PROBE}: best" in out and "over 5 random cursor positions" in out


def test_run_loop_until_escape(display, tmp_path):
    """run() draws frames until Esc closes the window, then frees it."""
    import glfw

    from flowkit.view.app import Viewer

    style = tmp_path / "s.toml"
    style.write_text(BASE)
    t = np.linspace(0.0, 1.0, 8)
    v = Viewer(Lines(np.c_[t, t, t], [0, 8], {"speed": t}), style, size=(200, 150), vsync=False)
    step = v.step

    def counted():
        step()
        v.invalidate()  # something to draw again: run() draws the next frame
        if v.frames == 3:
            v.on_key(glfw.KEY_ESCAPE)

    v.step = counted
    v.run()
    assert v.frames == 3 and v.window is None


def test_idle_uses_almost_no_cpu(fresh):
    """Nothing changing: run's loop sleeps between style file polls (psutil, 10 s)."""
    import psutil

    fresh.loop(seconds=1.0)  # the frames after the last input, then idle
    proc = psutil.Process()
    frames, before, t0 = fresh.frames, proc.cpu_times(), time.perf_counter()
    fresh.loop(seconds=10.0)
    after, elapsed = proc.cpu_times(), time.perf_counter() - t0
    used = (after.user - before.user + after.system - before.system) / elapsed
    assert elapsed >= 10.0 and used < 0.02, (used, fresh.frames - frames)
    assert fresh.frames == frames  # not one frame drawn
    write(fresh.style_path, BASE.replace("#ff0000", "#00ff00"))  # a file change still lands
    fresh.loop(seconds=1.0)
    assert fresh.frames > frames and count(scene(fresh), GREEN) > 100


def pixel(v, point):
    """Scene pixel (x, y) of a world point with the viewer's camera."""
    return project(v.renderer.bounds, v.camera, v.scene_size, [point])[0]


def test_probe_reports_the_files_values(fresh, lines_file):
    import h5py

    k = 21  # a vertex of the straight line
    with h5py.File(lines_file) as f:
        speed, temp = (float(f[f"VTKHDF/PointData/{a}"][k]) for a in ("speed", "temp"))
        x = f["VTKHDF/Points"][k]
    readout = fresh.probe_at(*pixel(fresh, x))
    assert readout is not None and fresh.probe == k
    assert readout[0] == f"position ({x[0]:.6g}, 0, 0) m"
    assert "seed 7, line 0, vertex 22 of 64" in readout
    assert f"speed {speed:.6g} m/s" in readout and f"temp {temp:.6g}" in readout
    assert "stopped: forward max_length, backward out_of_domain" in readout
    fresh.step()
    img, sc = fresh.image(), fresh.renderer.read()
    x0, y0, x1, y1 = fresh.overlays.box("probe")  # the read-out is drawn beside the vertex
    assert (img[y0:y1, x0:x1] != sc[y0:y1, x0:x1]).any(axis=2).mean() > 0.3
    assert fresh.probe_at(5, 5) is None  # nothing there: nothing shown
    fresh.step()
    assert fresh.overlays.box("probe") is None


def test_hover_probes_and_the_wheel_zooms_at_the_cursor(fresh):
    k = 50
    at = pixel(fresh, fresh.lines.points[k])
    fresh._cursor_cb(fresh.window, *at)  # panel hidden: window = scene coordinates
    fresh.step()
    assert fresh.probe == k and fresh.overlays.box("probe") is not None
    width = fresh.camera.setup(fresh.renderer.bounds, *SIZE).proj[0, 0]
    fresh._scroll_cb(fresh.window, 0, 3)  # zoom in 1 / 0.9**3 about the cursor
    fresh.step()
    assert fresh.camera.setup(fresh.renderer.bounds, *SIZE).proj[0, 0] == pytest.approx(
        width / 0.9 ** 3)
    np.testing.assert_allclose(pixel(fresh, fresh.lines.points[k]), at, atol=1e-6)
    assert fresh.probe == k  # still under the cursor


def test_undo_returns_the_style_files_values(fresh):
    import glfw

    file_style = load_style(fresh.style_path)
    width = ("styles", "default", "bands", 1, "width")
    for i in range(30):  # one drag of the width: one undo step
        fresh.edit(width, 2.0 + 0.1 * (i + 1), merge=i > 0)
    assert fresh.history.counts == (1, 0)
    for i in range(55):  # 55 separate edits
        fresh.edit(("styles", "default", "bands", 1, "color"), (i / 64, 0.5, 0.25, 1.0))
    fresh.on_key(glfw.KEY_C)  # the colour attribute: undoable too
    fresh.set_color_range((0.2, 0.3))
    edited = fresh.style
    assert fresh.history.counts == (58, 0)
    for _ in range(57):
        fresh.on_key(glfw.KEY_Z, mods=glfw.MOD_CONTROL)
    assert fresh.style.line_style.bands[1].width == pytest.approx(5.0)
    fresh.on_key(glfw.KEY_Z, mods=glfw.MOD_CONTROL)
    assert fresh.style == file_style and fresh.style.line_style.bands[1].width == 2.0
    assert fresh.undo() is None and fresh.history.counts == (0, 58)
    for _ in range(58):
        fresh.on_key(glfw.KEY_Z, mods=glfw.MOD_CONTROL | glfw.MOD_SHIFT)
    assert fresh.style == edited
    fresh.step()
    assert fresh.error is None


def test_saved_width_is_written_as_the_panel_shows_it(fresh, monkeypatch):
    """The width widget (float32 inside ImGui) dragged to 4.072: the file says 4.072."""
    from flowkit.view import panel

    fresh.show_panel = True
    drag = panel.imgui.drag_float

    def dragged(label, value, *args, **kwargs):  # what ImGui returns for a drag to 4.072
        changed, x = drag(label, value, *args, **kwargs)
        if label == "width" and value == 2.0:
            assert kwargs["format"] == "%.3f"
            return True, float(np.float32(4.072))
        return changed, x

    monkeypatch.setattr(panel.imgui, "drag_float", dragged)
    fresh.step()
    monkeypatch.undo()
    assert fresh.style.line_style.bands[1].width == 4.072
    fresh.save_style()
    text = fresh.style_path.read_text()
    assert "width = 4.072\n" in text and "4.072000" not in text
    assert tomllib.loads(text)["bands"][1]["width"] == 4.072


def test_axes_and_outline_toggle(fresh):
    import glfw

    fresh.on_drag(-50, 40)  # turned so that no axis points at the eye
    img = fresh.image()[:, :, :3].astype(int)
    x0, y0, x1, y1 = fresh.overlays.box("axes")
    assert x0 < 20 and y1 > SIZE[1] - 20  # bottom left
    box = img[y0:y1, x0:x1]
    for rgb in ((235, 70, 70), (90, 205, 90), (90, 140, 255)):  # x, y, z arrows
        assert count(box, rgb) > 20, rgb
    assert not lit(scene(fresh)[y0:y1, x0:x1]).any()  # the scene is black there
    fresh.on_key(glfw.KEY_A)
    assert not lit(fresh.image()[y0:y1, x0:x1, :3]).any() and fresh.overlays.box("axes") is None
    # the outline: the field's box from the file, its top edge (z = 0.5) a grey row
    fresh.reset_camera()
    fresh.step()
    grey = (204, 204, 204)
    row = round(pixel(fresh, (0.0, 0.0, 0.5))[1])
    assert row < SIZE[1] / 2 - 50  # well above the line

    def edge():
        return count(scene(fresh)[row - 1:row + 2], grey)

    assert edge() == 0
    fresh.on_key(glfw.KEY_B)
    fresh.step()
    assert edge() > 0.5 * SIZE[0]
    fresh.on_key(glfw.KEY_B)
    fresh.step()
    assert edge() == 0


def test_click_pins_the_probe_and_data_range_resets(fresh):
    import glfw

    k = 10
    at = pixel(fresh, fresh.lines.points[k])
    fresh._cursor_cb(fresh.window, *at)
    fresh._button_cb(fresh.window, glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
    fresh._button_cb(fresh.window, glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)  # a click
    assert fresh.probe == k and fresh.probe_pinned
    fresh._cursor_cb(fresh.window, 5, 5)  # moving away keeps the pinned probe
    fresh.step()
    assert fresh.probe == k and fresh.overlays.box("probe") is not None
    fresh._button_cb(fresh.window, glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
    fresh._button_cb(fresh.window, glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)  # on empty scene
    fresh.step()
    assert fresh.probe is None and fresh.overlays.box("probe") is None
    # the colour range: set, then back to the attribute's data range (automatic)
    fresh.set_color_range((0.25, 0.5))
    assert fresh.color_map().range == (0.25, 0.5)
    fresh.set_color_range(None)
    assert fresh.color_map().range is None
    assert fresh.color_map(resolved=True).range == fresh.value_range("speed") == (0.0, 1.0)
