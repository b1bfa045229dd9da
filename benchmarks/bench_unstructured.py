"""Unstructured OpenFOAM meshes (snappyHexMesh around obstacles, exported by foamToVTK as it
comes): flowkit info, resampling next to VTK's vtkResampleToImage, walls, and lines against
VTK's vtkStreamTracer on the mesh itself.

The case: OpenFOAM's ``incompressible/simpleFoam/windAroundBuildings`` tutorial (Debian's
``openfoam`` and ``openfoam-examples`` packages; about 5 minutes on 2 cores), as it comes:
``surfaceFeatureExtract``, ``blockMesh``, ``snappyHexMesh -overwrite``, ``cp -r 0.orig 0``,
``simpleFoam`` (endTime 150 is enough for a flow around the buildings), ``foamToVTK
-latestTime``: 185 237 cells (171 484 hexahedra, 1 102 wedges, 12 651 polyhedra), 218 801
points.  Pass the ``.vtm`` foamToVTK wrote; its ``internal`` block is the mesh, its
``boundary/buildings`` and ``boundary/ground`` patches are the walls.

What is printed (each timed tool in a fresh process of its own, wall seconds best of
``--repeat`` and peak RSS from wait4):

1. ``flowkit info CASE.vtm`` end to end (default grid, from the cells' sizes).
2. Resampling onto ``--shape`` (default 160 x 120 x 60, 1.15M nodes): flowkit (read, locate,
   interpolate U) and VTK (vtkXMLUnstructuredGridReader, vtkResampleToImage); flowkit's first
   run with an empty numba cache (the compile cost).
3. Walls: nodes that VTK's own cell location (vtkResampleToImage's valid-point mask) puts in
   no cell but flowkit gives a value, and the reverse; U's largest difference where both hold
   one.
4. Lines: ``--seeds`` seeds on a plane upstream, traced by flowkit through the resampled grid
   (each vertex then probed against the mesh's own cells: none may lie in no cell, i.e. in a
   building) and by vtkStreamTracer on the unstructured mesh; the median distance between
   the two at equal arc length, over the pairs whose VTK line stays ``--clearance`` cells away
   from the walls up to that length, for ``--spacings`` grids (refinement).  With ``--decomp``
   (the case exported again with ``foamToVTK -latestTime -poly-decomp``) VTK also traces the
   decomposed mesh: VTK's interpolation in polyhedra (mean value coordinates, and its search for
   the containing polyhedron) moves its own lines by decimetres, the decomposed mesh does not.

Run: ``python benchmarks/bench_unstructured.py CASE.vtm [--decomp DECOMP.vtm] [--repeat 3]
[--out FILE]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common as C


# -- jobs, each in a fresh process ---------------------------------------------------------------
def job(kind: str, vtu: str, shape) -> dict:
    t0 = time.perf_counter()
    if kind == "flowkit":
        from flowkit.fields import load_field

        f = load_field(vtu, resample=tuple(shape))
        nan = int(np.isnan(f.vector[..., 0]).sum())
        return {"seconds": time.perf_counter() - t0, "nan_nodes": nan}
    import vtk
    from vtkmodules.vtkCommonCore import vtkSMPTools

    vtkSMPTools.SetBackend("STDThread")  # (the wheel starts Sequential: VTK on both cores too)
    vtkSMPTools.Initialize(os.cpu_count())
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(vtu)
    r.Update()
    t1 = time.perf_counter()
    rs = vtk.vtkResampleToImage()
    rs.SetInputConnection(r.GetOutputPort())
    rs.SetSamplingDimensions(*shape)
    rs.UseInputBoundsOn()
    rs.Update()
    return {"seconds": time.perf_counter() - t0, "read_seconds": t1 - t0,
            "invalid_nodes": _invalid(rs.GetOutput())}


def _invalid(image) -> int:
    from vtk.util.numpy_support import vtk_to_numpy

    return int((vtk_to_numpy(image.GetPointData().GetArray("vtkValidPointMask")) == 0).sum())


def timed(argv, env=None) -> tuple[float, int, str]:
    """(wall seconds, peak RSS in MB, stdout) of a child process."""
    t = time.perf_counter()
    p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    out = p.stdout.read().decode()
    err = p.stderr.read().decode()
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{argv} failed: {err[-2000:]}")
    return wall, ru.ru_maxrss // 1024, out


def best_of(argv, repeat, env=None):
    runs = [timed(argv, env) for _ in range(repeat)]
    walls = [r[0] for r in runs]
    return min(walls), max(walls), max(r[1] for r in runs), runs[-1][2]


# -- walls and lines -------------------------------------------------------------------------
def vtk_mesh(vtu):
    import vtk

    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(vtu))
    r.Update()
    return r.GetOutput()


def polydata(points):
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    pd = vtk.vtkPolyData()
    p = vtk.vtkPoints()
    p.SetData(numpy_to_vtk(np.ascontiguousarray(points, float), deep=1))
    pd.SetPoints(p)
    return pd


def on_box(points, bounds) -> np.ndarray:
    """Whether each point lies on a face of the box ``bounds`` (to 1e-9 of its size)."""
    b = np.asarray(bounds, float)
    tol = 1e-9 * np.ptp(b, axis=1).max()
    return np.any((np.abs(points - b[:, 0]) <= tol) | (np.abs(points - b[:, 1]) <= tol), axis=-1)


def in_no_cell(mesh, points) -> np.ndarray:
    """Whether each point lies in no cell of ``mesh`` (VTK's own cell location)."""
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    probe = vtk.vtkProbeFilter()
    probe.SetInputData(polydata(points))
    probe.SetSourceData(mesh)
    probe.Update()
    return vtk_to_numpy(probe.GetOutput().GetPointData().GetArray("vtkValidPointMask")) == 0


def vtk_lines(mesh, seeds, length):
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    st = vtk.vtkStreamTracer()
    st.SetInputData(mesh)
    st.SetSourceData(polydata(seeds))
    st.SetInputArrayToProcess(0, 0, 0, 0, "U")
    st.SetIntegratorTypeToRungeKutta45()
    st.SetIntegrationDirectionToForward()
    st.SetIntegrationStepUnit(2)  # in cell lengths (each cell's own)
    st.SetInitialIntegrationStep(0.2)
    st.SetMinimumIntegrationStep(0.01)
    st.SetMaximumIntegrationStep(0.5)
    st.SetMaximumError(1e-6)
    st.SetMaximumPropagation(length)
    st.SetMaximumNumberOfSteps(100000)
    t = time.perf_counter()
    st.Update()
    dt = time.perf_counter() - t
    out = st.GetOutput()
    pts = vtk_to_numpy(out.GetPoints().GetData()).astype(float)
    seed_ids = vtk_to_numpy(out.GetCellData().GetArray("SeedIds"))
    lines = out.GetLines()
    conn = vtk_to_numpy(lines.GetConnectivityArray())
    offs = vtk_to_numpy(lines.GetOffsetsArray())
    by_seed = {}
    for i in range(offs.size - 1):
        ids = conn[offs[i]:offs[i + 1]]
        by_seed[int(seed_ids[i])] = pts[ids]
    return by_seed, dt


def wall_distance(walls, points) -> np.ndarray:
    import vtk

    d = vtk.vtkImplicitPolyDataDistance()
    d.SetInput(walls)
    return np.abs(np.array([d.EvaluateFunction(*p) for p in points]))


def patch(vtm: Path, name):
    import vtk

    r = vtk.vtkXMLPolyDataReader()
    r.SetFileName(str(vtm.parent / vtm.stem / "boundary" / f"{name}.vtp"))
    r.Update()
    tri = vtk.vtkTriangleFilter()
    tri.SetInputData(r.GetOutput())
    tri.Update()
    return tri.GetOutput()


def walls_of(vtm: Path):
    import vtk

    app = vtk.vtkAppendPolyData()
    for name in ("buildings", "ground"):
        app.AddInputData(patch(vtm, name))
    app.Update()
    return app.GetOutput()


def compare_lines(vtm, vtu, decomp, spacings, n_seeds, length, arcs, clearance, report):
    """flowkit's lines through grids of each spacing against vtkStreamTracer on the mesh (and on
    foamToVTK's -poly-decomp export of it, where given: VTK then interpolates no polyhedra)."""
    import flowkit
    from flowkit.fields import load_field

    mesh = vtk_mesh(vtu)
    b = np.array(mesh.GetBounds()).reshape(3, 2)
    ny = round(np.sqrt(n_seeds * 1.6))
    nz = max(1, n_seeds // ny)
    y = np.linspace(b[1, 0] + 10, b[1, 1] - 10, ny)
    z = np.linspace(5.0, 0.7 * b[2, 1], nz)
    Y, Z = np.meshgrid(y, z, indexing="ij")
    seeds = np.stack([np.full(Y.size, b[0, 0] + 5.0), Y.ravel(), Z.ravel()], 1)
    refs = {}
    for name, path in (("polyhedra", vtu), ("decomposed", decomp)):
        if path is not None:
            refs[name], vtk_s = vtk_lines(vtk_mesh(path), seeds, length)
            report(f"vtkStreamTracer on the mesh ({name}): {len(seeds)} seeds in {vtk_s:.2f} s")
    walls = walls_of(vtm)
    ok = {}  # arc -> seeds whose VTK line keeps its clearance up to that arc length
    for i, p in refs["polyhedra"].items():
        cum = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        d = wall_distance(walls, p)
        for s in arcs:
            if cum[-1] >= s and d[cum <= s].min() > clearance:
                ok.setdefault(s, []).append(i)
    report("seeds whose VTK line stays clear of the walls up to each arc length: "
           + ", ".join(f"{s:g} m: {len(ok.get(s, []))}" for s in arcs))
    rows = []
    for h in spacings:
        t = time.perf_counter()
        f = load_field(vtu, resample=f"spacing:{h}")
        _ = f.vector
        t_res = time.perf_counter() - t
        t = time.perf_counter()
        lines = flowkit.trace(f, seeds, max_length=length, rtol=1e-6)
        t_tr = time.perf_counter() - t
        bad = in_no_cell(mesh, lines.points) & ~on_box(lines.points, f.grid.bounds)
        row = {"spacing": h, "nodes": int(np.prod(f.grid.shape)), "resample_s": round(t_res, 2),
               "trace_s": round(t_tr, 2), "vertices": int(lines.n_points),
               "vertices_in_no_cell": int(bad.sum())}
        if bad.any():
            row["deepest_m"] = float(wall_distance(walls, lines.points[bad]).max())
        for name, ref in refs.items():
            for s in arcs:
                ids = np.array([i for i in ok.get(s, []) if i in ref], int)
                mine = C.point_at_arc_length(lines.points, lines.offsets, s)[ids]
                theirs = np.array([C.point_at_arc_length(ref[i], np.array([0, len(ref[i])]), s)[0]
                                   for i in ids]).reshape(-1, 3)
                d = np.linalg.norm(mine - theirs, axis=1)
                d = d[np.isfinite(d)]
                row[f"median_m@{s:g} vs {name}"] = float(f"{np.median(d):.3g}") if d.size else None
        rows.append(row)
        report(json.dumps(row))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("vtm", type=Path, help="foamToVTK's .vtm (or the internal .vtu)")
    ap.add_argument("--shape", default="160,120,60")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seeds", type=int, default=500)
    ap.add_argument("--length", type=float, default=300.0)
    ap.add_argument("--arcs", default="25,50,100,200")
    ap.add_argument("--clearance", type=float, default=3.0, help="in finest cells (1.75 m)")
    ap.add_argument("--spacings", default="3.5,1.75,1.17")
    ap.add_argument("--decomp", type=Path,
                    help="the same case exported with foamToVTK -poly-decomp (its .vtm)")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--job", choices=["flowkit", "vtk"], help=argparse.SUPPRESS)
    args = ap.parse_args()
    shape = [int(n) for n in args.shape.split(",")]
    if args.job:
        print(json.dumps(job(args.job, str(args.vtm), shape)))
        return
    from vtkmodules.vtkCommonCore import vtkSMPTools

    vtkSMPTools.SetBackend("STDThread")  # (the wheel starts Sequential: VTK on every core)
    vtkSMPTools.Initialize(os.cpu_count())
    from flowkit.fields.readers.vtu import vtm_block

    vtu = vtm_block(args.vtm) if args.vtm.suffix == ".vtm" else args.vtm
    lines_out = []

    def report(s):
        print(s, flush=True)
        lines_out.append(s)

    report(f"# bench_unstructured: {args.vtm}\n\n{C.machine()}\n")
    py = sys.executable
    lo, hi, rss, _ = best_of([py, "-m", "flowkit", "info", str(args.vtm)], args.repeat)
    report(f"flowkit info {args.vtm.name}: {lo:.2f} s best of {args.repeat} (worst {hi:.2f}), "
           f"peak RSS {rss} MB")
    me = [py, __file__, str(vtu), "--shape", args.shape, "--job"]
    for tool in ("flowkit", "vtk"):
        lo, hi, rss, out = best_of(me + [tool], args.repeat)
        res = json.loads(out)
        report(f"resample {args.shape} ({np.prod(shape):,} nodes), {tool}: {lo:.2f} s best of "
               f"{args.repeat} (worst {hi:.2f}; in-process {res['seconds']:.2f} s), peak RSS "
               f"{rss} MB; {json.dumps({k: v for k, v in res.items() if k != 'seconds'})}")
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cold, _, out = timed(me + ["flowkit"], env)
        report(f"resample, flowkit, empty numba cache (compiles its kernels): {cold:.2f} s, "
               f"in-process {json.loads(out)['seconds']:.2f} s")
    # walls: flowkit's NaN nodes against VTK's own cell location
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    from flowkit.fields import load_field

    f = load_field(vtu, resample=tuple(shape))
    rs = vtk.vtkResampleToImage()
    rs.SetInputDataObject(vtk_mesh(vtu))
    rs.SetSamplingDimensions(*shape)
    rs.UseInputBoundsOff()  # (its own bounds shrink the box a little: the same nodes here)
    rs.SetSamplingBounds(*np.asarray(f.grid.bounds).ravel())
    rs.Update()
    img = rs.GetOutput()
    valid = vtk_to_numpy(img.GetPointData().GetArray("vtkValidPointMask")).reshape(
        shape[::-1]).transpose(2, 1, 0) == 1
    u_vtk = vtk_to_numpy(img.GetPointData().GetArray("U")).reshape(
        (*shape[::-1], 3)).transpose(2, 1, 0, 3)
    mine = np.isfinite(f.vector[..., 0])
    both = mine & valid
    rim = on_box(f.grid.node_points(), f.grid.bounds)  # VTK's probe counts these as outside
    dif = np.abs(f.vector[both].astype(float) - u_vtk[both]).max(-1)
    diff = dif.max()
    report(f"walls ({np.prod(shape):,} nodes, {int(rim.sum())} on the box's outer faces left "
           f"out): VTK puts {int((~valid & ~rim).sum())} in no cell, flowkit "
           f"{int((~mine & ~rim).sum())}; in no cell for VTK but valued by flowkit: "
           f"{int((mine & ~valid & ~rim).sum())}; the reverse: {int((~mine & valid).sum())}; "
           f"|dU| where both hold a value: median {np.median(dif):.3g}, largest {diff:.3g} m/s "
           "(VTK interpolates polyhedra by mean value coordinates)")

    decomp = vtm_block(args.decomp) if args.decomp else None
    rows = compare_lines(args.vtm, vtu, decomp, [float(s) for s in args.spacings.split(",")],
                         args.seeds, args.length, [float(s) for s in args.arcs.split(",")],
                         args.clearance * 1.75, report)
    del rows
    out = args.out or Path(__file__).parent / "results" / f"unstructured_{time.strftime('%Y%m%d_%H%M')}.md"
    out.parent.mkdir(exist_ok=True)
    out.write_text("\n".join(lines_out) + "\n")
    print(f"-> {out}")


if __name__ == "__main__":
    main()
