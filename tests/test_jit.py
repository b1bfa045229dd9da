"""numba's private API is an accelerator, never a requirement: a numba without what flowkit's
accelerators use still imports flowkit and traces the same lines, bit for bit, on public numba
alone (flowkit/numba_private.py)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CODE = """
import hashlib, json, sys
if sys.argv[1] == "renamed":  # what a numba release that renames one pass class looks like
    import numba.core.typed_passes as tp
    del tp.NopythonTypeInference
import numpy as np
import flowkit
from flowkit import jit, numba_private
from flowkit.fields.analytic import ABCFlow
from flowkit.integrate.pathlines import pathlines
f = ABCFlow().to_field(12, bounds=[[0, 2 * np.pi]] * 3, periodic=True)
s = np.array([[1.0, 2.0, 3.0], [4.0, 1.0, 0.5], [2.5, 5.0, 4.0], [0.3, 0.3, 6.0]])
runs = {"default": {}, "both, vorticity, T": {"direction": "both", "attributes": ["vorticity"]},
        "dop853": {"method": "dop853"}, "rk4 lock-step": {"method": "rk4", "step": 0.1,
        "cell_aware": False}, "ros34pw2": {"method": "ros34pw2"}}
out = {}
for name, opts in runs.items():
    lines = flowkit.trace(f, s, max_length=4.0, **opts)
    h = hashlib.sha256(lines.points.tobytes() + lines.offsets.tobytes())
    for k in sorted(lines.point_data):
        h.update(lines.point_data[k].tobytes())
    out[name] = (h.hexdigest(), lines.points.shape[0])
series = ABCFlow().to_series([0.0, 1.0], shape=10, bounds=[[0, 2 * np.pi]] * 3, periodic=True)
p = pathlines(series, s, max_time=1.0)
out["pathlines"] = (hashlib.sha256(p.points.tobytes()).hexdigest(), p.points.shape[0])
print(json.dumps({"accelerated": jit.ACCELERATED, "why": numba_private.WHY, "lines": out}))
"""


def _run(mode, cache=None):
    env = dict(os.environ, FLOWKIT_LOCKSTEP_WAIT="1", PYTHONPATH=str(ROOT))
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache)
    p = subprocess.run([sys.executable, "-c", CODE, mode], env=env, capture_output=True,
                       text=True, timeout=900, cwd=ROOT, check=False)
    assert p.returncode == 0, p.stderr[-3000:]
    return json.loads(p.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_without_numbas_private_api_flowkit_imports_and_traces_the_same_lines(tmp_path):
    plain = _run("renamed", tmp_path / "numba")
    assert plain["accelerated"] is False and "NopythonTypeInference" in plain["why"]
    fast = _run("as is")
    assert fast["accelerated"] is True
    assert all(n > 10 for _, n in fast["lines"].values())
    assert plain["lines"] == fast["lines"]


def test_accelerators_can_be_switched_off(tmp_path):
    env = dict(os.environ, FLOWKIT_NUMBA_ACCELERATORS="0", PYTHONPATH=str(ROOT))
    code = ("from flowkit import jit, numba_private\n"
            "print(jit.ACCELERATED, numba_private.WHY)")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=300, check=True, cwd=ROOT).stdout
    assert out.startswith("False switched off")
