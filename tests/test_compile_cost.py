"""Compile cost cannot creep back silently: what a default trace compiles, counted.

A fresh process with an empty numba cache runs the default trace (and the demo scene's options:
both directions, resampled output, attributes); every compiled function of the kernel must
then have exactly one specialization (a literal argument, an int64/uint64 loop index or a
second dtype would add one: each costs seconds on every fresh machine), and the lock-step,
which only fixed-step plain traces use, must not have been compiled at all.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

# helper_sigs.py's functions compiled or loaded for argument types its entries do not name (a
# helper loaded inside its cached caller has no signature of its own here; a helper of the step
# loop's evaluator has an entry per variant)
STALE = """
import importlib
from flowkit.helper_sigs import HELPERS
from flowkit.parallel_compile import for_type
named = {}
for table in HELPERS.values():
    for m, n, sig in table:  # (the heated room is stored as float32: float32 nodes too)
        named.setdefault((m, n), set()).update({sig, for_type(sig, "float32")})
stale = [n for (m, n), sigs in named.items()
         if not set(getattr(importlib.import_module(m), n).signatures) <= sigs]
"""
CODE = """
import hashlib, json, logging, os
import numba
from numba.core import event
compiled = []
class C(event.Listener):
    def on_start(self, ev):
        pass
    def on_end(self, ev):
        f = ev.data["dispatcher"].py_func
        if f.__module__.startswith("flowkit."):
            compiled.append(f.__qualname__)
event.register("numba:compile", C())
import flowkit
from flowkit import datasets
from flowkit.integrate import kernel as K, lanes, seeds
notices = []
class H(logging.Handler):
    def emit(self, record):
        notices.append(record.getMessage())
logging.getLogger("flowkit.compile").addHandler(H())
logging.getLogger("flowkit.compile").setLevel(logging.INFO)
f = datasets.hotroom()
s = seeds.line((1, 1, 1), (9, 1, 9), 16)
digest = hashlib.sha256()
for opts in ({}, {"direction": "both", "spacing": 0.1, "rtol": 1e-6}, {"method": "dop853"}):
    digest.update(flowkit.trace(f, s, max_length=5, **opts).points.tobytes())
sigs = {n: [str(x) for x in d.signatures] for n, d in vars(K).items()
        if isinstance(d, numba.core.registry.CPUDispatcher)}
""" + STALE + """
table = HELPERS["flowkit.integrate.kernel._advance_lines"]
from flowkit import parallel_compile
turns = parallel_compile._turns  # the helpers the second process claimed (None: none started)
theirs = [] if turns is None else [k[1] for k in table if k not in turns.mine
                                   and os.path.exists(turns._path(k) + ".claim")]
print(json.dumps({"sigs": sigs, "lockstep": len(lanes.lockstep.signatures), "notices": notices,
                  "compiled": compiled, "points": digest.hexdigest(), "stale": stale,
                  "table": sorted(n for m, n, sig in table), "theirs": theirs}))
"""


def _cold_run(tmp_path, code, parallel):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / f"numba{parallel}"),
               FLOWKIT_PARALLEL_COMPILE=str(parallel))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=900, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_default_trace_compiles_one_specialization_of_each_function(tmp_path):
    """Each function once, alone and with a second compile process.  With two cores the first
    trace's helpers are shared between this process and a second one (flowkit.parallel_compile):
    this process compiles fewer of them than alone, loads the others from the disk cache, and
    the lines are the same bits."""
    together = _cold_run(tmp_path, CODE, 1)
    alone = _cold_run(tmp_path, CODE, 0)
    for res in (together, alone):
        sigs = res["sigs"]
        assert len(sigs["_advance_lines"]) == 1
        many = {n: s for n, s in sigs.items() if len(s) > 1}
        assert not many, f"functions compiled more than once: {many}"
        assert res["lockstep"] == 0  # not compiled for adaptive or cell-aware traces
        # the compilation took seconds: the user was told, once
        assert any("compiling the tracing kernel for this CPU, once" in m for m in res["notices"])
        assert len(res["notices"]) == len(set(res["notices"]))
    assert together["points"] == alone["points"]
    # that process's table (helper_sigs.py) names every helper the kernel asks for, with the
    # argument types it asks for (else: python -m flowkit.write_helper_sigs)
    assert not alone["stale"], f"helper_sigs.py is stale for {alone['stale']}"
    helpers = {n for n, sig in alone["sigs"].items() if sig and n != "_advance_lines"}
    assert helpers <= set(alone["table"]), helpers - set(alone["table"])
    assert set(alone["table"]) <= set(alone["compiled"])
    from flowkit import parallel_compile

    if parallel_compile.enabled():  # (two cores or more: a second process was started)
        loaded = set(alone["compiled"]) - set(together["compiled"])
        assert len(loaded) >= 5, f"the second process compiled only {sorted(loaded)}"
        # they took turns: nothing the other process claimed was compiled here as well
        assert together["theirs"] and not set(together["theirs"]) & set(together["compiled"])


def test_turns_wait_for_the_claimant_and_not_for_a_dead_one(tmp_path, monkeypatch):
    """A helper the other process claimed is waited for until its done file appears (then
    loaded, not compiled); not once the other process has ended; and a claim is taken once."""
    import threading
    import time

    from flowkit import parallel_compile
    from flowkit.integrate import kernel

    key = next(k for k in parallel_compile._Turns(str(tmp_path), bool).table if k[1] == "_norm3")
    alive = threading.Event()
    alive.set()
    theirs = parallel_compile._Turns(str(tmp_path), alive.is_set)
    ours = parallel_compile._Turns(str(tmp_path), alive.is_set)
    assert theirs.claim(key) and theirs.claim(key) and not ours.claim(key)
    monkeypatch.setattr(parallel_compile, "_turns", ours)
    monkeypatch.setattr(kernel._norm3, "overloads", {})  # as in a process that has not compiled it
    threading.Timer(0.3, theirs.done, (key,)).start()
    t = time.monotonic()
    with parallel_compile.turn(kernel._norm3, key[2]):
        waited = time.monotonic() - t
    assert 0.25 < waited < 5.0
    key2 = next(k for k in ours.table if k[1] == "_width")
    assert theirs.claim(key2)
    alive.clear()  # the other process ended without storing it: compile here, at once
    t = time.monotonic()
    with parallel_compile.turn(kernel._width, key2[2]):
        assert time.monotonic() - t < 2.0  # (not WAIT_S: a loaded machine may pause it briefly)


OPTIONS_CODE = """
import json
import numpy as np
import numba
import flowkit
from flowkit import datasets
from flowkit.fields import curl, interp
from flowkit.fields.analytic import ABCFlow
from flowkit.integrate import kernel as K, lanes, pathlines as P, rosenbrock as R, seeds, stiffness
from flowkit.integrate import unsteady
f = datasets.hotroom()
s = seeds.line((1, 1, 1), (9, 1, 9), 8)
f.sample(s)
f.sample_scalar("T", s)
flowkit.trace(f, s, max_length=3, method="ros34pw2", direction="both")
series = ABCFlow().to_series([0.0, 1.0], shape=12, bounds=[[0, 2 * np.pi]] * 3)
for _, snap in series:  # float32, as the heated room is stored: one type for every kernel
    snap.vector = snap.vector.astype(np.float32)
P.pathlines(series, s[:, [0, 0, 2]] * 0.5, max_time=0.5, attributes=["speed", "vorticity"])
flowkit.trace(f, s, max_length=3, attributes=["vorticity"])
flowkit.trace(f, s, max_length=3, method="rk4", step=0.1, cell_aware=False)  # the lock-step
flowkit.trace(f, s, max_length=3, cell_aware=False, rtol=1e-6)
""" + STALE + """
print(json.dumps({m.__name__: {n: len(d.signatures) for n, d in vars(m).items()
                               if isinstance(d, numba.core.registry.CPUDispatcher)
                               and d.py_func.__module__ == m.__name__}
                  for m in (interp, curl, K, P, R, unsteady, lanes, stiffness)} | {"stale": stale}))
"""


def test_attributes_pathlines_rosenbrock_lanes_compile_one_specialization_each(tmp_path):
    """A literal argument or a prange index compiles a helper once more per value or type (each
    seconds on a fresh machine): with an empty cache (a helper loaded inside its caller's cached
    code is not counted), every compiled function of the samplers, the vorticity, the pathline and the
    Rosenbrock integrators, the lock-step and the kernel helpers they share has one signature
    at most; and each helper helper_sigs.py names for them is compiled for the types it says."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), FLOWKIT_LOCKSTEP_WAIT="1")
    out = subprocess.run([sys.executable, "-c", OPTIONS_CODE], env=env, capture_output=True,
                         text=True, timeout=900, check=True).stdout
    counts = json.loads(out.strip().splitlines()[-1])
    stale = counts.pop("stale")
    assert not stale, f"helper_sigs.py is stale for {stale}: python -m flowkit.write_helper_sigs"
    # the step loop once per variant: explicit, with the Rosenbrock stepper, for pathlines; its
    # stage once per evaluator
    assert counts["flowkit.integrate.kernel"].pop("_advance_lines") == 3
    assert counts["flowkit.integrate.kernel"].pop("_stage") == 2
    many = {m: {n: c for n, c in d.items() if c > 1} for m, d in counts.items()}
    assert not any(many.values()), f"compiled more than once: {many}"
    assert counts["flowkit.fields.interp"]["_sample_range"] == 1
    assert counts["flowkit.fields.curl"]["_curl_range"] == 1  # the vorticity's node curl
    assert counts["flowkit.integrate.lanes"]["lockstep"] == 1
    assert counts["flowkit.integrate.kernel"]["_dense"] == 1  # shared by every driver


def test_no_helper_uses_numbas_ir_inlining():
    """numba's IR inlining types and lowers a copy of a helper at every call site (it tripled
    the tracing kernel's compile time); helpers use flowkit.jit.inline (LLVM inlines them)."""
    import re
    from pathlib import Path

    import flowkit

    root = Path(flowkit.__file__).parent
    ir_inline = re.compile(r"jit\([^)]*\binline\s*=")
    users = [str(p.relative_to(root)) for p in root.rglob("*.py") if ir_inline.search(p.read_text())]
    assert not users, f"numba IR inlining in {users}: use flowkit.jit.inline"


def test_import_leaves_scipy_integrate_unloaded():
    """Every process pays flowkit's import (each CLI call, test subprocess, Dask worker):
    scipy.integrate's package import is ~0.4 s of it, and the method registry needs only its
    DOP853 coefficient table (the numbers, checked against scipy's own module here)."""
    code = ("import sys, flowkit\n"
            "from flowkit.integrate.methods import get_method\n"
            "m = get_method('dop853')\n"
            "loaded = 'scipy.integrate' in sys.modules\n"
            "from scipy.integrate._ivp import dop853_coefficients as dc\n"
            "import numpy as np\n"
            "same = all(np.array_equal(x, y) for x, y in ((m.c, dc.C), (m.a, dc.A)))\n"
            "print(loaded, same)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "True"]


def test_second_compile_process_only_where_it_helps(monkeypatch):
    """Not on one core (a container's CPU set counts, not the host's), not when switched off,
    not where sys.executable is a program that embeds Python (it would be started instead),
    and never when numba's disk cache already holds the kernel (a warm machine starts none)."""
    import flowkit
    from flowkit import datasets, numba_cache, parallel_compile
    from flowkit.integrate import kernel, seeds

    flowkit.trace(datasets.hotroom(), seeds.line((1, 1, 1), (9, 1, 9), 4), max_length=1)
    assert numba_cache.in_disk_cache(kernel._advance_lines)
    name = "flowkit.integrate.kernel._advance_lines"
    monkeypatch.setattr(parallel_compile, "_started", set())
    monkeypatch.setattr(kernel._advance_lines, "overloads", {})  # as in a fresh process
    assert parallel_compile.start(name, kernel._advance_lines) is None  # cached: none started
    monkeypatch.setattr(parallel_compile, "_cores", lambda: 2)
    assert parallel_compile.enabled()
    monkeypatch.setenv("FLOWKIT_PARALLEL_COMPILE", "0")
    assert not parallel_compile.enabled()
    monkeypatch.delenv("FLOWKIT_PARALLEL_COMPILE")
    monkeypatch.setattr(parallel_compile, "_cores", lambda: 1)
    assert not parallel_compile.enabled()
    monkeypatch.setattr(parallel_compile, "_cores", lambda: 2)
    for exe in ("/opt/blender/blender", "/usr/bin/uwsgi", ""):  # Python embedded in a program
        monkeypatch.setattr(sys, "executable", exe)
        assert not parallel_compile.enabled()


def test_second_process_compiles_the_next_kernels_helpers_only_while_its_parent_lives(tmp_path):
    """After the tracing kernel's helpers, the second process compiles the helpers of its
    Rosenbrock and pathline variants (helper_sigs.py), but only while the process that started it lives: its
    standard input is that process's pipe, closed at exit.  Two second processes side by side on
    empty caches: one whose parent keeps the pipe open until it ends, one started on a closed
    input (a parent that has exited)."""
    from flowkit import parallel_compile
    from flowkit.helper_sigs import HELPERS

    kernel = "flowkit.integrate.kernel._advance_lines"
    procs = {}
    for alive in (True, False):
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / str(alive)))
        procs[alive] = subprocess.Popen(
            [sys.executable, "-m", "flowkit.parallel_compile", kernel], env=env,
            stdin=subprocess.PIPE if alive else subprocess.DEVNULL)
    for proc in procs.values():
        assert proc.wait(timeout=600) == 0
    procs[True].stdin.close()

    first = {n for m, n, sig in HELPERS[kernel]}

    def cached(alive, table):  # the helpers of a table that the process left in its cache
        return {n for m, n, sig in HELPERS[table]
                if any((tmp_path / str(alive)).rglob(f"*.{n}-*.nbi"))}

    for nxt in parallel_compile.NEXT[kernel]:  # (a helper of both tables: the first's)
        names = {n for m, n, sig in HELPERS[nxt]} - first
        assert names and cached(True, nxt) >= names
        assert not cached(False, nxt) - first
    assert cached(False, kernel) == {n for m, n, sig in HELPERS[kernel]}


def test_the_compile_notices_name_kernels_that_exist():
    """Each kernel the notices describe by name is a numba function where the table says (a
    renamed kernel would fall back to "a flowkit kernel" without its typical seconds)."""
    import importlib

    from numba.core.registry import CPUDispatcher

    from flowkit.compile_notice import TYPICAL

    for qualified in TYPICAL:
        module, name = qualified.split(":")[0].rsplit(".", 1)
        assert isinstance(getattr(importlib.import_module(module), name), CPUDispatcher), qualified
