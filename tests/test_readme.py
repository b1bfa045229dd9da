"""The README's examples run as written: the Python example on the demo data it names as the
alternative to a user's file (``flowkit.datasets.hotroom()`` after a plain ``import flowkit``),
and every ``flowkit ...`` line of its shell blocks on the heated room's own foamToVTK files
(``run.vtu`` is one snapshot, ``run_*.vtu`` two), so the README cannot drift from the CLI."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
from PIL import Image

from flowkit.cli import main

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT / ".." / "shared" / "datasets" / "hotroom"
# appended to `flowkit bench precision --quick` (a CI smoke already, still a minute): one
# problem, few seeds, no peers; test_precision_smoke checks its table
BENCH_NARROW = ["--no-peers", "--seeds", "4", "--problems", "rotation"]
# appended to the animation's line: its 24 frames at the style's full size take 90 s on llvmpipe
SMALL = ["--size", "320x180"]


def readme_commands() -> list[list[str]]:
    """Every ``flowkit ...`` command of the README's shell blocks, continuations joined."""
    text = (ROOT / "README.md").read_text()
    out = []
    for block in re.findall(r"```sh\n(.*?)```", text, re.DOTALL):
        for line in block.replace("\\\n", " ").splitlines():
            argv = shlex.split(line, comments=True)
            if argv and argv[0] == "flowkit":
                out.append(argv[1:])
    return out


def test_readme_python_example_runs(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    assert blocks, "the README has no Python example"
    load = 'flowkit.fields.load_field("run.vtu", vector="U")'
    code = blocks[0]
    assert load in code and "flowkit.datasets.hotroom()" in code
    code = code.replace(load, "flowkit.datasets.hotroom()")
    code = code.replace('"examples/', f'"{ROOT}/examples/')  # its paths are the checkout's
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})  # noqa: S102 (the project's own README)
    import flowkit

    lines = flowkit.read_lines(tmp_path / "lines.h5")
    assert len(lines) == 50 and {"speed", "T"} <= set(lines.point_data)
    img = np.asarray(Image.open(tmp_path / "halo.png"))
    assert img.shape[:2] == (1080, 1920) and img.reshape(-1, img.shape[-1]).std(axis=0).max() > 0


def test_readme_flowkit_lines_run(tmp_path, monkeypatch, capsys, display):
    cmds = readme_commands()
    assert [c[0] for c in cmds] == ["info", "info", "trace", "trace", "trace", "info", "sample",
                                    "resample", "render", "render",
                                    "render", "scene", "view", "view", "trace", "bench",
                                    "compile"], cmds
    (tmp_path / "run.vtu").symlink_to((SHARED / "hotroom_t2000.vtu").resolve())
    for t in ("0400", "2000"):
        (tmp_path / f"run_{t}.vtu").symlink_to((SHARED / f"hotroom_t{t}.vtu").resolve())
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    from flowkit.view.app import Viewer

    drawn = []

    def run_briefly(self):  # the window opens and draws; a user would close it
        for _ in range(3):
            self.step()
        drawn.append(self.error)
        self.close()

    monkeypatch.setattr(Viewer, "run", run_briefly)
    outputs = {}
    for argv in cmds:
        if argv[0] == "bench":
            argv = argv + BENCH_NARROW + ["--out", str(tmp_path / "bench")]
        elif "--frames" in argv:
            argv = argv + SMALL
        rc = main(argv)
        out, err = capsys.readouterr()
        assert rc == 0, (argv, err[-2000:])
        outputs.setdefault(argv[0], []).append(out)
        if argv[:2] == ["trace", "run.vtu"]:  # the lines file the next lines read
            lines = __import__("flowkit").read_lines("lines.h5")
            assert len(lines) == 8 ** 3 and {"speed", "T", "time"} <= set(lines.point_data)
    assert "grid: uniform, shape (41, 21, 41)" in outputs["info"][0]
    assert "range [" not in outputs["info"][0] and "range [300" in outputs["info"][1]  # --stats
    info = outputs["info"][2]
    assert "lines: 512 " in info and re.search(r"^ +T +float64", info, re.MULTILINE)
    assert Image.open("halo.png").size == (1920, 1080) and Image.open("overview.png").size
    reasons = __import__("flowkit").read_lines("even.h5").line_data["reason"]
    assert (reasons == __import__("flowkit").integrate.reasons.Reason.TOO_CLOSE).any()
    assert len(__import__("flowkit").read_lines("hot.h5")) == 500
    grid = __import__("flowkit").fields.load_field("grid.h5")
    assert grid.grid.shape == (81, 41, 81) and "0 of 269001 nodes lie in no cell" in grid.notes[0]
    gif = Image.open("arrows.gif")
    assert gif.n_frames == 24 and gif.size == (320, 180)
    assert "attributes traced: speed, T" in outputs["scene"][0]
    assert drawn == [None, None]  # the lines file, and the scene with live seeding
    assert re.search(r"^examples/hotroom_scene.toml: (all from the cache|compiled)",
                     outputs["compile"][0], re.MULTILINE)
    # the series traced on two workers: the last command of the trace lines wrote lines.h5
    series = __import__("flowkit").read_lines("lines.h5")
    assert len(series) == 2 * 1000 and "snapshot" in series.line_data
