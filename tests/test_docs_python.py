"""docs/python.md runs as written: its Python blocks, one after the other in one namespace, in
a folder of their own; what they print and write is checked, so the page cannot drift."""

import re
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parent.parent


def test_the_python_tour_runs_as_written(tmp_path, monkeypatch, capsys):
    text = (ROOT / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    assert len(blocks) >= 5
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    for code in blocks:
        exec(compile(code, "docs/python.md", "exec"), ns)  # noqa: S102 (our own docs page)
    out = capsys.readouterr().out
    assert "arrays (point data):" in out and "U [m/s]: vector (3), float32" in out
    assert "<Lines: 50 lines" in out and "reasons:" in out
    assert len(ns["hot"]) == 200 and len(ns["even"]) > 10
    assert len(ns["df"]) == ns["lines"].n_points
    assert not ns["field"].scalars.in_memory("p")  # the tour never needed p
    assert Image.open("overview.png").size == (640, 360)
    assert Path("lines.h5").exists() and Path("exact.h5").exists()
