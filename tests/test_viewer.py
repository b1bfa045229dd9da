"""The interactive viewer in a real glfw window on a virtual display (Xvfb, started by
conftest.py's ``display``), with synthetic input: pixels of the scene checked on llvmpipe.

One window serves the tests (a new GL context recompiles every program); each test starts from
the base style file and the style's camera.  Xvfb missing: skipped on a developer's machine, a
failure in CI (CI set), where .ci/run installs it.
"""

from __future__ import annotations

import os
import tomllib

import numpy as np
import pytest
from render_scenes import project

from flowkit.lines import Lines
from flowkit.render.style import load_style

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


@pytest.fixture(scope="module")
def viewer(display, tmp_path_factory):
    from flowkit.view.app import Viewer

    d = tmp_path_factory.mktemp("viewer")
    style = d / "style.toml"
    style.write_text(BASE)
    n = 64  # one line along x: face-on it spans the image, end-on it is a dot
    t = np.linspace(0.0, 1.0, n)
    lines = Lines(np.c_[2 * t - 1, 0 * t, 0 * t], [0, n], {"speed": t, "temp": 1.0 - t})
    v = Viewer(lines, style, size=SIZE, vsync=False, screenshot_dir=d)
    yield v
    v.close()


@pytest.fixture
def fresh(viewer):
    """The viewer with the base style file, its camera, no error, a drawn frame."""
    import glfw

    write(viewer.style_path, BASE)
    viewer.step()
    viewer.reset_camera()
    glfw.set_window_should_close(viewer.window, False)
    viewer.step()
    assert viewer.error is None and viewer.style == load_style(viewer.style_path)
    return viewer


def scene(v) -> np.ndarray:
    return v.renderer.read()[:, :, :3].astype(int)


def lit(img) -> np.ndarray:
    return img.sum(axis=2) > 0


def count(img, rgb) -> int:
    return int(np.all(np.abs(img - rgb) <= 2, axis=2).sum())


def test_window_shows_scene_and_panel(fresh):
    img = fresh.step(read_screen=True)[:, :, :3].astype(int)
    h, w = img.shape[:2]
    assert (w, h) == fresh.size == SIZE
    # right of the panel the window shows the scene as drawn offscreen
    np.testing.assert_array_equal(img[:, 400:], scene(fresh)[:, 400:])
    # the panel covers the top left: it differs from the (black there) scene
    assert lit(img[10:100, 10:300]).mean() > 0.3 and not lit(scene(fresh)[10:100, 10:300]).any()
    assert fresh.frame_time > 0 and fresh.scene_time > 0
    import glfw

    glfw.set_window_size(fresh.window, 500, 300)  # the scene follows the window's size
    try:
        for _ in range(20):  # the X server applies the resize asynchronously
            img = fresh.step(read_screen=True)
            if img.shape[:2] == (300, 500):
                break
        assert img.shape[:2] == (300, 500) and fresh.size == (500, 300)
        np.testing.assert_array_equal(img[:, 400:, :3], scene(fresh)[:, 400:])
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
    fresh.on_scroll(2)  # orthographic: magnify 1 / 0.9**2
    fresh.step()
    lo2, hi2 = extent()
    assert (hi2 - lo2) / (hi - lo) == pytest.approx(1 / 0.81, rel=0.03)
    fresh.on_drag(40, 0, button=1)  # right drag pans: the scene follows the mouse
    fresh.step()
    lo3, hi3 = extent()
    assert lo3 - lo2 == pytest.approx(40, abs=2) and hi3 - hi2 == pytest.approx(40, abs=2)
    fresh.on_key(__import__("glfw").KEY_R)
    fresh.step()
    assert extent() == (lo, hi)


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
    assert fresh.camera == fresh.style.camera
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


def test_colour_key_cycles_attribute(fresh):
    import glfw

    img = scene(fresh)
    row = int(np.flatnonzero(lit(img).any(axis=1)).mean())
    cols = np.flatnonzero(lit(img[row:row + 1]).any(axis=0))
    left, right = img[row, cols.min() + 2, 0], img[row, cols.max() - 2, 0]
    assert left < 25 and right > 230  # speed = x: dark to bright
    fresh.on_key(glfw.KEY_C)
    fresh.step()
    assert fresh.style.line_style.bands[0].color.attribute == "temp"
    img = scene(fresh)
    assert img[row, cols.min() + 2, 0] > 230 and img[row, cols.max() - 2, 0] < 25
    fresh.on_key(glfw.KEY_C)
    assert fresh.style.line_style.bands[0].color.attribute == "speed"


def test_screenshot_key_writes_png(fresh):
    import glfw
    from PIL import Image

    fresh.on_key(glfw.KEY_S)
    fresh.on_key(glfw.KEY_S)
    shots = sorted(fresh.screenshot_dir.glob("flowkit-view-*.png"))
    assert [p.name for p in shots][-2:] == ["flowkit-view-000.png", "flowkit-view-001.png"]
    img = np.asarray(Image.open(shots[-1]))
    assert img.shape == (SIZE[1], SIZE[0], 4)
    np.testing.assert_array_equal(img, fresh.renderer.read())
    assert not list(fresh.screenshot_dir.glob(".*.tmp.png"))  # atomic: no temp left


def test_benchmark_runs(display, monkeypatch, capsys):
    """benchmarks/bench_viewer.py at a tiny size: every kind of change lands as it says."""
    from pathlib import Path

    monkeypatch.setenv("MESA_SHADER_CACHE_DISABLE", "true")  # restored after the test
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_viewer

    assert bench_viewer.main(["--lines", "10", "--vertices", "40", "--repeat", "1",
                              "--size", "200x150"]) == 0
    out = capsys.readouterr().out
    for kind in bench_viewer.KINDS:  # each timed change asserted its update kind in the run
        assert kind in out


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
        if v.frames == 3:
            v.on_key(glfw.KEY_ESCAPE)

    v.step = counted
    v.run()
    assert v.frames == 3 and v.window is None
