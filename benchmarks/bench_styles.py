"""Frame time of the full issue-6 style (transfer function choosing between two styles, arrow
and dash shapes, a directional colour pattern over a colormap, depth-dependent halo) next to
the plain two-band halo style, same lines, same run.

The scene is bench_render's (2500 lines x 1000 vertices = 2.5M vertices at 1920x1080) plus the
attributes the full style reads: arc_length and a pseudo integration time (arc length / speed
summed).  Both styles are 5 pixels wide at their widest; each frame is drawn, resolved and read
back (the read-back waits for the GPU).  Goal: full < 1.5 x plain.

    .venv/bin/python benchmarks/bench_styles.py [--lines 2500 --vertices 1000 --frames 5]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_render import halo_style, scene

from flowkit.render import Band, ColorMap, LineRenderer, LineStyle, Style
from flowkit.render.style import Pattern, Shape, Transfer, TransferRange


def with_line_attributes(lines):
    """arc_length and time (ds / speed) along each line, per vertex."""
    seg = np.linalg.norm(np.diff(lines.points, axis=0), axis=1)
    start = np.zeros(lines.n_points, bool)
    start[lines.offsets[:-1]] = True
    step = np.r_[0.0, seg]
    step[start] = 0.0
    speed = np.maximum(lines.point_data["speed"], 1e-6)
    dt = np.r_[0.0, seg / (0.5 * (speed[1:] + speed[:-1]))]
    dt[start] = 0.0
    line_start = np.repeat(lines.offsets[:-1], np.diff(lines.offsets))
    cs, ct = np.cumsum(step), np.cumsum(dt)
    lines.point_data["arc_length"] = cs - cs[line_start]
    lines.point_data["time"] = ct - ct[line_start]
    return lines


def full_style(antialias: str) -> Style:
    """Focus: arrow core on time + colour pattern over a colormap + halo; context: thin dashes;
    the transfer function on speed picks between them per fragment."""
    focus = LineStyle((
        Band(ColorMap("viridis", "speed", (0.0, 0.01)), 1.5,
             shape=Shape("arrow", "time", 20.0),
             pattern=Pattern((0, 0, 0, 1), "arc_length", 0.05, 0.5, 1.0, 0.6)),
        Band((1, 1, 1, 1), 1.0, depth_offset=0.02)))
    context = LineStyle((Band((0.5, 0.5, 0.5, 1), 1.0, shape=Shape("dash", "arc_length", 0.03)),))
    return Style(styles={"focus": focus, "context": context},
                 transfer=Transfer("speed", (TransferRange((0.004, np.inf), "focus"),
                                             TransferRange((-np.inf, 0.004), "context")), 0.001),
                 background=(0.8, 0.8, 0.8, 1.0), antialias=antialias)


def time_style(r: LineRenderer, style: Style, size, frames: int) -> float:
    for _ in range(2):  # warm-up: compile, framebuffers, attribute upload
        r.draw(style, size)
        r.read()
    t0 = time.perf_counter()
    for _ in range(frames):
        r.draw(style, size)
        r.read()
    return (time.perf_counter() - t0) / frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=2500)
    ap.add_argument("--vertices", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--size", default="1920x1080")
    a = ap.parse_args()
    size = tuple(int(v) for v in a.size.split("x"))
    lines = with_line_attributes(scene(a.lines, a.vertices))
    sp = lines.point_data["speed"]
    print(f"{a.lines} lines x {a.vertices} vertices = {lines.n_points:,} vertices at "
          f"{size[0]}x{size[1]}; {a.frames} frames after 2 warm-up frames; speed median "
          f"{np.median(sp):.4f} (transfer bound 0.004: {np.mean(sp >= 0.004):.0%} focus)")
    with LineRenderer(lines) as r:
        info = r.ctx.info
        print(f"GL: {info['GL_RENDERER']} / {info['GL_VERSION']}; load average "
              f"{os.getloadavg()[0]:.2f}, {os.cpu_count()} cpus")
        for aa in ("msaa", "none"):
            plain = time_style(r, halo_style(aa), size, a.frames)
            full = time_style(r, full_style(aa), size, a.frames)
            print(f"[{aa:4s}] plain halo {plain * 1e3:8.1f} ms/frame   full transfer+shapes+"
                  f"pattern {full * 1e3:8.1f} ms/frame   ratio full/plain {full / plain:.2f} "
                  f"(goal < 1.5)")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
