"""Snapshots at real size: flowkit and VTK's vtkStreamTracer on one large float32 field.

Writes the ABC flow on [0, 4 pi]^3 at N^3 nodes in float32 as a flowkit HDF5 field (U and T,
chunked 64^3 nodes, uncompressed), then runs each of these in a fresh process, one after the
other, on the same file and the same random seeds:

- ``flowkit info FILE`` (metadata only) and ``flowkit info FILE --stats``;
- ``flowkit trace FILE --seeds random:S --max-length 10 --rtol 1e-5`` (end to end: start-up,
  reading, tracing, writing the lines);
- ``flowkit trace`` with S/100 seeds in one octant (what a corner of the field costs);
- with ``--memory SIZE`` (repeatable): ``flowkit trace --memory SIZE`` as above, its lines
  compared with the first trace's, and the re-read factor (bytes read / bytes of U);
- VTK: U read with h5py into VTK's x-fastest order a slab at a time (kept float32, no second
  field-sized copy), a vtkImageData and vtkStreamTracer (RK45, max error 1e-5, propagation
  10, vtkSMPTools threads on every core).

Each prints wall time, peak RSS and bytes read (``rchar``: what the process read through
system calls, page cache included).  The generated file is deleted at the end unless --keep.

    .venv/bin/python benchmarks/bench_bigfield.py --n 512        # 2.1 GB file
    .venv/bin/python benchmarks/bench_bigfield.py --n 1024       # 17 GB file
    .venv/bin/python benchmarks/bench_bigfield.py --n 1024 --memory 3GB
    .venv/bin/python benchmarks/bench_bigfield.py --n 1280 --memory 8GB --skip vtk,stats,whole
    .venv/bin/python benchmarks/bench_bigfield.py --n 128 --seeds 1000   # a quick look
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

A, B, C = np.sqrt(3.0), np.sqrt(2.0), 1.0
EXTENT = 4 * np.pi
CHUNK = 64


def write_abc(path: Path, n: int, chunk: int = CHUNK, coef=(A, B, C), scalar: bool = True,
              time: float | None = None) -> None:
    """ABC at n^3 nodes, float32, as a flowkit HDF5 field, written a slab at a time: U chunked
    ``chunk``^3 nodes with the coefficients ``coef`` (A, B, C), and T unless not ``scalar``;
    ``time``: the snapshot's time."""
    import h5py

    a, b, cc = coef
    x = np.linspace(0.0, EXTENT, n)
    c = min(chunk, n)
    with h5py.File(path, "w") as f:
        f.attrs["flowkit_format"] = "field"
        f.attrs["flowkit_format_version"] = 1
        f.attrs["vector_name"] = "U"
        if time is not None:
            f.attrs["time"] = time
        for name in "xyz":
            f[name] = x
        u = f.create_dataset("vectors/U", (n, n, n, 3), np.float32, chunks=(c, c, c, 3))
        u.attrs["units"] = "m/s"
        if scalar:
            t = f.create_dataset("scalars/T", (n, n, n), np.float32, chunks=(c, c, c))
            t.attrs["units"] = "K"
        y, z = x[None, :, None], x[None, None, :]
        for i0 in range(0, n, c):
            xs = x[i0:i0 + c, None, None]
            slab = np.empty((xs.shape[0], n, n, 3), np.float32)
            slab[..., 0] = a * np.sin(z) + cc * np.cos(y)
            slab[..., 1] = b * np.sin(xs) + a * np.cos(z)
            slab[..., 2] = cc * np.sin(y) + b * np.cos(xs)
            u[i0:i0 + c] = slab
            if scalar:
                t[i0:i0 + c] = (300.0 + np.sin(xs) * np.cos(y) + 0 * z).astype(np.float32)


def seeds(n_seeds: int, octant: bool = False) -> np.ndarray:
    hi = EXTENT / 2 if octant else EXTENT
    return np.random.default_rng(0).random((n_seeds, 3)) * hi


def _stats() -> dict:
    """Peak RSS (VmHWM: ru_maxrss survives exec, so a child would report its parent's peak
    from before the fork) and bytes read of this process."""
    io, status = {}, {}
    try:
        with open("/proc/self/io") as f:
            io = dict(line.split(": ") for line in f.read().splitlines())
        with open("/proc/self/status") as f:
            status = dict(line.split(":", 1) for line in f.read().splitlines() if ":" in line)
    except OSError:
        pass
    hwm = status.get("VmHWM", "").split()
    rss = int(hwm[0]) * 1024 if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {"rss": rss, "read": int(io.get("rchar", 0))}


def child_flowkit(out: str, argv: list[str]) -> None:
    from flowkit.cli import main

    rc = main(argv)
    Path(out).write_text(json.dumps({**_stats(), "rc": rc}))


def child_vtk(out: str, path: str, n_seeds: int) -> None:
    import h5py
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkSMPTools

    vtkSMPTools.SetBackend("STDThread")
    vtkSMPTools.Initialize(os.cpu_count())
    t0 = time.perf_counter()
    # VTK's point order is x fastest, the file's z fastest: rather than a transposed copy, VTK
    # sees the axes reversed (its x is the file's z: an image of nz x ny x nx nodes, the vector
    # components and the seeds reversed to match), which is the same flow mirrored
    with h5py.File(path, "r") as f:
        ds = f["vectors/U"]
        nx, ny, nz, _ = ds.shape
        x = f["x"][()]
        vec = np.empty((nx, ny, nz, 3), np.float32)
        for i0 in range(0, nx, CHUNK):
            sl = np.s_[i0:i0 + CHUNK]
            ds.read_direct(vec, source_sel=sl, dest_sel=sl)
            vec[sl] = vec[sl][..., ::-1]
    t_read = time.perf_counter() - t0
    img = vtk.vtkImageData()
    img.SetDimensions(nz, ny, nx)
    img.SetOrigin(x[0], x[0], x[0])
    h = x[1] - x[0]
    img.SetSpacing(h, h, h)
    arr = numpy_to_vtk(vec.reshape(-1, 3), deep=0)
    arr.SetName("U")
    img.GetPointData().SetVectors(arr)
    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(seeds(n_seeds)[:, ::-1]), deep=1))
    src = vtk.vtkPolyData()
    src.SetPoints(pts)
    st = vtk.vtkStreamTracer()
    st.SetInputData(img)
    st.SetSourceData(src)
    st.SetIntegratorTypeToRungeKutta45()
    st.SetIntegrationDirectionToForward()
    st.SetIntegrationStepUnit(st.CELL_LENGTH_UNIT)
    st.SetInitialIntegrationStep(0.5)
    st.SetMinimumIntegrationStep(0.01)
    st.SetMaximumIntegrationStep(2.0)
    st.SetMaximumError(1e-5)
    st.SetMaximumPropagation(10.0)
    st.SetMaximumNumberOfSteps(10**9)
    t0 = time.perf_counter()
    st.Update()
    t_trace = time.perf_counter() - t0
    n_lines = st.GetOutput().GetNumberOfLines()
    n_points = len(vtk_to_numpy(st.GetOutput().GetPoints().GetData()))
    Path(out).write_text(json.dumps({**_stats(), "rc": 0, "lines": n_lines, "points": n_points,
                                     "read_s": t_read, "trace_s": t_trace}))


def _same_lines(a: Path, b: Path) -> str:
    """Whether two lines files hold the same vertices, offsets and reasons ("yes" or why not)."""
    import h5py

    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        for name in ("x", "y", "z", "rowSize", "reason"):
            if name in fa and not np.array_equal(fa[name][()], fb[name][()]):
                return f"no ({name} differs)"
    return "yes"


def run(label: str, args: list[str]) -> dict:
    """One child process: wall time, peak RSS, bytes read."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as tmp:
        out = tmp.name
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, __file__, *args[:1], out, *args[1:]],
                          capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t
    res = json.loads(Path(out).read_text()) if Path(out).stat().st_size else {"rc": "crashed"}
    Path(out).unlink()
    res.update(label=label, wall=wall)
    if proc.returncode != 0 or res.get("rc") != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        res["error"] = " | ".join(tail)
    print(f"{label:<44} {wall:8.2f} s  peak RSS {res.get('rss', 0) / 1e9:6.2f} GB  "
          f"read {res.get('read', 0) / 1e9:7.2f} GB"
          + (f"  (reading {res['read_s']:.2f} s, tracing {res['trace_s']:.2f} s, "
             f"{res['lines']} lines, {res['points']} points)" if "trace_s" in res else "")
          + (f"  ERROR {res['error']}" if "error" in res else ""), flush=True)
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=512, help="nodes per axis (default 512)")
    ap.add_argument("--seeds", type=int, default=10_000, help="random seeds (default 10000)")
    ap.add_argument("--dir", default=None, help="where to write the field (default: a temp dir)")
    ap.add_argument("--keep", action="store_true", help="keep the generated field file")
    ap.add_argument("--skip", default="", help="comma-separated: vtk, stats, octant, whole (the "
                    "trace without --memory)")
    ap.add_argument("--memory", action="append", default=[],
                    help="also trace under this memory budget (e.g. 3GB; repeatable)")
    args = ap.parse_args(argv)
    skip = set(filter(None, args.skip.split(",")))
    folder = Path(args.dir or tempfile.mkdtemp(prefix="flowkit-bigfield-"))
    path = folder / f"abc_{args.n}.h5"
    lines = folder / "lines.h5"
    try:
        if not path.exists():
            t = time.perf_counter()
            write_abc(path, args.n)
            print(f"wrote {path} ({path.stat().st_size / 1e9:.2f} GB) in "
                  f"{time.perf_counter() - t:.1f} s", flush=True)
        u_bytes = args.n ** 3 * 12
        print(f"ABC {args.n}^3 float32, U {u_bytes / 1e9:.2f} GB; {args.seeds} seeds, "
              f"max length 10, rtol 1e-5; {os.cpu_count()} cores")
        res = {"info": run("flowkit info", ["_flowkit", "info", str(path)])}
        if "stats" not in skip:
            res["stats"] = run("flowkit info --stats", ["_flowkit", "info", str(path), "--stats"])
        common = ["--max-length", "10", "--rtol", "1e-5"]
        every = ["--seeds", f"random:{args.seeds}:0", *common]
        if "whole" not in skip:
            res["trace"] = run("flowkit trace", ["_flowkit", "trace", str(path), *every,
                                                 "-o", str(lines)])
        for m in args.memory:
            out = folder / f"lines_{m}.h5"
            res[m] = r = run(f"flowkit trace --memory {m}", [
                "_flowkit", "trace", str(path), *every, "-o", str(out), "--memory", m])
            print(f"  re-read factor (bytes read / U): {r.get('read', 0) / u_bytes:.2f}; "
                  + (f"lines equal to the first trace's: {_same_lines(lines, out)}"
                     if "trace" in res else ""), flush=True)
            out.unlink(missing_ok=True)
        if "octant" not in skip:
            k = max(1, args.seeds // 100)
            res["octant"] = run(f"flowkit trace, {k} seeds in one octant", [
                "_flowkit", "trace", str(path), "--seeds",
                f"box:0,0,0:{EXTENT / 2},{EXTENT / 2},{EXTENT / 2}:{k}:random:0", *common,
                "-o", str(lines.with_name("octant.h5"))])
            lines.with_name("octant.h5").unlink(missing_ok=True)
        if "vtk" not in skip:
            res["vtk"] = run("VTK vtkStreamTracer (h5py read, float32)",
                             ["_vtk", str(path), str(args.seeds)])
        tr, vt = res.get("trace", {}), res.get("vtk")
        print(f"\npeak RSS of the trace / (U + 0.5 GB): {tr.get('rss', 0) / (u_bytes + 5e8):.2f}")
        if vt and tr and "error" not in vt and "error" not in tr:
            print(f"wall time flowkit trace / VTK: {tr['wall'] / vt['wall']:.2f}")
        if "octant" in res:
            print(f"octant trace read {res['octant'].get('read', 0) / path.stat().st_size:.2f} "
                  "of the file")
    finally:
        lines.unlink(missing_ok=True)
        if not args.keep:
            path.unlink(missing_ok=True)
            if args.dir is None:
                folder.rmdir()
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "_flowkit":
        child_flowkit(sys.argv[2], sys.argv[3:])
    elif len(sys.argv) > 2 and sys.argv[1] == "_vtk":
        child_vtk(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        sys.exit(main())
