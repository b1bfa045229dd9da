"""What VTK's vtkStreamTracer and streamtracer report on the extreme cases of tests/test_extreme.py,
beside flowkit's reason codes: one row per case (the seed, the expected outcome, each tool's
stated reason, its vertex count and whether every vertex is finite).

Run: ``python benchmarks/extreme_peers.py`` (peers skipped when not installed).  All tools trace
forward; VTK and streamtracer in arc length (their only mode), flowkit in time unless noted.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # the peer benchmark's adapters

from flowkit import trace
from flowkit.fields import Field, Grid
from flowkit.fields.analytic import LinearField, SolidBodyRotation, UniformFlow
from flowkit.integrate.reasons import Reason

VTK_REASONS = {1: "out_of_domain", 2: "not_initialized", 3: "unexpected_value", 4: "out_of_length",
               5: "out_of_steps", 6: "stagnation"}
ST_REASONS = {-1: "nan", 1: "max_steps", 2: "out_of_bounds"}


def cases():
    rot = SolidBodyRotation()
    hole = rot.to_field(17)
    hole.vector[10:, 8:11, :] = np.nan
    sink = LinearField.sink().to_field(5)
    u = UniformFlow(U=(1.0, 0, 0)).to_field(5)
    thin = rot.to_field(grid=Grid.regular((-1, -1, 0), (0.25, 0.25, 0.1), (9, 9, 2)))
    x = np.linspace(-1, 1, 65)
    v = np.zeros((65, 3, 3, 3))
    v[..., 0] = (10.0 ** (8 * x))[:, None, None]
    speeds = Field(Grid.from_axes(x, np.linspace(0, 1, 3), np.linspace(0, 1, 3)), v)
    return [  # name, field, seed, expected, length
        ("sink, seed at the critical point", sink, [0, 0, 0], "stagnation, 1 vertex", 5.0),
        ("sink, seed near", sink, [0.3, 0.2, 0.1], "stagnation at the sink", 5.0),
        ("NaN hole ahead", hole, [0.0, -0.5, 0.0], "nan_field, finite vertices", 5.0),
        ("seed in a NaN cell", hole, [0.5, 0.0, 0.0], "seed_outside, no vertex", 5.0),
        ("seed outside", u, [1.5, 0.5, 0.5], "seed_outside, no vertex", 5.0),
        ("seed on inflow face", u, [0.0, 0.5, 0.5], "out_of_domain at x = 1", 5.0),
        ("seed on outflow face", u, [1.0, 0.5, 0.5], "out_of_domain, 1 vertex", 5.0),
        ("all-zero field", Field(u.grid, np.zeros_like(u.vector)), [0.5, 0.5, 0.5], "stagnation", 5.0),
        ("one cell thick", thin, [0.5, 0.0, 0.05], "max_length (circle)", 3.0),
        ("speeds 1e-8..1e8", speeds, [-0.5, 0.5, 0.5], "out_of_domain at x = 1", 5.0),
    ]


def flowkit_outcome(field, seed, length):
    L = trace(field, [seed], parameter="arc_length", max_length=length, rtol=1e-6, atol=1e-6,
              stagnation=1e-12 if "1e-08" in field.source else None, max_steps=100_000)
    p = L.points
    return Reason(L.line_data["reason"][0]).label, len(p), bool(np.all(np.isfinite(p))), _end(p)


def vtk_outcome(vt, seed, length):
    st = vt._tracer(np.array([seed], float), length, "RK45", 1e-6, 0.2, 0.01, 1.0, "cell")
    st.SetTerminalSpeed(1e-12)
    st.Update()
    out = st.GetOutput()
    from vtk.util.numpy_support import vtk_to_numpy

    if out.GetNumberOfCells() == 0:
        return "no line", 0, True, "-"
    p = vtk_to_numpy(out.GetPoints().GetData())
    r = int(vtk_to_numpy(out.GetCellData().GetArray("ReasonForTermination"))[0])
    return VTK_REASONS.get(r, str(r)), len(p), bool(np.all(np.isfinite(p))), _end(p)


def st_outcome(field, seed, length):
    from streamtracer import StreamTracer, VectorGrid

    g = field.grid
    grid = VectorGrid(field.vector, grid_spacing=g.spacing, origin_coord=g.origin)
    ds = 0.01
    st = StreamTracer(int(length / ds) + 1, ds)
    st.trace(np.array([seed], float), grid, direction=1)
    p = st.xs[0]
    return ST_REASONS.get(int(st.ROT[0]), str(st.ROT[0])), len(p), bool(np.all(np.isfinite(p))), _end(p)


def _end(p):
    return "-" if len(p) == 0 else "(" + ", ".join(f"{c:.3g}" for c in p[-1]) + ")"


def main() -> int:
    rows = []
    for name, field, seed, expected, length in cases():
        tools = {"flowkit": lambda f=field, s=seed, n=length: flowkit_outcome(f, s, n)}
        if field.grid.uniform:
            try:
                vt = peers.VTKTracer(field)
                tools["vtk"] = lambda vt=vt, s=seed, n=length: vtk_outcome(vt, s, n)
            except ImportError:
                pass
            try:
                import streamtracer  # noqa: F401

                tools["streamtracer"] = lambda f=field, s=seed, n=length: st_outcome(f, s, n)
            except ImportError:
                pass
        for tool, fn in tools.items():
            try:
                reason, n, finite, end = fn()
            except Exception as e:  # noqa: BLE001  (a peer that raises is an outcome to report)
                reason, n, finite, end = f"error: {type(e).__name__}: {e}"[:60], 0, True, "-"
            rows.append((name, expected, tool, reason, n, "yes" if finite else "NO", end))
    print("| case | expected | tool | reason reported | vertices | all finite | last vertex |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(str(c) for c in r) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
