"""``flowkit compile`` warms the cache: a fresh process with an empty cache compiles the kernels
the default options need, and a second process then finds every one of them cached."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from flowkit import warmup

ROOT = Path(__file__).resolve().parent.parent


def _compile(cache: Path, *what: str) -> str:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "flowkit", "compile", *what], env=env,
                          capture_output=True, text=True, timeout=900, check=True).stdout


SCENE_RUN = """
from numba.core import event
compiled = []
class C(event.Listener):
    def on_start(self, ev):
        pass
    def on_end(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__module__)
event.register("numba:compile", C())
import sys
from flowkit.scene import run_scene
run_scene(sys.argv[1], out_dir=sys.argv[2], cache_dir=sys.argv[2] + "/cache")
print(sorted(set(m for m in compiled if m.startswith("flowkit"))))
"""


def test_compile_then_a_second_process_finds_everything_cached(tmp_path):
    """``flowkit compile default SCENE`` (what make install runs for the demo) compiles what
    the scene runs: its trace options and the renderer's level-of-detail kernels, so a second
    compile finds everything cached and the scene after it compiles none of flowkit's
    functions."""
    cache = tmp_path / "numba"
    scene = ROOT / "examples" / "hotroom_scene.toml"
    first = _compile(cache, "default", str(scene))
    m = re.search(r"^default: compiled (\d+) functions in ([\d.]+) s", first, re.MULTILINE)
    assert m and int(m[1]) >= 5 and float(m[2]) > 1.0, first
    assert f"cache: {cache}" in first
    assert list(cache.rglob("kernel._advance_lines-*.nbi"))  # the tracing kernel is stored
    second = _compile(cache)
    assert re.search(r"^default: all from the cache \(", second, re.MULTILINE), second
    assert "compiled 0 functions in 0.0 s" in second
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", SCENE_RUN, str(scene), str(tmp_path / "out")],
                         env=env, capture_output=True, text=True, timeout=900, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]", out


def test_what_to_compile_is_checked_before_anything_compiles(tmp_path):
    with pytest.raises(ValueError, match="'bogus' is neither an option set .*default.*all"):
        warmup.jobs(["default", "bogus"])
    bad = tmp_path / "scene.toml"
    bad.write_text("version = 1\n[trace]\nmethodd = 'rk4'\n")
    with pytest.raises(ValueError, match="scene.toml"):
        warmup.jobs([str(bad)])
    assert [label for label, _ in warmup.jobs(["all"])] == [
        f"{n}{t}" for n in warmup.OPTION_SETS for t in ("", " (float32)")]
    assert [label for label, _ in warmup.jobs(["rk4"], ["float32"])] == ["rk4 (float32)"]
    with pytest.raises(ValueError, match="'int8' is not one of float64, float32"):
        warmup.jobs(["default"], ["int8"])


EVEN_RUN = SCENE_RUN.split("import sys")[0] + """
from flowkit import datasets
from flowkit.seeding import trace_spec
trace_spec(datasets.hotroom(), "even:1/30d", max_length=12.0, direction="both")
print(sorted(set(m for m in compiled if m.startswith("flowkit"))))
"""


def test_compile_even_warms_the_evenly_spaced_seeder(tmp_path):
    """``flowkit compile even`` compiles the seeder's pick and walk beside the tracing kernel:
    evenly spaced lines on real data then compile none of flowkit's functions."""
    cache = tmp_path / "numba"
    first = _compile(cache, "even")
    assert re.search(r"^even: compiled \d+ functions", first, re.MULTILINE), first
    assert list(cache.rglob("even._pick-*.nbi")) and list(cache.rglob("even._walk-*.nbi"))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", EVEN_RUN], env=env, capture_output=True,
                         text=True, timeout=900, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]", out


def test_a_scene_with_evenly_spaced_seeds_warms_the_seeder(tmp_path, monkeypatch):
    scene = tmp_path / "even.toml"
    scene.write_text((ROOT / "examples" / "hotroom_scene.toml").read_text()
                     .replace('spec = "plane:1,0.6,1:8,0,0:0,0,8:8,8"', 'spec = "even:1/20d"')
                     .replace('halo = "styles/halo.toml"',
                              f'halo = "{ROOT / "examples" / "styles" / "halo.toml"}"'))
    seen = []
    monkeypatch.setattr(warmup, "_trace", lambda opts, even=None, dtype=None: seen.append(even))
    monkeypatch.setattr(warmup, "_render", lambda plan, lines: None)
    for _, run in warmup.jobs([str(scene), str(ROOT / "examples" / "hotroom_scene.toml")]):
        run()
    assert seen == [warmup.EVEN_SPEC, None]
