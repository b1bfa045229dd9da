"""Viewer: time from a style parameter change to the updated frame, on bench_render's scene.

2500 lines x 1000 vertices (2.5M vertices, bench_render.scene) with bench_render's halo style in a
real window (glfw; under Xvfb when there is no DISPLAY: this script starts one), llvmpipe here.
Each figure is one change -> ``Viewer.step()`` (events, style file poll, panel, scene draw, blit,
panel draw, swap) -> glFinish, repeated ``--repeat`` times, interleaved over the kinds:

- redraw:          the same frame drawn again (no change): what every change below costs at least
- uniform (panel): a band colour changed through ``Viewer.edit`` (what a panel widget does)
- uniform (file):  the same change saved to the watched style file (read, parse, validate)
- recompile:       a change of template flags (the halo's colour constant <-> colour-mapped on
                   speed, about the same fragment cost either way) whose program is
                   not compiled yet (the program cache is emptied first; Mesa's on-disk shader
                   cache is off for the run, so this is a cold compile)
- program switch:  the same change when both programs are already compiled
- camera (orbit):  an orbit step (level-of-detail selection + draw, no style change)

Then the probe: ``Viewer.pick`` (the vertex under the cursor, CPU k-d tree) at ``--probes``
random cursor positions over the scene, best / median / max, and how many found a vertex;
and the time the k-d tree took to build (in a background thread from the window's start).

Best and median per kind; ratios against "redraw" from this run; the load average, since
the machine is shared.

    .venv/bin/python benchmarks/bench_viewer.py [--lines 2500 --vertices 1000 --repeat 5
    --size 1280x720]
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_render import halo_style, scene

from flowkit.render.style import ColorMap, save_style

PROBE = "probe (pick the vertex under the cursor)"
KINDS = ("redraw", "uniform (panel)", "uniform (file)", "recompile", "program switch",
         "camera (orbit)")


@contextlib.contextmanager
def display():
    """The current DISPLAY, or a private Xvfb for the run."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        raise SystemExit("no DISPLAY and no Xvfb (apt-get install xvfb): the viewer needs one")
    r, w = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(w), "-screen", "0", "1920x1200x24",
                             "-nolisten", "tcp"], pass_fds=(w,), stderr=subprocess.DEVNULL)
    os.close(w)
    with os.fdopen(r) as f:
        os.environ["DISPLAY"] = ":" + f.readline().strip()
    try:
        yield os.environ["DISPLAY"]
    finally:
        import glfw

        glfw.terminate()
        del os.environ["DISPLAY"]
        proc.terminate()
        proc.wait(10)


def measure(lines, size, repeat: int, probes: int) -> dict[str, list[float]]:
    from flowkit.view.app import Viewer

    colors = [(0.0, 0.0, 0.0, 1.0), (0.2, 0.0, 0.4, 1.0)]
    base = halo_style("smooth")
    times: dict[str, list[float]] = {k: [] for k in KINDS}
    with tempfile.TemporaryDirectory() as d:
        path = save_style(base, Path(d) / "style.toml")
        with Viewer(lines, path, size=size, vsync=False, screenshot_dir=d) as v:
            for _ in range(3):  # warm: first draw, level-of-detail caches
                v.step()
            v.finish()
            core = ("styles", "default", "bands", 0, "color")
            halo = ("styles", "default", "bands", 1, "color")
            mapped = ColorMap("gray", "speed", (0.0, 0.3))

            def timed(kind, change, expect):
                t0 = time.perf_counter()
                change()
                v.step()
                v.finish()
                times[kind].append(time.perf_counter() - t0)
                assert v.last_update == expect and v.error is None, (kind, v.last_update, v.error)

            def other():  # a core colour different from the current one
                return colors[v.style.line_style.bands[0].color == colors[0]]

            for _ in range(repeat):
                timed("redraw", v.invalidate, v.last_update)
                timed("uniform (panel)", lambda: v.edit(core, other()), "uniforms")
                bands = v.style.line_style.bands
                edited = dataclasses.replace(v.style, styles={"default": dataclasses.replace(
                    v.style.line_style, bands=(dataclasses.replace(bands[0], color=other()),
                                               *bands[1:]))})
                timed("uniform (file)", lambda s=edited: save_style(s, path), "uniforms")
                new = mapped if v.style.line_style.bands[1].color != mapped else (1, 1, 1, 1.0)
                cache = v.renderer.programs.programs  # forget all but the current program
                for flags in [f for f in cache if f != v.flags]:  # (kept alive: no id reuse)
                    del cache[flags]
                timed("recompile", lambda c=new: v.edit(halo, c), "recompile")
                new = mapped if v.style.line_style.bands[1].color != mapped else (1, 1, 1, 1.0)
                timed("program switch", lambda c=new: v.edit(halo, c), "recompile")
                last = v.updates.copy()
                timed("camera (orbit)", lambda: v.on_drag(2.0, 0.0), v.last_update)
                assert v.updates == last
            info = {"vertices drawn": v.renderer.n_drawn, "size": v.size, "scene": v.scene_size,
                    "renderer": v.ctx.info["GL_RENDERER"]}
            t0 = time.perf_counter()
            v.picker.tree  # noqa: B018  (waits for the build, started with the window)
            info["index wait"] = time.perf_counter() - t0
            info["index build"] = v.picker.build_time
            rng = np.random.default_rng(1)
            sw, sh = v.scene_size
            times[PROBE], hits = [], 0
            for _ in range(probes):
                x, y = rng.uniform(0, sw), rng.uniform(0, sh)
                t0 = time.perf_counter()
                hits += v.pick(x, y) is not None
                times[PROBE].append(time.perf_counter() - t0)
            info["hits"] = hits
    return times, info


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--lines", type=int, default=2500)
    p.add_argument("--vertices", type=int, default=1000)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--size", default="1280x720")
    p.add_argument("--probes", type=int, default=200)
    a = p.parse_args(argv)
    size = tuple(int(x) for x in a.size.lower().split("x"))
    os.environ["MESA_SHADER_CACHE_DISABLE"] = "true"  # read when the GL context is made
    lines = scene(a.lines, a.vertices)
    with display():
        times, info = measure(lines, size, a.repeat, a.probes)
    load = os.getloadavg()
    print(f"viewer: {a.lines} lines x {a.vertices} vertices = {lines.n_points} vertices, window "
          f"{info['size'][0]}x{info['size'][1]} (scene {info['scene'][0]}x{info['scene'][1]} "
          f"right of the panel), {info['renderer']}, "
          f"{info['vertices drawn']} vertices drawn (level of detail)")
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores; "
          f"{a.repeat} repeats, interleaved")
    ref = min(times["redraw"])
    print(f"{'change -> updated frame (glFinish)':38s} {'best ms':>9s} {'median ms':>10s} "
          f"{'best / redraw':>14s}")
    for k in KINDS:
        t = times[k]
        print(f"{k:38s} {1e3 * min(t):9.1f} {1e3 * statistics.median(t):10.1f} "
              f"{min(t) / ref:14.2f}")
    t = times[PROBE]
    p95 = float(np.percentile(t, 95))
    print(f"{PROBE}: best {1e3 * min(t):.2f} ms, median {1e3 * statistics.median(t):.2f} ms, "
          f"95th percentile {1e3 * p95:.2f} ms, max {1e3 * max(t):.2f} ms over {len(t)} random cursor positions ({info['hits']} on a "
          f"line); k-d tree of {lines.n_points} vertices built in {info['index build']:.2f} s "
          f"(background thread; waited {info['index wait']:.2f} s for it after the timings)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
