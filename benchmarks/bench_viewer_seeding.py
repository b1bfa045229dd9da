"""Viewer, live seeding: time from a rake handle drag to the frame showing the lines traced again.

The heated room (examples/hotroom_scene.toml: its field, trace options, halo style and camera),
a line rake of ``--seeds`` seeds (default 200) across the room 60 cm above the floor, in a real
window (glfw; under Xvfb when there is no DISPLAY: bench_viewer's ``display``), panel hidden.
Warm: the numba kernel is compiled (and one drag done) before timing.  Each repeat drags the
rake's end handle a few pixels (alternately left and right) and times ``Viewer.step()`` (trace
+ the new lines into the renderer + draw + overlays + swap) with glFinish, split into the trace
and the rest; then whether a drag would trace live (``Viewer.live_time`` against
``app.LIVE_SECONDS``).

    .venv/bin/python benchmarks/bench_viewer_seeding.py [--seeds 200 --repeat 15 --size 1280x720]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_viewer import display


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--tolerance", type=float, help="the renderer's level-of-detail tolerance "
                    "in pixels (default: the viewer's; 0 draws every vertex)")
    ap.add_argument("--scene", default=str(ROOT / "examples" / "hotroom_scene.toml"))
    args = ap.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    with display():
        from flowkit.view.app import LIVE_SECONDS, Viewer
        from flowkit.view.seeding import open_scene

        rake = f"line:1,0.6,1:9,0.6,9:{args.seeds}"
        s = open_scene(args.scene, rake=rake)
        v = Viewer(s.lines, s.style_path, size=size, vsync=False, camera=s.camera,
                   seeding=s.seeding, units=s.units, tolerance=args.tolerance)
        try:
            v.show_panel = False
            v.step()
            total, traced = [], []
            for k in range(args.repeat + 1):
                x, y = v.handle_xy("end")
                assert v.grab(x, y) == "end"
                v.on_drag(6 if k % 2 else -6, 0)
                v.release()
                t0 = time.perf_counter()
                v.step()
                v.finish()
                if k:  # the first is the warm-up
                    total.append(time.perf_counter() - t0)
                    traced.append(v.trace_time)
            n = len(v.lines)
            print(f"heated room, {n} lines, {v.lines.n_points} vertices, window "
                  f"{size[0]}x{size[1]}, {args.repeat} drags, load average "
                  f"{os.getloadavg()[0]:.1f}")
            print("| after a rake drag | best ms | median ms |")
            print("| --- | ---: | ---: |")
            rest = [a - b for a, b in zip(total, traced)]
            for name, xs in (("re-trace (flowkit.trace, warm)", traced),
                             ("new lines into the renderer + redraw + frame", rest),
                             ("re-trace + redraw (the frame)", total)):
                print(f"| {name} | {1e3 * min(xs):.1f} | {1e3 * statistics.median(xs):.1f} |")
            med = statistics.median(total)
            print(f"goal <= 100 ms: median {1e3 * med:.0f} ms "
                  f"({'met' if med <= 0.1 else 'not met'})")
            live = v.live_time()
            print(f"live while dragging: {'yes' if live <= LIVE_SECONDS else 'no'} (re-trace + "
                  f"redraw of the scene, median of the last frames {1e3 * live:.0f} ms, limit "
                  f"{1e3 * LIVE_SECONDS:.0f} ms)")
        finally:
            v.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
