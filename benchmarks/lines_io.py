"""Lines file I/O: flowkit's lines.h5 against the floor (plain h5py, one dataset per array, no
layout) and against VTK's own XML PolyData writer (.vtp, what a ParaView user would save), on the
same lines in the same run. Prints wall times, sizes and ratios.

    .venv/bin/python benchmarks/lines_io.py [--lines 2000] [--vertices 1000]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from flowkit.io.lines_h5 import LinesWriter, read_lines, write_lines
from flowkit.lines import Lines


def make(n_lines: int, n_vertices: int) -> Lines:
    rng = np.random.default_rng(0)
    n = n_lines * n_vertices
    steps = rng.normal(scale=1e-2, size=(n, 3))
    return Lines(np.cumsum(steps, axis=0), np.arange(0, n + 1, n_vertices),
                 {"time": np.linspace(0, 1, n), "arc_length": np.cumsum(np.abs(steps[:, 0])),
                  "speed": rng.random(n), "velocity": rng.normal(size=(n, 3))},
                 {"seed_id": np.arange(n_lines), "reason": np.ones(n_lines, np.int8),
                  "n_accepted": np.full(n_lines, n_vertices, np.int32),
                  "n_rejected": np.zeros(n_lines, np.int32)},
                 {"method": "dopri5"})


def best(fn, repeat=3) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def floor_write(lines: Lines, path: Path) -> None:
    with h5py.File(path, "w") as f:
        f["points"] = lines.points.astype(np.float32)
        f["offsets"] = lines.offsets
        for k, v in {**lines.point_data, **lines.line_data}.items():
            f[k] = v


def vtp_write(lines: Lines, path: Path) -> None:
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    poly = vtk.vtkPolyData()
    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(lines.points.astype(np.float32), deep=True))
    poly.SetPoints(pts)
    cells = vtk.vtkCellArray()
    cells.SetData(numpy_to_vtk(lines.offsets, deep=True),
                  numpy_to_vtk(np.arange(lines.n_points), deep=True))
    poly.SetLines(cells)
    for data, arrays in ((poly.GetPointData(), lines.point_data),
                         (poly.GetCellData(), lines.line_data)):
        for k, v in arrays.items():
            a = numpy_to_vtk(np.ascontiguousarray(v), deep=True)
            a.SetName(k)
            data.AddArray(a)
    w = vtk.vtkXMLPolyDataWriter()
    w.SetFileName(str(path))
    w.SetInputData(poly)
    w.SetDataModeToAppended()
    w.SetCompressorTypeToZLib()
    w.Write()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=2000)
    ap.add_argument("--vertices", type=int, default=1000)
    args = ap.parse_args()
    lines = make(args.lines, args.vertices)
    print(f"{len(lines)} lines x {args.vertices} vertices = {lines.n_points} vertices, "
          f"attributes {list(lines.point_data)} + {list(lines.line_data)}; "
          f"load average {os.getloadavg()[0]:.2f}")
    rows = []
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        floor = best(lambda: floor_write(lines, d / "floor.h5"))
        rows.append(("plain h5py, no layout (floor)", floor, d / "floor.h5"))
        for comp in (None, "lzf", "gzip"):
            p = d / f"lines_{comp}.h5"
            rows.append((f"flowkit write_lines, {comp}",
                         best(lambda p=p, comp=comp: write_lines(lines, p, compression=comp)), p))
        chunks = [lines[i:i + 200] for i in range(0, len(lines), 200)]

        def streamed():
            with LinesWriter.like(lines, d / "streamed.h5") as w:
                for c in chunks:
                    w.append(c)
        rows.append((f"flowkit LinesWriter, gzip, {len(chunks)} chunks", best(streamed),
                     d / "streamed.h5"))
        try:
            rows.append(("VTK XML .vtp, zlib", best(lambda: vtp_write(lines, d / "l.vtp")),
                         d / "l.vtp"))
        except ImportError:
            print("(vtk not installed: no .vtp comparison)")
        print(f"\n{'writer':<42} {'time s':>8} {'x floor':>8} {'MB':>8}")
        for name, t, p in rows:
            print(f"{name:<42} {t:8.3f} {t / floor:8.2f} {p.stat().st_size / 1e6:8.1f}")
        gz = d / "lines_gzip.h5"
        full = best(lambda: read_lines(gz))
        one = best(lambda: read_lines(gz, attributes=["speed"]))
        raw = best(lambda: read_lines(d / "lines_None.h5"))
        print(f"\nread_lines gzip, all attributes {full:.3f} s; only 'speed' {one:.3f} s "
              f"({full / one:.1f}x less); uncompressed, all {raw:.3f} s")


if __name__ == "__main__":
    main()
