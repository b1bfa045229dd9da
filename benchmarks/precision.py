"""Work–precision: run time against error for every method × tolerance × backend × cell-aware.

Problems (``flowkit bench precision``, or ``python benchmarks/precision.py``):

(a) exact solutions, time-parameterised, ``max_time`` met exactly, error = |end − exact| at that
    time: solid-body rotation (one turn), a linear spiral sink, a linear saddle, and the stiff
    linear field (eigenvalues −1, −1e4).  Linear fields are reproduced exactly by trilinear
    interpolation, so this is integration error alone.
(b) gridded: ABC on two grids (16 and 32 nodes per period, three periods, bounded) and the heated
    room, in arc length to ``max_length``, against a tight cell-by-cell DOP853 on the *same*
    trilinear interpolant (``common.reference_points``, the peer benchmark's reference).  The
    interpolation error (that reference against DOP853 on the analytic ABC field) is reported
    on its own line per grid: below it, a smaller integration error buys nothing.

Peers on the same axes: scipy solve_ivp (RK45, DOP853; Radau on the stiff field) everywhere, VTK's
vtkStreamTracer and streamtracer on the ABC grids (``peers.py`` adapters; skipped when not
installed).  Errors are the median over seeds; wall time is for all seeds (scipy runs a subset,
scaled).  Output: CSV, Markdown and a log-log PNG per problem panel.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import common as C  # the peer benchmark's shared pieces
import peers

from flowkit import trace
from flowkit.fields.analytic import ABCFlow, LinearField, SolidBodyRotation
from flowkit.integrate.reasons import Reason

METHODS = ("dopri5", "cashkarp", "bs23", "dop853")
ROS = "ros34pw2"
TOLS_FULL = tuple(10.0 ** -k for k in range(2, 11))
TOLS_QUICK = (1e-3, 1e-6, 1e-9)
COLUMNS = [("problem", "{}"), ("tool", "{}"), ("method", "{}"), ("backend", "{}"),
           ("cell_aware", "{}"), ("tol", "{:.0e}"), ("median_err", "{:.2e}"), ("max_err", "{:.2e}"),
           ("failed", "{}"), ("wall_s", "{:.4f}"), ("steps", "{:.0f}")]


# -- problems ---------------------------------------------------------------------------------
class Problem:
    """One panel: a field, seeds, how far, and the reference end points."""

    def __init__(self, name, field, seeds, ref, parameter, limit, analytic=None, note=""):
        self.name, self.field, self.seeds, self.ref = name, field, seeds, ref
        self.parameter, self.limit, self.analytic, self.note = parameter, limit, analytic, note

    @property
    def limit_kw(self):
        return {"max_time" if self.parameter == "time" else "max_length": self.limit}

    @property
    def good_reason(self):
        return Reason.MAX_TIME if self.parameter == "time" else Reason.MAX_LENGTH


def _box(rng, n, lo, hi):
    return lo + (np.asarray(hi) - np.asarray(lo)) * rng.random((n, 3))


def analytic_problems(n_seeds, rng):
    out = []
    rot = SolidBodyRotation()
    r = 0.2 + 0.6 * rng.random(n_seeds)
    a = 2 * np.pi * rng.random(n_seeds)
    s = np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(-0.5, 0.5, n_seeds)], 1)
    out.append(("rotation", rot, rot.to_field(9), s, 2 * np.pi))
    sp = LinearField.spiral(omega=1.0, rate=-0.1)
    out.append(("spiral sink", sp, sp.to_field(5), _box(rng, n_seeds, [-0.8] * 3, [0.8] * 3), 10.0))
    sd = LinearField.saddle()
    out.append(("saddle", sd, sd.to_field(5), _box(rng, n_seeds, [-0.3, -0.9, -0.9], [0.3, 0.9, 0.9]), 1.0))
    st = LinearField.stiff()
    out.append(("stiff linear", st, st.to_field((4, 4, 11)),
                _box(rng, n_seeds, [-0.9, -0.9, 0.0], [0.9, 0.9, 1.0]), 5.0))
    return [Problem(name, fld, s, f.trajectory(s, T), "time", T, analytic=f,
                    note=f"{f.describe()}, t = {T:g}") for name, f, fld, s, T in out]


def abc_problem(npp, n_seeds, processes):
    pb = C.Problem(nodes_per_period=npp, n_seeds=n_seeds)
    fld = C.abc_field(pb)
    seeds = C.make_seeds(pb)
    ref, _, sec, cached = C.cached_reference(pb, fld, seeds, processes)
    print(f"  ABC {npp}/period: reference {sec:.0f} s{' (cached)' if cached else ''}", flush=True)
    return Problem(f"ABC {npp}/period", fld, seeds, ref, "arc_length", pb.length,
                   note=f"{pb.n_nodes}^3 nodes, arc length {pb.length:g}")


def interpolation_error(problem, n=20):
    """Median |trilinear reference − analytic reference| (DOP853 rtol 1e-12 on ABC itself)."""
    from scipy.integrate import solve_ivp

    abc = ABCFlow()

    def f(_, y):
        v = abc.velocity(y)[0]
        return v / np.linalg.norm(v)

    d = []
    for s, r in zip(problem.seeds[:n], problem.ref[:n]):
        sol = solve_ivp(f, (0, problem.limit), s, method="DOP853", rtol=1e-12, atol=1e-12)
        d.append(np.linalg.norm(sol.y[:, -1] - r))
    return float(np.median(d))


def hotroom_problem(n_seeds, processes, length=2.0):
    from flowkit.datasets import hotroom

    fld = hotroom()
    rng = np.random.default_rng(7)
    b = fld.grid.bounds
    cand = _box(rng, 6 * n_seeds, b[:, 0] + 0.5, b[:, 1] - 0.5)
    # keep seeds whose line runs the whole length well inside (same work for every tool)
    L = trace(fld, cand, method="dop853", rtol=1e-10, atol=1e-10, parameter="arc_length",
              max_length=length)
    ok = L.line_data["reason"] == Reason.MAX_LENGTH
    for i in np.flatnonzero(ok):
        p = L[i].points
        ok[i] = np.all((p > b[:, 0] + 0.05) & (p < b[:, 1] - 0.05))
    seeds = cand[ok][:n_seeds]
    t0 = time.perf_counter()
    ref, _ = C.reference_points(fld, seeds, length, processes=processes, progress=False)
    print(f"  heated room: {len(seeds)} seeds, reference {time.perf_counter() - t0:.0f} s", flush=True)
    return Problem("heated room", fld, seeds, ref, "arc_length", length,
                   note=f"{fld.grid.shape} nodes, arc length {length:g} m")


# -- runs -------------------------------------------------------------------------------------
def _best(fn, repeat):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _row(problem, tool, method, backend, aware, tol, ends, ok, wall, steps):
    err = np.linalg.norm(ends - problem.ref[:len(ends)], axis=1)
    err = np.where(ok & np.isfinite(err), err, np.inf)
    fin = err[np.isfinite(err)]
    return {"problem": problem.name, "tool": tool, "method": method, "backend": backend,
            "cell_aware": aware, "tol": tol, "median_err": float(np.median(err)),
            "max_err": float(fin.max()) if fin.size else np.inf, "failed": int((~ok).sum()),
            "wall_s": wall, "steps": float(steps)}


def flowkit_rows(problem, tols, backends, repeat, methods=METHODS + (ROS,), ros_problems=None):
    # lines are measured against exact end points at a fixed time or length: the stagnation
    # threshold low enough that a line slowing onto its attractor (the stiff linear field) goes on
    kw = dict(parameter=problem.parameter, max_steps=10**6, stagnation_rel=1e-6,
              **problem.limit_kw)
    for backend in backends:
        for method in methods:
            if method == ROS and (backend != "numba"
                                  or (ros_problems is not None and problem.name not in ros_problems)):
                continue
            for aware in ((True,) if method == ROS else (True, False)):
                def run(tol, n=None, method=method, aware=aware, backend=backend):
                    s = problem.seeds if n is None else problem.seeds[:n]
                    return trace(problem.field, s, method=method, rtol=tol, atol=tol,
                                 cell_aware=aware, backend=backend, **kw)
                run(1e-3, 2)  # compile (numba cache / OpenCL program) outside the timing
                for tol in tols:
                    if method == "bs23" and tol < 1e-8:
                        continue  # 3rd order: 10^5+ steps per line, nothing to learn
                    L, wall = _best(lambda tol=tol: run(tol), repeat)
                    ends = L.points[L.offsets[1:] - 1]
                    ok = L.line_data["reason"] == problem.good_reason
                    steps = np.mean(L.line_data["n_accepted"] + L.line_data["n_rejected"])
                    yield _row(problem, "flowkit", method, backend, aware, tol, ends, ok, wall, steps)


def scipy_rows(problem, tols, n):
    """solve_ivp on the problem's own right-hand side: the analytic field (linear fields: the
    same ODE as the grid) or the trilinear interpolant (``peers.scipy_run``)."""
    from scipy.integrate import solve_ivp

    sub = problem.seeds[:n]
    for method in ("RK45", "DOP853") + (("Radau",) if problem.name == "stiff linear" else ()):
        for tol in tols:
            if method == "RK45" and tol < 1e-8:
                continue
            if problem.analytic is None:
                run = peers.scipy_run(problem.field, sub, problem.limit, len(problem.seeds),
                                      rtol=tol, atol=tol, method=method)
                ends, wall = run.end_points, run.full_wall
                ok = np.isfinite(ends[:, 0])
                steps = run.n_vertices / len(sub)
            else:
                A = problem.analytic
                ends, steps = np.full((len(sub), 3), np.nan), 0
                jac = (lambda t, y, A=A: A.jacobian(y)[0]) if method == "Radau" else None
                t0 = time.perf_counter()
                for i, s in enumerate(sub):
                    sol = solve_ivp(lambda t, y, A=A: A.velocity(y)[0], (0, problem.limit), s,
                                    method=method, rtol=tol, atol=tol, jac=jac)
                    ends[i] = sol.y[:, -1]
                    steps += sol.t.size - 1
                wall = (time.perf_counter() - t0) * len(problem.seeds) / len(sub)
                ok = np.ones(len(sub), bool)
                steps /= len(sub)
            yield _row(problem, "scipy", method, "python", "-", tol, ends, ok, wall, steps)


def grid_peer_rows(problem):
    """VTK vtkStreamTracer (RK45 at several max errors, RK4) and streamtracer (RK4) on ABC."""
    L = problem.limit
    try:
        vt = peers.VTKTracer(problem.field)
    except ImportError:
        vt = None
    if vt is not None:
        cell = vt.cell_diagonal
        for err in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
            r = vt.run(problem.seeds, L, "RK45", err, step=0.2 * cell, min_step=0.01 * cell,
                       max_step=cell)
            yield _peer_row(problem, "vtk", "RK45", err, r)
        for h in (0.1, 0.03, 0.01):
            yield _peer_row(problem, "vtk", "RK4", h, vt.run(problem.seeds, L, "RK4", step=h))
        del vt
    try:
        st = peers.StreamtracerTracer(problem.field)
    except ImportError:
        return
    for ds in (0.1, 0.05, 0.02, 0.01, 0.005):
        yield _peer_row(problem, "streamtracer", "RK4", ds, st.run(problem.seeds, L, ds))


def _peer_row(problem, tool, method, tol, run):
    ok = np.isfinite(run.end_points[:, 0])
    return _row(problem, tool, method, "-", "-", tol, run.end_points, ok, run.full_wall,
                run.n_vertices / len(problem.seeds))


# -- output -----------------------------------------------------------------------------------
def markdown(rows, columns=COLUMNS):
    head = "| " + " | ".join(c for c, _ in columns) + " |"
    sep = "|" + "|".join("---" for _ in columns) + "|"
    return "\n".join([head, sep] + ["| " + " | ".join(f.format(r[c]) for c, f in columns) + " |"
                                    for r in rows])


def plot(rows, problems, interp, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(problems)
    ncol = min(n, 4)
    nrow = -(-n // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.6 * nrow), squeeze=False)
    style = {"dopri5": "C0", "cashkarp": "C1", "bs23": "C2", "dop853": "C3", ROS: "C4",
             "RK45": "C5", "DOP853": "C6", "Radau": "C7", "RK4": "C8"}
    for ax, p in zip(axes.flat, problems):
        groups = {}
        for r in rows:
            if r["problem"] == p.name and np.isfinite(r["median_err"]) and r["median_err"] > 0:
                key = (r["tool"], r["method"], r["backend"], r["cell_aware"])
                groups.setdefault(key, []).append(r)
        for (tool, method, backend, aware), rs in groups.items():
            rs.sort(key=lambda r: r["median_err"])
            ls = "-" if aware in (True, "-") else ":"
            mk = {"flowkit": "o", "scipy": "s", "vtk": "^", "streamtracer": "v"}[tool]
            if backend == "opencl":
                mk = "x"
            label = f"{tool} {method}" + ("" if tool != "flowkit" else
                                          f" {backend}{' aware' if aware is True else ' plain'}")
            ax.loglog([r["median_err"] for r in rs], [r["wall_s"] for r in rs], ls, marker=mk,
                      ms=3.5, lw=1, color=style.get(method, "k"), label=label)
        if p.name in interp:
            ax.axvline(interp[p.name], color="0.4", lw=1, ls="--", label="interpolation error")
        ax.set_title(p.name, fontsize=10)
        ax.set_xlabel("median error", fontsize=8)
        ax.set_ylabel("wall time [s]", fontsize=8)
        ax.grid(True, which="both", lw=0.3)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[n:]:
        ax.axis("off")
    handles = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=5, fontsize=7)
    fig.suptitle("flowkit work–precision (solid: cell-aware, dotted: plain; x: OpenCL)", fontsize=11)
    fig.tight_layout(rect=(0, 0.04 + 0.025 * (len(handles) // 5 + 1), 1, 0.97))
    path.parent.mkdir(parents=True, exist_ok=True)
    with C.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path


def summary(rows):
    """Key comparisons: dopri5 vs ros34pw2 on the stiff field; cell-aware vs plain."""
    out = ["## Stiff linear field: ros34pw2 against dopri5 (cell-aware, numba)\n",
           ("| tol | dopri5 err | dopri5 steps | dopri5 s | ros34pw2 err | ros34pw2 steps | "
            "ros34pw2 s | steps ratio | time ratio |"), "|---|---|---|---|---|---|---|---|---|"]
    st = [r for r in rows if r["problem"] == "stiff linear" and r["tool"] == "flowkit"
          and r["backend"] == "numba" and r["cell_aware"] is True]
    for tol in sorted({r["tol"] for r in st}, reverse=True):
        d = next((r for r in st if r["method"] == "dopri5" and r["tol"] == tol), None)
        q = next((r for r in st if r["method"] == ROS and r["tol"] == tol), None)
        if d and q:
            out.append(f"| {tol:.0e} | {d['median_err']:.2e} | {d['steps']:.0f} | {d['wall_s']:.4f} | "
                       f"{q['median_err']:.2e} | {q['steps']:.0f} | {q['wall_s']:.4f} | "
                       f"{d['steps'] / q['steps']:.0f}x | {d['wall_s'] / q['wall_s']:.1f}x |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="flowkit bench precision", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="CI smoke: 3 tolerances, few seeds, one "
                    "ABC grid, no heated room, no VTK/streamtracer")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="directory for CSV/MD/PNG")
    ap.add_argument("--plot", type=Path, help="PNG path (default OUT/work_precision[_quick].png)")
    ap.add_argument("--backends", default=None, help="numba,opencl (default: numba, plus opencl "
                    "in full mode when PoCL/an OpenCL device is present)")
    ap.add_argument("--no-peers", action="store_true", help="flowkit only")
    ap.add_argument("--seeds", type=int, help="seeds per problem")
    ap.add_argument("--processes", type=int, default=2, help="processes for the references")
    ap.add_argument("--problems", help="comma-separated subset, e.g. 'rotation,stiff linear'")
    ap.add_argument("--tols", help="comma-separated tolerances (default 1e-2 ... 1e-10, every decade)")
    ap.add_argument("--methods", help=f"comma-separated flowkit methods (default {','.join(METHODS)},{ROS})")
    ap.add_argument("--ros-problems", help=f"problems {ROS} runs on (default: all)")
    ap.add_argument("--abc-grids", default="16,32", help="ABC nodes per period (default 16,32)")
    ap.add_argument("--peers", choices=("all", "scipy", "none"), default="all",
                    help="scipy: solve_ivp on the analytic problems only (cheap); none: as --no-peers")
    ap.add_argument("--repeat", type=int, help="timing repeats, fastest kept (default 2; quick 1)")
    a = ap.parse_args(argv)
    quick = a.quick
    tols = TOLS_QUICK if quick else TOLS_FULL
    if a.tols:
        tols = tuple(float(t) for t in a.tols.split(","))
    methods = tuple(m.strip() for m in a.methods.split(",")) if a.methods else METHODS + (ROS,)
    ros_problems = None if not a.ros_problems else {w.strip() for w in a.ros_problems.split(",")}
    grids = [int(g) for g in a.abc_grids.split(",") if g.strip()]
    peers_mode = "none" if a.no_peers else a.peers
    n_seeds = a.seeds or (8 if quick else 32)
    repeat = a.repeat or (1 if quick else 2)
    want = None if not a.problems else {w.strip() for w in a.problems.split(",")}
    backends = _backends(a.backends, quick)
    print(f"machine: {C.machine()}\nbackends: {', '.join(backends)}", flush=True)
    t_start = time.perf_counter()
    rng = np.random.default_rng(20261122)
    problems = [p for p in analytic_problems(n_seeds, rng) if want is None or p.name in want]
    if 16 in grids and (want is None or "ABC 16/period" in want):
        problems.append(abc_problem(16, 20 if quick else 200, a.processes))
    if not quick and 32 in grids and (want is None or "ABC 32/period" in want):
        problems.append(abc_problem(32, 100, a.processes))
    if not quick and (want is None or "heated room" in want):
        problems.append(hotroom_problem(n_seeds, a.processes))
    interp = {p.name: interpolation_error(p, 5 if quick else 20) for p in problems
              if p.name.startswith("ABC")}
    rows = []
    for p in problems:
        print(f"{p.name}: {p.note}, {len(p.seeds)} seeds", flush=True)
        gen = [flowkit_rows(p, tols, backends, repeat, methods, ros_problems)]
        if peers_mode == "all" or (peers_mode == "scipy" and p.analytic is not None):
            gen.append(scipy_rows(p, tols, 2 if quick else 8))
        if peers_mode == "all" and not quick and p.name.startswith("ABC"):
            gen.append(grid_peer_rows(p))
        for g in gen:
            for r in g:
                rows.append(r)
                print(f"  {r['tool']:12s} {r['method']:9s} {r['backend']:6s} aware={r['cell_aware']!s:5s} "
                      f"tol={r['tol']:.0e}  median {r['median_err']:.2e}  {r['wall_s']:.4f} s  "
                      f"{r['steps']:.0f} steps" + (f"  FAILED {r['failed']}" if r["failed"] else ""),
                      flush=True)
    tag = "_quick" if quick else ""
    a.out.mkdir(parents=True, exist_ok=True)
    csv_path = C.write_csv(a.out / f"precision{tag}.csv", rows)
    text = [f"# Work–precision{' (quick)' if quick else ''}\n", f"machine: {C.machine()}\n",
            "Interpolation error (trilinear-interpolant reference vs DOP853 on analytic ABC, "
            "median): " + ", ".join(f"{k}: {v:.2e}" for k, v in interp.items()) + "\n",
            summary(rows) + "\n", "## All runs\n", markdown(rows)]
    md_path = a.out / f"precision{tag}.md"
    with C.atomic_path(md_path) as tmp, open(tmp, "w") as fh:
        fh.write("\n".join(text) + "\n")
    try:
        png = plot(rows, problems, interp, a.plot or a.out / f"work_precision{tag}.png")
    except ModuleNotFoundError as e:  # the plot needs the bench extra; the tables do not
        png = f"not drawn ({e.name} missing: pip install 'flowkit[bench]')"
    print("\n" + summary(rows))
    print(f"\ninterpolation error: {interp}")
    print(f"CSV: {csv_path}\nMarkdown: {md_path}\nplot: {png}")
    print(f"total {time.perf_counter() - t_start:.0f} s; machine at the end: {C.machine()}")
    return 0


def _backends(spec, quick):
    if spec:
        return tuple(s.strip() for s in spec.split(",") if s.strip())
    if quick:
        return ("numba",)
    try:
        from flowkit.integrate.opencl import select_device

        select_device("opencl")
        return ("numba", "opencl")
    except (ImportError, OSError, RuntimeError, ValueError) as e:  # no pyopencl/device
        print(f"opencl backend not used: {e}")
        return ("numba",)


if __name__ == "__main__":
    sys.exit(main())
