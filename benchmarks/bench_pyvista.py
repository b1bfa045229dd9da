"""The same task written with flowkit's Python API and with PyVista's streamlines: lines of
code, wall time and error against a reference, on the ABC flow sampled on a grid.

The task, as a pipeline user has it: a ``pyvista.ImageData`` holding a velocity ``U``, seed
points and a length; trace forward lines of that arc length and hand back, per line, its
vertices and the speed along it.  Each variant is one function below, written as a user would
(each tool's defaults: flowkit dopri5 at rtol 1e-6; PyVista RK45 with max_error 1e-6, steps
in cell lengths).  PyVista takes seed points through ``streamlines_from_source``, the filter
its ``streamlines()`` builds a sphere or line of seeds for.

Measured:
- lines of code: the non-blank, non-comment lines of each task function's body (docstring
  left out), read from this file with ``inspect.getsource``;
- wall time: each task run once to warm up (numba's compiled kernels loaded, VTK's pipeline
  built), then twice, timed;
- whether the lines reach the length asked for: the true arc length of PyVista's lines from
  its own output (``peers.vtk_ends``: vtkStreamTracer's RK45 stops by a propagation that
  counts its next proposed step, not the step taken);
- the error at arc length ``length``: each tool's point there against (a) a tight scipy DOP853
  (rtol = atol = 1e-12) on the same trilinear interpolant, cell by cell (``common.
  cached_reference``: integration error only), and (b) the same on the analytic ABC velocity
  (integration plus the grid's interpolation error: what the user gets).  flowkit's lines end
  at ``length`` exactly (its last vertex); PyVista's point there is read from an untimed run
  of the same call with a longer ``max_length`` (the same steps), between the vertices around
  it (cubic Hermite), as bench_trace.py does for VTK.

    .venv/bin/python benchmarks/bench_pyvista.py    # writes benchmarks/results/bench_pyvista.log
"""

from __future__ import annotations

import argparse
import ast
import inspect
import sys
import textwrap
import time

import numba
import numpy as np
import pyvista as pv
from common import (
    RESULTS,
    Problem,
    abc_field,
    cached_reference,
    errors,
    machine,
    make_seeds,
    markdown_table,
)
from peers import VTKTracer, vtk_ends
from scipy.integrate import solve_ivp

import flowkit
from flowkit.fields.analytic import ABCFlow
from flowkit.integrate.reasons import Reason


# -- the two variants of the task ------------------------------------------------------------
def task_flowkit(grid, seeds, length):
    """Per line: (vertices, speed at them)."""
    field = flowkit.fields.from_pyvista(grid)
    lines = flowkit.trace(field, seeds, max_length=length, attributes=["speed"])
    return [(line.points, line.point_data["speed"]) for line in lines]


def task_pyvista(grid, seeds, length):
    """Per line: (vertices, speed at them)."""
    out = grid.streamlines_from_source(pv.PolyData(seeds), vectors="U", max_length=length,
                                       integration_direction="forward")
    speed = np.linalg.norm(out["U"], axis=1)
    cells, result, i = out.lines, [], 0
    while i < len(cells):  # VTK's cell array: n, then the n point ids of each line
        ids = cells[i + 1:i + 1 + cells[i]]
        result.append((out.points[ids], speed[ids]))
        i += cells[i] + 1
    return result


def lines_of_code(fn) -> int:
    """Non-blank, non-comment lines of ``fn``'s body, its signature and docstring left out."""
    node = ast.parse(textwrap.dedent(inspect.getsource(fn))).body[0]
    first = node.body[1 if ast.get_docstring(node) else 0]
    body = inspect.getsource(fn).splitlines()[first.lineno - 1:]
    return sum(1 for ln in body if ln.strip() and not ln.strip().startswith("#"))


# -- evaluation (untimed) --------------------------------------------------------------------
def image_of(field) -> pv.ImageData:
    """The field as the user's ImageData: VTK's x-fastest point order."""
    g = field.grid
    img = pv.ImageData(dimensions=g.shape, spacing=g.spacing, origin=g.origin)
    img.point_data["U"] = field.vector.transpose(2, 1, 0, 3).reshape(-1, 3)
    return img


def flowkit_ends(grid, seeds, length):
    """The point at arc length ``length`` of each of the task's lines (NaN: stopped short)."""
    lines = flowkit.trace(flowkit.fields.from_pyvista(grid), seeds, max_length=length)
    ends = lines.points[lines.offsets[1:] - 1].astype(np.float64)
    full = lines.line_data["reason"] == Reason.MAX_LENGTH  # max_length is met exactly
    ends[~full] = np.nan
    return ends, np.where(full, length, lines.arc_length())


def pyvista_ends(grid, seeds, length):
    """The arc length the task's lines reach, and each line's point at ``length`` from the
    same call run further."""
    asked = grid.streamlines_from_source(pv.PolyData(seeds), vectors="U", max_length=length,
                                         integration_direction="forward")
    reached = vtk_ends(asked, "U", len(seeds), length)[1]
    far = grid.streamlines_from_source(pv.PolyData(seeds), vectors="U", max_length=4 * length,
                                       integration_direction="forward")
    return vtk_ends(far, "U", len(seeds), length)[0], reached


def analytic_reference(seeds, length):
    """Points at arc length ``length`` on the analytic ABC lines (DOP853, rtol = atol = 1e-12)."""
    abc = ABCFlow()

    def rhs(s, x):
        v = abc.velocity(x[None])[0]
        return v / np.linalg.norm(v)

    return np.array([solve_ivp(rhs, (0.0, length), s, method="DOP853", rtol=1e-12,
                               atol=1e-12).y[:, -1] for s in seeds])


def timed(task, *args, repeat=2):
    task(*args)  # warm: compiled kernels loaded, pipelines built
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        task(*args)
        out.append(time.perf_counter() - t0)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nodes-per-period", type=int, default=32)
    ap.add_argument("--seeds", type=int, default=1000)
    ap.add_argument("--length", type=float, default=10.0)
    a = ap.parse_args(argv)
    problem = Problem(nodes_per_period=a.nodes_per_period, n_seeds=a.seeds, length=a.length)
    field = abc_field(problem)
    seeds = make_seeds(problem)
    grid = image_of(field)
    ref, _, ref_s, cached = cached_reference(problem, field, seeds, processes=1)
    exact = analytic_reference(seeds, problem.length)

    rows, cores = [], numba.get_num_threads()
    for name, task, ends_of, threads in (
            ("flowkit", task_flowkit, flowkit_ends, cores), ("flowkit", task_flowkit, flowkit_ends, 1),
            ("pyvista", task_pyvista, pyvista_ends, 1), ("pyvista", task_pyvista, pyvista_ends, cores)):
        # each tool on one thread and on every core: numba's threads, vtkSMPTools' (PyVista's
        # default backend is Sequential)
        numba.set_num_threads(threads if name == "flowkit" else cores)
        VTKTracer.set_threads(threads if name == "pyvista" else 1)
        t1, t2 = timed(task, grid, seeds, problem.length)
        result = task(grid, seeds, problem.length)
        ends, reached = ends_of(grid, seeds, problem.length)
        e_interp, e_exact = errors(ends, ref), errors(ends, exact)
        if name == "flowkit" and threads == 1:  # the part that copies the grid into its order
            convert = min(timed(flowkit.fields.from_pyvista, grid))
        rows.append({"variant": name, "threads": threads, "loc": lines_of_code(task),
                     "run1_s": t1, "run2_s": t2,
                     "lines": len(result), "vertices": sum(len(p) for p, _ in result),
                     "reach": f"{np.sum(reached >= problem.length * (1 - 1e-6))}/{len(seeds)}",
                     "median_reached": float(np.median(reached)),
                     "med_err_interp": float(np.median(e_interp)),
                     "max_err_interp": float(e_interp.max()),
                     "med_err_exact": float(np.median(e_exact)),
                     "max_err_exact": float(e_exact.max())})
    VTKTracer.set_threads(1)
    cols = [("variant", "{}"), ("threads", "{}"), ("loc", "{}"), ("run1_s", "{:.4f}"), ("run2_s", "{:.4f}"),
            ("lines", "{}"), ("vertices", "{}"), ("reach", "{}"), ("median_reached", "{:.3g}"),
            ("med_err_interp", "{:.2e}"), ("max_err_interp", "{:.2e}"),
            ("med_err_exact", "{:.2e}"), ("max_err_exact", "{:.2e}")]
    g = field.grid
    text = "\n".join([
        f"# flowkit's API and PyVista's streamlines on the same task ({time.strftime('%Y-%m-%d')})",
        f"command: {' '.join([sys.executable.split('/')[-1], *sys.argv])}",
        f"machine: {machine()}",
        f"flowkit {flowkit.__version__}, pyvista {pv.__version__}",
        (f"problem: ABC flow sampled at the nodes of [0, {problem.span:.4g}]^3, {g.shape[0]}^3 "
        f"nodes (float64); {len(seeds)} seeds in the central period; lines of arc length "
        f"{problem.length:g}, forward"),
        (f"reference on the interpolant: scipy DOP853 rtol=atol=1e-12 cell by cell "
        f"({'cached' if cached else f'{ref_s:.1f} s'}); exact: DOP853 1e-12 on the analytic "
        "velocity"),
        "",
        markdown_table(rows, cols),
        "",
        ("loc: non-blank, non-comment lines of the task function's body; run1_s/run2_s: two "
        "warm runs; reach: lines whose true arc length reaches the length asked for; "
        "median_reached: their median arc length; err_interp: distance at arc length "
        f"{problem.length:g} from the reference on the same interpolant (integration error); "
        "err_exact: from the analytic line (integration and interpolation error)"),
        (f"flowkit's time includes flowkit.fields.from_pyvista, {convert:.4f} s (the grid's "
        "arrays reordered from VTK's x-fastest order)"),
        ("threads: flowkit's are numba's (numba.set_num_threads), PyVista's vtkSMPTools' "
        "(Sequential by default in the pip wheel; STDThread for more)")])
    print(text)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "bench_pyvista.log").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
