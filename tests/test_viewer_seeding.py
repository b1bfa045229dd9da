"""Live seeding: the rake's model (no display), and in a real window under Xvfb a scripted drag
of a rake handle that re-traces and redraws the lines, whose saved seed spec traces to the same
lines through ``flowkit trace``."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from flowkit.integrate.seeds import SeedError, parse_seed_spec
from flowkit.view.rake import Rake

BOUNDS = [[0.0, 10.0], [0.0, 5.0], [0.0, 10.0]]


def test_rake_moves_round_and_stay_exact():
    r = Rake.from_spec("line:1,1,1:9,1,1:5")
    assert r.spec() == "line:1.0,1.0,1.0:9.0,1.0,1.0:5"
    m = r.moved("end", (9.123456, 7.0, 1.0), BOUNDS, decimals=3)
    assert m.b == (9.123, 5.0, 1.0)  # rounded, kept inside the box
    np.testing.assert_array_equal(m.seeds(), parse_seed_spec(m.spec()))
    t = r.moved("middle", np.array(r.handles()["middle"]) + (0, 10, 0), BOUNDS, 3)
    assert t.a[1] == t.b[1] == 5.0  # a translation stops at the box for every handle
    p = r.as_kind("plane").moved("origin", (2.0, 2.0, 0.5), BOUNDS, 3)
    h = r.as_kind("plane").handles()
    np.testing.assert_allclose(p.handles()["u"], h["u"])  # the other corners stay
    np.testing.assert_allclose(p.handles()["v"], h["v"])
    flat = p.moved("v", p.handles()["u"], BOUNDS, 3)
    assert flat == p  # u and v parallel: refused
    assert p.more().counts == (p.counts[0] + 1, p.counts[1] + 1)
    assert r.with_counts(0).counts == (1,)
    with pytest.raises(SeedError, match="a rake is a line"):
        Rake.from_spec("box:0,0,0:1,1,1:3")


SCENE = """\
version = 1
[field]
dataset = "hotroom"
snapshot = 0
[seeds]
spec = "line:2,1,2:8,1,8:12"
[trace]
direction = "both"
max_length = 3.0
spacing = 0.1
[styles]
plain = "plain.toml"
[views.v]
camera = { azimuth = -70, elevation = 25, up = [0, 1, 0] }
"""
STYLE = """\
version = 1
background = "#000000"
antialias = "none"
[[bands]]
color = { cmap = "gray", attribute = "speed", range = [0.0, 0.1] }
width = 2.0
"""


def test_rake_drag_retraces_and_saved_spec_traces_the_same(display, tmp_path, capsys):
    from flowkit.cli import main
    from flowkit.datasets import hotroom_path
    from flowkit.io.lines_h5 import read_lines
    from flowkit.view.app import Viewer
    from flowkit.view.seeding import open_scene

    (tmp_path / "plain.toml").write_text(STYLE)
    (tmp_path / "scene.toml").write_text(SCENE)
    s = open_scene(tmp_path / "scene.toml")
    assert s.seeding.rake.spec() == "line:2.0,1.0,2.0:8.0,1.0,8.0:12"
    v = Viewer(s.lines, s.style_path, size=(320, 200), vsync=False, camera=s.camera,
               seeding=s.seeding, units=s.units)
    try:
        v.show_panel = False
        v.step()
        before = v.renderer.read()
        assert v.retraces == 0 and v.image().shape == (200, 320, 4)
        x, y = v.handle_xy("end")
        assert v.grab(x + 3, y - 2) == "end"  # within the grab radius
        v.on_drag(-50, -25)  # as the cursor callback does while the button is held
        v.release()
        v.step()
        assert v.retraces == 1 and v.rake != s.seeding.rake
        np.testing.assert_allclose(v.handle_xy("end"), (x - 50, y - 25), atol=1.5)  # followed
        after = v.renderer.read()
        assert (np.abs(after.astype(int) - before).sum(axis=2) > 0).sum() > 200
        v.step()
        assert v.retraces == 1  # nothing moved: nothing traced
        path = v.save_seeds()
        assert path == tmp_path / "scene.seeds"
        spec = path.read_text().strip()
        assert spec == v.rake.spec() and f"saved seeds to {path}" in capsys.readouterr().out
        out = tmp_path / "cli.h5"
        assert main(["trace", str(hotroom_path()), "-o", str(out), "--seeds", spec,
                     "--direction", "both", "--max-length", "3", "--spacing", "0.1",
                     "--attributes", "speed", "--float64", "--quiet"]) == 0
        cli = read_lines(out)
        np.testing.assert_array_equal(cli.offsets, v.lines.offsets)
        np.testing.assert_allclose(cli.points, v.lines.points, rtol=0, atol=1e-12)
        np.testing.assert_allclose(cli.point_data["speed"], v.lines.point_data["speed"],
                                   rtol=1e-12)
    finally:
        v.close()


def test_rake_drag_reuses_the_renderer_and_draws_as_a_new_one(display, tmp_path, monkeypatch):
    """Lines traced again during a drag go into the renderer's own buffers: no new renderer,
    program, vertex array, texture or buffer per drag, and the frame is the picture a fresh
    renderer of those lines draws."""
    from flowkit.render import renderer as renderer_module
    from flowkit.view.app import Viewer
    from flowkit.view.seeding import open_scene

    (tmp_path / "plain.toml").write_text(STYLE)
    (tmp_path / "scene.toml").write_text(SCENE)
    s = open_scene(tmp_path / "scene.toml")
    v = Viewer(s.lines, s.style_path, size=(320, 200), vsync=False, camera=s.camera,
               seeding=s.seeding, units=s.units)
    try:
        v.show_panel = False
        v.step()
        r = v.renderer
        vaos, compiles, allocations = dict(r._vaos), r.programs.compiles, r.allocations
        made = []
        real_init = renderer_module.LineRenderer.__init__

        def counting_init(self, *args, **kwargs):
            made.append(self)
            real_init(self, *args, **kwargs)

        monkeypatch.setattr(renderer_module.LineRenderer, "__init__", counting_init)
        for k in range(4):
            x, y = v.handle_xy("end")
            assert v.grab(x, y) == "end"
            v.on_drag(-12 if k % 2 else 15, 5)
            n = v.retraces
            v.step()  # while the handle is held: traced live while that keeps up
            if k == 0:  # no re-trace timed yet: live
                assert v.retraces == n + 1 and v.live_time() == v.reseed_time > 0
            v.release()
            v.step()
        assert v.retraces >= 4 and v.rake != s.seeding.rake
        assert made == [] and v.renderer is r  # not rebuilt for the new lines
        assert r.programs.compiles == compiles  # the compiled programs serve the new lines
        assert r._vaos == vaos and all(r._vaos[k] is vaos[k] for k in vaos)
        assert r.allocations == allocations  # textures and buffers written in place
        assert r.lines is v.lines and r.uploaded_attributes() == ["speed"]
        live = v.renderer.read()
        monkeypatch.undo()
        with renderer_module.LineRenderer(v.lines, v.ctx, bounds=r.bounds) as fresh:
            fresh.draw(v.style, tuple(v.scene_size), v.camera)
            still = fresh.read()
        np.testing.assert_array_equal(live, still)
    finally:
        v.close()


def test_scene_with_inline_style_needs_a_style_file(tmp_path):
    from flowkit.view.seeding import open_scene

    (tmp_path / "scene.toml").write_text(SCENE.replace('plain = "plain.toml"', textwrap.dedent(
        """\
        [styles.plain]
        bands = [{ color = "#ffffff", width = 2 }]""")))
    with pytest.raises(ValueError, match="inline.*--style"):
        open_scene(tmp_path / "scene.toml")
