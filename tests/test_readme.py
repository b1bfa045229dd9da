"""The README's Python example runs as written, on the demo data it names as the alternative
to a user's file (``flowkit.datasets.hotroom()`` after a plain ``import flowkit``)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent


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
