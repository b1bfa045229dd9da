"""Frame time of the two-band halo style vs VTK's plain wide lines, same lines, same run.

2500 lines x 1000 vertices (2.5M vertices) at 1920x1080, seen from the same camera by both.
flowkit: headless EGL, geometry uploaded once; every frame turns the camera by 0.1 degree (so the
per-frame level-of-detail selection runs every frame), draws, resolves and reads back to host
memory (the read-back waits for the rasterizer, so the time is honest).  VTK: vtkPolyData lines,
LineWidth 4, offscreen render window, no MSAA, the same camera turns, rendered and read back
the same way.  Each figure is the best of ``--frames`` frames after 2 warm-up frames (best, not
mean: the machine is shared), wall time and process CPU time (all threads); ratios compare
figures taken in this run.

``strips``: the same halo frames with the strips built in the vertex shader (the default) and
in a lines_adjacency geometry shader, two renderers drawn alternately frame by frame (both see
the same load), with and without antialiasing.

    .venv/bin/python benchmarks/bench_render.py [--lines 2500 --vertices 1000 --frames 5]
    [--only default,msaa,none,full,strips,vtk]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from flowkit.lines import Lines
from flowkit.render import Band, Camera, LineRenderer, LineStyle, Style

BACKGROUND = (0.8, 0.8, 0.8, 1.0)


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
                 background=BACKGROUND, antialias=antialias)


def camera(frame: int) -> Camera:
    return Camera(azimuth=-60.0 + 0.1 * frame)


def best_of(frames: int, draw) -> tuple[float, float, np.ndarray]:
    """(best wall s, best CPU s, last image) over ``frames`` frames after 2 warm-up frames."""
    wall, cpu, img = [], [], None
    for k in range(frames + 2):
        t0, c0 = time.perf_counter(), time.process_time()
        img = draw(k)
        if k >= 2:
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    return min(wall), min(cpu), img


def time_flowkit(lines: Lines, size, frames: int, antialias: str, **renderer_args):
    style = halo_style(antialias)
    with LineRenderer(lines, **renderer_args) as r:
        def draw(k):
            r.draw(style, size, camera(k))
            return r.read()
        wall, cpu, img = best_of(frames, draw)
        info = {"samples": r.samples_for(style), "kept": r.n_drawn}
    return wall, cpu, img, info


def time_strips(lines: Lines, size, frames: int, antialias: str, tolerance=None) -> dict:
    """{stage: (best wall s, best CPU s, drawn points)}: vertex- and geometry-shader strips,
    frames interleaved."""
    style = halo_style(antialias)
    out = {}
    with (LineRenderer(lines, tolerance=tolerance) as rv,
          LineRenderer(lines, ctx=rv.ctx, tolerance=tolerance, strips="geometry") as rg):
        times = {"vertex": ([], []), "geometry": ([], [])}
        for k in range(frames + 2):
            for stage, r in (("vertex", rv), ("geometry", rg)):
                t0, c0 = time.perf_counter(), time.process_time()
                r.draw(style, size, camera(k))
                r.read()
                if k >= 2:
                    times[stage][0].append(time.perf_counter() - t0)
                    times[stage][1].append(time.process_time() - c0)
                out[stage] = r.n_drawn
        return {st: (min(w), min(c), out[st]) for st, (w, c) in times.items()}


def time_vtk(lines: Lines, size, frames: int):
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray, vtk_to_numpy

    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(lines.points, np.float32), deep=True))
    conn = np.arange(lines.n_points, dtype=np.int64)
    cells = vtk.vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(lines.offsets.astype(np.int64), deep=True),
                  numpy_to_vtkIdTypeArray(conn, deep=True))
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    poly.SetLines(cells)
    assert poly.GetNumberOfCells() == len(lines)
    mapper = vtk.vtkPolyDataMapper()
    mapper.SetInputData(poly)
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetLineWidth(4)
    actor.GetProperty().SetColor(0, 0, 0)
    ren = vtk.vtkRenderer()
    ren.SetBackground(*BACKGROUND[:3])
    ren.AddActor(actor)
    rw = vtk.vtkRenderWindow()
    rw.SetOffScreenRendering(1)
    rw.SetMultiSamples(0)
    rw.AddRenderer(ren)
    rw.SetSize(*size)
    buf = vtk.vtkUnsignedCharArray()
    bounds = lines.bounds()
    vcam = ren.GetActiveCamera()

    def draw(k):
        c = camera(k)  # the same eye, target, up and field of view as flowkit's
        setup = c.setup(bounds, *size)
        vcam.SetPosition(*setup.eye)
        vcam.SetFocalPoint(*bounds.mean(axis=1))
        vcam.SetViewUp(*c.choose_up(bounds, *size))  # (flowkit picks an up when none is set)
        vcam.SetViewAngle(c.fov)
        ren.ResetCameraClippingRange()
        rw.Render()
        rw.GetRGBACharPixelData(0, 0, size[0] - 1, size[1] - 1, 0, buf)  # waits for the GPU
        return vtk_to_numpy(buf).reshape(size[1], size[0], 4)

    wall, cpu, img = best_of(frames, draw)
    return wall, cpu, img, type(rw).__name__, rw.ReportCapabilities().splitlines()[:3]


def ink(img: np.ndarray) -> float:
    """Fraction of pixels that are not background."""
    bg = np.rint(np.array(BACKGROUND[:3]) * 255)
    return float(np.mean(np.any(np.abs(img[..., :3].astype(int) - bg) > 2, axis=2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=2500)
    ap.add_argument("--vertices", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--only", default="default,msaa,none,full,strips,vtk",
                    help="comma-separated runs: default, msaa, none, full, strips, vtk")
    a = ap.parse_args()
    runs = a.only.split(",")
    size = tuple(int(v) for v in a.size.split("x"))
    lines = scene(a.lines, a.vertices)
    from flowkit.render import default_context

    info = default_context().info
    print(f"{a.lines} lines x {a.vertices} vertices = {lines.n_points:,} vertices at "
          f"{size[0]}x{size[1]}; best of {a.frames} frames after 2 warm-up frames")
    print(f"flowkit GL: {info['GL_RENDERER']} / {info['GL_VERSION']}; "
          f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} cpus")
    rows = {}
    variants = {
        "default": ("flowkit halo, defaults (antialias='msaa' style)", "msaa", {}),
        "msaa": ("flowkit halo, 4x MSAA forced", "msaa", {"msaa": True}),
        "none": ("flowkit halo, no antialiasing", "none", {}),
        "full": ("flowkit halo, defaults, every vertex (tolerance 0)", "msaa", {"tolerance": 0.0}),
    }
    for key, (label, aa, kw) in variants.items():
        if key not in runs:
            continue
        wall, cpu, img, fi = time_flowkit(lines, size, a.frames, aa, **kw)
        aa_name = f"{fi['samples']}x MSAA" if fi["samples"] > 1 else (
            "analytic edges" if aa != "none" else "none")
        label = f"{label} [{aa_name}; {fi['kept']:,} vertices drawn]"
        rows[key] = (label, wall, cpu, ink(img))
    if "strips" in runs:
        # defaults (level of detail), no AA, and every vertex (tolerance 0, as on a GPU)
        for aa, tol in (("msaa", None), ("none", None), ("msaa", 0.0)):
            t = time_strips(lines, size, a.frames, aa, tol)
            name = f"{aa}{'' if tol is None else ', tol 0'}"
            for stage, (wall, cpu, kept) in t.items():
                print(f"strips [{name}] {stage:8} {wall * 1e3:8.1f} ms wall {cpu * 1e3:8.1f} ms "
                      f"CPU  {kept:>9,} points drawn")
            (wv, cv, _), (wg, cg, _) = t["vertex"], t["geometry"]
            print(f"strips [{name}] geometry / vertex: wall {wg / wv:.2f}, CPU {cg / cv:.2f} "
                  f"(interleaved frames, load {os.getloadavg()[0]:.2f})")
    if "vtk" in runs:
        try:
            wall, cpu, img, rw_name, caps = time_vtk(lines, size, a.frames)
            caps = "; ".join(c.strip() for c in caps)
            rows["vtk"] = (f"VTK plain lines, LineWidth 4, no MSAA ({rw_name}) [{caps}]",
                           wall, cpu, ink(img))
        except ImportError:
            print("vtk not installed (pip install '.[bench]'): no comparison")
    print(f"{'':4}{'ms/frame wall':>14}{'ms CPU':>9}{'ink':>7}{'/VTK wall':>10}{'/VTK CPU':>9}")
    vtk_row = rows.get("vtk")
    for key, (label, wall, cpu, cover) in rows.items():
        ratio = (f"{wall / vtk_row[1]:10.2f}{cpu / vtk_row[2]:9.2f}" if vtk_row else "")
        print(f"{key:8}{wall * 1e3:10.1f}{cpu * 1e3:9.1f}{cover:7.1%}{ratio}  {label}")
    print("ratios < 1: flowkit faster than VTK; ink: fraction of non-background pixels")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
