"""Empty or meaningless results are errors with a one-line reason, found before any work where
they can be: seeds all outside, lines of one vertex, a picture with nothing or everything
drawn, an output directory that does not exist; lines creeping along a wall stagnate."""

from __future__ import annotations

import numpy as np
import pytest

from flowkit import Field, Grid, trace, trace_to_file, write_lines
from flowkit.cli import main
from flowkit.fields.analytic import UniformFlow
from flowkit.fields.writers import save_field
from flowkit.integrate.reasons import Reason
from flowkit.integrate.trace import EmptyResultError
from flowkit.lines import Lines


@pytest.fixture()
def field_file(tmp_path):
    return save_field(UniformFlow(U=(1.0, 0.0, 0.0)).to_field(5), tmp_path / "u.npz")


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_trace_with_every_seed_outside_exits_non_zero_and_writes_nothing(field_file, tmp_path,
                                                                         capsys):
    out = tmp_path / "lines.h5"
    assert main(["trace", str(field_file), "-o", str(out), "--seeds", "points:5,5,5:-3,0,0", "--max-length", "9",
                 "--quiet"]) == 2
    assert "no seed lies inside the domain: all 2 seeds" in _one_line(capsys)
    assert not out.exists()
    with pytest.raises(EmptyResultError, match="no seed lies inside"):
        trace_to_file(UniformFlow().to_field(5), [[5.0, 5, 5]], out)
    assert not out.exists()


def test_output_directory_is_checked_before_any_work(tmp_path, capsys):
    missing = tmp_path / "no_such_dir" / "lines.h5"
    # the field does not exist either: the output is checked first
    assert main(["trace", str(tmp_path / "absent.npz"), "-o", str(missing), "--quiet"]) == 2
    assert f"directory {missing.parent} does not exist" in _one_line(capsys)
    assert main(["render", str(tmp_path / "absent.h5"), "-o", str(missing.with_suffix(".png"))]) == 2
    assert f"directory {missing.parent} does not exist" in _one_line(capsys)


def test_render_of_lines_with_one_vertex_is_an_error(tmp_path, capsys):
    lines = Lines(np.array([[0.1, 0.2, 0.3], [0.5, 0.5, 0.5]]), [0, 1, 2],
                  {"speed": np.zeros(2)}, {"reason": np.array([Reason.STAGNATION] * 2, np.int8)})
    path = write_lines(lines, tmp_path / "still.h5")
    out = tmp_path / "still.png"
    assert main(["render", str(path), "-o", str(out), "--size", "64x48"]) == 2
    msg = _one_line(capsys)
    assert "nothing to draw" in msg and "stagnation 2" in msg
    assert not out.exists()


def test_render_that_covers_everything_or_nothing_is_an_error(tmp_path, capsys):
    t = np.linspace(0, 1, 20)[:, None]
    lines = Lines(np.r_[t * [1, 0, 0], t * [0, 1, 1]], [0, 20, 40])
    path = write_lines(lines, tmp_path / "l.h5")
    wide = tmp_path / "wide.toml"
    wide.write_text('version = 1\n[[bands]]\ncolor = "#000000"\nwidth = 1e9\n')
    out = tmp_path / "o.png"
    assert main(["render", str(path), "--style", str(wide), "-o", str(out), "--size", "64x48"]) == 2
    assert "a line is 2e+09 pixels wide, wider than the 64x48 image" in _one_line(capsys)
    clear = tmp_path / "clear.toml"
    clear.write_text('version = 1\nbackground = "#ffffff"\n[[bands]]\ncolor = "#ffffff"\nwidth = 2\n')
    assert main(["render", str(path), "--style", str(clear), "-o", str(out), "--size", "64x48"]) == 2
    assert "the picture shows no line" in _one_line(capsys)
    assert not out.exists()
    ok = tmp_path / "ok.toml"
    ok.write_text('version = 1\nbackground = "#ffffff"\n[[bands]]\ncolor = "#000000"\nwidth = 2\n')
    assert main(["render", str(path), "--style", str(ok), "-o", str(out), "--size", "64x48"]) == 0
    assert out.exists()


def test_a_line_creeping_along_a_wall_stagnates_by_the_fields_typical_speed():
    """Air at 0.1 m/s slowing to 1e-6 m/s over the last fifth before a wall: the line ends by
    the stagnation rule (1e-4 of the typical speed), not after days of creeping."""
    x = np.linspace(0, 1, 51)
    g = Grid.from_axes(x, np.linspace(0, 0.1, 3), np.linspace(0, 0.1, 3))
    speed = np.interp(x, [0, 0.8, 0.85, 1.0], [0.1, 0.1, 1e-6, 1e-6])
    v = np.zeros(g.shape + (3,))
    v[..., 0] = speed[:, None, None]
    lines = trace(Field(g, v), [[0.05, 0.05, 0.05]], attributes=["time"])
    assert lines.line_data["reason"].tolist() == [Reason.STAGNATION]
    assert lines.point_data["time"][-1] < 100.0  # seconds: 8 of flow, then a short creep


def test_scene_output_directory_is_checked_before_tracing(tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text('version = 1\n[field]\ndataset = "hotroom"\n[seeds]\nspec = "points:5,2,5"\n'
                     '[trace]\nmax_length = 2.0\n[styles.s]\n[[styles.s.bands]]\nwidth = 2\n')
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main(["scene", str(scene), "--out", str(blocker / "out"), "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert f"output directory {blocker / 'out'}" in err and "snapshot" not in err  # no stage ran
