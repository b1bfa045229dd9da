"""Adapters: each runs one tool at one setting on the benchmark's field and seeds and returns a
``common.Run`` holding its point at arc length ``length`` per seed and the timed cost.

Only the tracing call itself is timed (VTK: ``Update()``; streamtracer: ``trace``; flowkit:
``trace``); building each tool's copy of the grid is not.  Every tool integrates in arc length
(normalised velocity), so the point at arc length ``length`` is the tool's own end point:

* flowkit: ``max_length`` is met exactly by the dense output (the last vertex).
* VTK vtkStreamTracer: RK4 shortens its last step so that it ends at MaximumPropagation; RK45
  does not end at that arc length (see ``VTKTracer.run``), so its point at ``length`` is
  recovered from its own output.  VTK's output points are float32 (~5e-7 rounding here).
* streamtracer: fixed steps of ``ds`` in arc length, so vertex ``length / ds`` (``ds`` must
  divide ``length``).
* scipy solve_ivp: ``t_span = (0, length)`` ends there exactly.
"""

from __future__ import annotations

import numpy as np
from common import Run, Timer, unit_velocity
from scipy.integrate import solve_ivp

from flowkit.fields import Field

# -- flowkit ------------------------------------------------------------------------------


def flowkit_run(field: Field, seeds, length, method="dopri5", rtol=1e-6, atol=None,
                cell_aware=True, **options) -> Run:
    """flowkit.trace in arc length with max_length; the last vertex of each line."""
    import numba

    from flowkit import trace
    from flowkit.integrate.methods import get_method
    from flowkit.integrate.reasons import Reason

    atol = rtol if atol is None else atol
    with Timer() as t:
        lines = trace(field, seeds, method=method, rtol=rtol, atol=atol, max_length=length,
                      parameter="arc_length", cell_aware=cell_aware, **options)
    ends = lines.points[lines.offsets[1:] - 1].astype(np.float64)
    ok = lines.line_data["reason"] == Reason.MAX_LENGTH
    ends[~ok] = np.nan  # a line that stopped short has no point at arc length `length`
    # a fixed-step method is named by its step, not a tolerance
    tol = f"tol={rtol:.0e}" if get_method(method).adaptive else f"step={options.get('step')}"
    name = f"{method} {tol} cell_aware={'on' if cell_aware else 'off'}"
    if cell_aware and not options.get("cross_faces", True):
        name += " cross_faces=off"
    if options.get("attributes"):
        name += " +" + ",".join(options["attributes"])
    return Run("flowkit", name, ends, lines.n_points, t.wall, t.cpu, len(seeds),
               notes=[f"numba threads {numba.get_num_threads()}",
                      f"kernel path: {lines.attrs.get('kernel_path', '?')}"])


# -- VTK ----------------------------------------------------------------------------------


class VTKTracer:
    """vtkImageData (a uniform grid) or vtkRectilinearGrid (the vector array as point data,
    float64) and vtkStreamTracer.

    VTK stores point data x-fastest, flowkit z-fastest: the image holds a transposed copy of
    the vectors (one more field-sized array while it lives).  vtkStreamTracer (VTK >= 9.1)
    shares seeds among vtkSMPTools threads; the pip wheel starts on the Sequential backend:
    ``set_threads`` switches to STDThread (and back).  ``cell_diagonal`` is the mean cell's
    (the length-unit steps are set from it; VTK's cell unit is each cell's own diagonal).
    """

    def __init__(self, field: Field):
        import vtk
        from vtk.util.numpy_support import numpy_to_vtk

        g = field.grid
        self.vtk = vtk
        if g.uniform:
            img = vtk.vtkImageData()
            img.SetDimensions(*g.shape)
            img.SetOrigin(*g.origin)
            img.SetSpacing(*g.spacing)
        else:
            img = vtk.vtkRectilinearGrid()
            img.SetDimensions(*g.shape)
            img.SetXCoordinates(numpy_to_vtk(g.axes[0].copy(), deep=1))
            img.SetYCoordinates(numpy_to_vtk(g.axes[1].copy(), deep=1))
            img.SetZCoordinates(numpy_to_vtk(g.axes[2].copy(), deep=1))
        self._vectors = np.ascontiguousarray(field.vector.transpose(2, 1, 0, 3)).reshape(-1, 3)
        arr = numpy_to_vtk(self._vectors, deep=0)  # shares self._vectors, kept alive above
        arr.SetName(field.vector_name)
        img.GetPointData().SetVectors(arr)
        self.image = img
        self.vector_name = field.vector_name
        mean_width = [(c[-1] - c[0]) / (c.size - 1) for c in g.axes]
        self.cell_diagonal = float(np.linalg.norm(mean_width))

    @staticmethod
    def set_threads(n: int) -> None:
        """1: VTK's Sequential backend; n > 1: STDThread with n threads."""
        from vtkmodules.vtkCommonCore import vtkSMPTools

        vtkSMPTools.SetBackend("Sequential" if n <= 1 else "STDThread")
        vtkSMPTools.Initialize(max(n, 1))

    @staticmethod
    def threads() -> str:
        from vtkmodules.vtkCommonCore import vtkSMPTools

        return (f"vtkSMPTools backend {vtkSMPTools.GetBackend()}, "
                f"{vtkSMPTools.GetEstimatedNumberOfThreads()} thread(s)")

    def run(self, seeds, length, integrator="RK45", max_error=1e-6, step=0.1,
            min_step=None, max_step=None, unit="length", rk45_overshoot=4.0,
            vorticity=False) -> Run:
        """``step`` (and min/max) in length units, or in cells (VTK's cell length is the cell
        diagonal) with ``unit="cell"``; RK4 is fixed-step at ``step``.

        VTK's own stop at MaximumPropagation is exact for RK4 but not for RK45: it adds the
        *next* proposed step to its propagation instead of the step taken (vtkStreamTracer.cxx,
        ``propagation += fabs(stepSize.Interval)``), so an RK45 line stops at some other arc
        length (often far short of it).  The true arc length of each vertex follows from VTK's
        own output, s_k+1 = s_k + (IntegrationTime_k+1 - IntegrationTime_k) |U_k| (VTK advances
        time by step / speed at the step start); the point at ``length`` is the cubic Hermite
        interpolant (unit tangents) between the vertices around it.  So RK45 runs trace to
        ``rk45_overshoot * length`` of VTK's propagation, and the timed wall time is scaled by
        the fraction of the vertices that lie within arc length ``length`` (VTK's cost is per
        step); lines still short are traced again, untimed, much further (the steps are the
        same) and counted at their full time.  ``vorticity``: VTK's ComputeVorticity (vorticity,
        rotation and angular velocity at every vertex; its time and velocity are always there).
        """
        far = length if integrator == "RK4" else rk45_overshoot * length
        tracer = self._tracer(seeds, far, integrator, max_error, step, min_step, max_step, unit,
                              vorticity)
        with Timer() as t:
            tracer.Update()
        ends, s_end, nv, n_within = self._ends(tracer.GetOutput(), len(seeds), length)
        short = np.flatnonzero(np.isnan(ends[:, 0]))
        if short.size:
            again = self._tracer(seeds[short], 20 * length, integrator, max_error, step,
                                 min_step, max_step, unit, vorticity)
            again.Update()
            ends[short] = self._ends(again.GetOutput(), short.size, length)[0]
        scale = 1.0 if integrator == "RK4" else n_within / nv
        if integrator == "RK4":
            name = f"RK4 step={step:g} {unit}"
        else:
            lo = min_step if min_step is not None else step * 1e-4
            hi = max_step if max_step is not None else step * 100
            name = f"RK45 err={max_error:.0e} h0={step:.3g} [{lo:.2g}, {hi:.2g}] {unit}"
        from vtkmodules.vtkCommonCore import vtkSMPTools

        if vorticity:
            name += " vorticity"
        if vtkSMPTools.GetBackend() != "Sequential":
            name += f" smp={vtkSMPTools.GetEstimatedNumberOfThreads()}"
        notes = [self.threads()]
        if integrator != "RK4":
            notes.append(f"VTK's propagation {far:g} reached true arc length "
                         f"{np.nanmedian(s_end):.3g} (median); time scaled by {scale:.3f}")
        return Run("vtk", name, ends, n_within, t.wall * scale, t.cpu * scale, len(seeds),
                   notes=notes)

    def _tracer(self, seeds, length, integrator, max_error, step, min_step, max_step, unit,
                vorticity=False):
        vtk = self.vtk
        from vtk.util.numpy_support import numpy_to_vtk

        pts = vtk.vtkPoints()
        pts.SetData(numpy_to_vtk(np.ascontiguousarray(seeds, dtype=np.float64), deep=1))
        src = vtk.vtkPolyData()
        src.SetPoints(pts)
        st = vtk.vtkStreamTracer()
        st.SetInputData(self.image)
        st.SetSourceData(src)
        getattr(st, f"SetIntegratorTypeToRungeKutta{integrator[2:]}")()
        st.SetIntegrationDirectionToForward()
        st.SetIntegrationStepUnit(st.LENGTH_UNIT if unit == "length" else st.CELL_LENGTH_UNIT)
        st.SetInitialIntegrationStep(step)
        st.SetMinimumIntegrationStep(min_step if min_step is not None else step * 1e-4)
        st.SetMaximumIntegrationStep(max_step if max_step is not None else step * 100)
        st.SetMaximumError(max_error)
        st.SetMaximumPropagation(length)
        st.SetMaximumNumberOfSteps(10**9)
        st.SetTerminalSpeed(1e-300)
        st.SetComputeVorticity(vorticity)
        return st

    def _ends(self, out, n_seeds, length):
        return vtk_ends(out, self.vector_name, n_seeds, length)


def vtk_ends(out, vector_name: str, n_seeds: int, length: float):
    """(points at arc length ``length`` (NaN where the line is shorter), true arc length
    at each line's end, vertex count, vertices within ``length`` (all of a short line))
    from a vtkStreamTracer output (PyVista's ``streamlines`` too): see ``VTKTracer.run``."""
    from vtk.util.numpy_support import vtk_to_numpy

    P = vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    lines = out.GetLines()
    off = vtk_to_numpy(lines.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(lines.GetConnectivityArray()).astype(np.int64)
    T = vtk_to_numpy(out.GetPointData().GetArray("IntegrationTime"))[conn]
    U = vtk_to_numpy(out.GetPointData().GetArray(vector_name))[conn]
    seed_ids = vtk_to_numpy(out.GetCellData().GetArray("SeedIds"))
    P = P[conn]
    speed = np.linalg.norm(U, axis=1)
    ends = np.full((n_seeds, 3), np.nan)
    s_end = np.full(n_seeds, np.nan)
    within = 0
    for c, sid in enumerate(seed_ids):
        a, b = off[c], off[c + 1]
        ds = np.diff(T[a:b]) * speed[a:b - 1]
        s = np.concatenate([[0.0], np.cumsum(ds)])
        s_end[sid] = s[-1]
        if s[-1] < length * (1 - 1e-9):
            within += b - a
            continue
        k = min(int(np.searchsorted(s, length, side="right")) - 1, b - a - 2)
        within += k + 2
        h = s[k + 1] - s[k]
        th = min((length - s[k]) / h, 1.0)
        m0, m1 = U[a + k] / speed[a + k], U[a + k + 1] / speed[a + k + 1]
        ends[sid] = ((2 * th**3 - 3 * th**2 + 1) * P[a + k] + (th**3 - 2 * th**2 + th) * h * m0
                     + (-2 * th**3 + 3 * th**2) * P[a + k + 1] + (th**3 - th**2) * h * m1)
    return ends, s_end, int(P.shape[0]), within


# -- streamtracer -------------------------------------------------------------------------


class StreamtracerTracer:
    """streamtracer's VectorGrid over the same float64 vectors (no copy) and fixed-step RK4."""

    def __init__(self, field: Field):
        from streamtracer import VectorGrid

        g = field.grid
        if not g.uniform:
            raise ValueError("StreamtracerTracer: benchmark uses the uniform-spacing form")
        self.grid = VectorGrid(field.vector, grid_spacing=g.spacing, origin_coord=g.origin)

    def run(self, seeds, length, ds) -> Run:
        from streamtracer import StreamTracer

        n = round(length / ds)
        if abs(n * ds - length) > 1e-9 * length:
            raise ValueError(f"streamtracer step {ds} must divide the length {length}")
        st = StreamTracer(n + 1, ds)  # n + 1 vertices: the last one at arc length n * ds
        with Timer() as t:
            st.trace(np.ascontiguousarray(seeds, dtype=np.float64), self.grid, direction=1)
        counts = np.array([len(x) for x in st.xs])
        ends = np.full((len(seeds), 3), np.nan)
        full = counts == n + 1
        ends[full] = np.array([x[-1] for x, f in zip(st.xs, full) if f]).reshape(-1, 3)
        return Run("streamtracer", f"RK4 ds={ds:g}", ends, int(counts.sum()), t.wall, t.cpu,
                   len(seeds))


# -- scipy ---------------------------------------------------------------------------------


def scipy_run(field: Field, seeds, length, n_total, rtol=1e-6, atol=None,
              method="RK45") -> Run:
    """solve_ivp on the trilinear interpolant (the reference's RHS, without cell switching),
    one seed at a time; the time is scaled from ``len(seeds)`` to ``n_total`` seeds."""
    ka = field.grid.kernel_args() + (field.vector,)
    atol = rtol if atol is None else atol
    ends = np.full((len(seeds), 3), np.nan)
    nv = 0
    with Timer() as t:
        for n, s in enumerate(seeds):
            sol = solve_ivp(lambda _, y: unit_velocity(*ka, y), (0.0, length), s, method=method,
                            rtol=rtol, atol=atol)
            if sol.status == 0:
                ends[n] = sol.y[:, -1]
            nv += sol.t.size
    return Run("scipy", f"{method} tol={rtol:.0e}", ends, nv, t.wall, t.cpu, len(seeds),
               scale=n_total / len(seeds), notes=["serial Python"])
