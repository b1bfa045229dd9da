"""Frame time of the two-band halo style vs VTK's plain wide lines, same lines, same run.

2500 lines x 1000 vertices (2.5M vertices) at 1920x1080.  flowkit: headless EGL, geometry
uploaded once, each frame drawn, resolved and read back to host memory (the read-back waits
for the GPU, so the time is honest).  VTK: vtkPolyData lines, LineWidth 4, offscreen render
window (EGL in the VTK wheel), each frame rendered and read back the same way.

    .venv/bin/python benchmarks/bench_render.py [--lines 2500 --vertices 1000 --frames 5]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from flowkit.lines import Lines
from flowkit.render import Band, Camera, LineRenderer, LineStyle, Style


def scene(n_lines: int, n_vertices: int, seed: int = 0) -> Lines:
    """Smooth random curves filling a unit-ish box (sums of a few sines per axis)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n_vertices)
    freq = rng.uniform(0.5, 3.0, (n_lines, 3, 3))
    phase = rng.uniform(0, 2 * np.pi, (n_lines, 3, 3))
    amp = rng.uniform(0.1, 0.4, (n_lines, 3, 3))
    start = rng.uniform(-1, 1, (n_lines, 3))
    pts = start[:, None, :] + np.einsum(
        "lak,lakt->lta", amp, np.sin(2 * np.pi * freq[..., None] * t + phase[..., None]))
    speed = np.linalg.norm(np.gradient(pts, axis=1), axis=2)
    offsets = np.arange(n_lines + 1) * n_vertices
    return Lines(pts.reshape(-1, 3), offsets, {"speed": speed.reshape(-1)})


def halo_style(antialias: str) -> Style:
    # 2 x (1.5 + 1) = 5 px wide: a black core with a white depth-dependent halo
    return Style(styles={"default": LineStyle((Band((0, 0, 0, 1), 1.5),
                                               Band((1, 1, 1, 1), 1.0, depth_offset=0.02)))},
                 background=(0.8, 0.8, 0.8, 1.0), antialias=antialias)


def time_flowkit(lines: Lines, size, frames: int, antialias: str) -> float:
    r = LineRenderer(lines)
    style = halo_style(antialias)
    cam = Camera()
    for _ in range(2):  # warm-up: compile, first upload of framebuffers
        r.draw(style, size, cam)
        r.read()
    t0 = time.perf_counter()
    for _ in range(frames):
        r.draw(style, size, cam)
        r.read()
    dt = (time.perf_counter() - t0) / frames
    r.release()
    return dt


def time_vtk(lines: Lines, size, frames: int):
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray

    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(lines.points, np.float32), deep=True))
    n = lines.lengths
    conn = np.arange(lines.n_points, dtype=np.int64)
    cells = vtk.vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(lines.offsets.astype(np.int64), deep=True),
                  numpy_to_vtkIdTypeArray(conn, deep=True))
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    poly.SetLines(cells)
    assert poly.GetNumberOfCells() == len(n)
    mapper = vtk.vtkPolyDataMapper()
    mapper.SetInputData(poly)
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetLineWidth(4)
    actor.GetProperty().SetColor(0, 0, 0)
    ren = vtk.vtkRenderer()
    ren.SetBackground(0.8, 0.8, 0.8)
    ren.AddActor(actor)
    rw = vtk.vtkRenderWindow()
    rw.SetOffScreenRendering(1)
    rw.SetMultiSamples(0)
    rw.AddRenderer(ren)
    rw.SetSize(*size)
    ren.ResetCamera()
    ren.GetActiveCamera().Azimuth(30)
    buf = vtk.vtkUnsignedCharArray()

    def frame():
        rw.Render()
        rw.GetRGBACharPixelData(0, 0, size[0] - 1, size[1] - 1, 0, buf)  # waits for the GPU

    for _ in range(2):
        frame()
    t0 = time.perf_counter()
    for _ in range(frames):
        frame()
    dt = (time.perf_counter() - t0) / frames
    return dt, type(rw).__name__, rw.ReportCapabilities().splitlines()[:3]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=2500)
    ap.add_argument("--vertices", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--size", default="1920x1080")
    a = ap.parse_args()
    size = tuple(int(v) for v in a.size.split("x"))
    lines = scene(a.lines, a.vertices)
    from flowkit.render import default_context

    info = default_context().info
    print(f"{a.lines} lines x {a.vertices} vertices = {lines.n_points:,} vertices at "
          f"{size[0]}x{size[1]}; {a.frames} frames after 2 warm-up frames")
    print(f"flowkit GL: {info['GL_RENDERER']} / {info['GL_VERSION']}; "
          f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} cpus")
    fk_msaa = time_flowkit(lines, size, a.frames, "msaa")
    print(f"flowkit halo style, 4x MSAA + band smoothing : {fk_msaa * 1e3:8.1f} ms/frame")
    fk_none = time_flowkit(lines, size, a.frames, "none")
    print(f"flowkit halo style, no antialiasing          : {fk_none * 1e3:8.1f} ms/frame")
    try:
        vt, rw_name, caps = time_vtk(lines, size, a.frames)
    except ImportError:
        print("vtk not installed (pip install '.[bench]'): no comparison")
        return
    print(f"VTK plain lines, LineWidth 4, no MSAA ({rw_name}): {vt * 1e3:8.1f} ms/frame "
          f"[{'; '.join(c.strip() for c in caps)}]")
    print(f"ratio flowkit(MSAA halo) / VTK(plain wide lines): {fk_msaa / vt:.2f}  "
          f"(< 1 means flowkit is faster)")
    print(f"ratio flowkit(no-AA halo) / VTK(plain wide lines): {fk_none / vt:.2f}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
