"""Frame time of the full transfer-function style (a transfer function choosing between two
styles, arrow and dash shapes, a directional colour pattern over a colormap, depth-dependent
halo) next to the plain two-band halo style, same lines, same run.

The scene is bench_render's (2500 lines x 1000 vertices = 2.5M vertices at 1920x1080) plus the
attributes the full style reads: arc_length and a pseudo integration time (arc length / speed
summed).  Both styles are 5 pixels wide at their widest; each frame is drawn, resolved and read
back (the read-back waits for the GPU).  Goal: full < 1.5 x plain.  Wall and process CPU time
(all threads), best of the frames: the machine is shared.

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
from bench_render import camera, halo_style, scene

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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=2500)
    ap.add_argument("--vertices", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--aa", default="msaa,none", help="antialias settings to time")
    a = ap.parse_args()
    size = tuple(int(v) for v in a.size.split("x"))
    lines = with_line_attributes(scene(a.lines, a.vertices))
    sp = lines.point_data["speed"]
    print(f"{a.lines} lines x {a.vertices} vertices = {lines.n_points:,} vertices at "
          f"{size[0]}x{size[1]}; plain and full interleaved frame by frame, the camera turning "
          f"0.1 degree per frame (level of detail recomputed), best of {a.frames} after 2 "
          f"warm-up; speed median {np.median(sp):.4f} (transfer bound 0.004: "
          f"{np.mean(sp >= 0.004):.0%} focus)")
    with LineRenderer(lines) as r:
        info = r.ctx.info
        print(f"GL: {info['GL_RENDERER']} / {info['GL_VERSION']}; load average "
              f"{os.getloadavg()[0]:.2f}, {os.cpu_count()} cpus")
        for aa in a.aa.split(","):
            styles = {"plain": halo_style(aa), "full": full_style(aa)}
            wall = {k: [] for k in styles}
            cpu = {k: [] for k in styles}
            kept = {}
            for f in range(a.frames + 2):
                for k, st in styles.items():  # interleaved: both see the same load
                    t0, c0 = time.perf_counter(), time.process_time()
                    r.draw(st, size, camera(f))
                    r.read()
                    if f >= 2:
                        wall[k].append(time.perf_counter() - t0)
                        cpu[k].append(time.process_time() - c0)
                    kept[k] = r.n_drawn
            w = {k: min(v) * 1e3 for k, v in wall.items()}
            c = {k: min(v) * 1e3 for k, v in cpu.items()}
            for k in styles:
                print(f"[{aa:4s}] {k:5s} {w[k]:8.1f} ms wall {c[k]:8.1f} ms CPU  "
                      f"{kept[k]:>9,} vertices drawn")
            print(f"[{aa:4s}] ratio full/plain: wall {w['full'] / w['plain']:.2f}, CPU "
                  f"{c['full'] / c['plain']:.2f} (goal < 1.5)")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
