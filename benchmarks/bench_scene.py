"""The heated-room demo scene (examples/hotroom_scene.toml), end to end, in one process:

- cold:       empty cache: load the field, trace (speed, T), store, write lines, render 2 views
- style-only: the same scene with its styles' colours changed: cache hit, no trace, re-render
- all on:     empty cache, every attribute traced (time, arc_length, speed, velocity, vorticity,
              vorticity_magnitude, distance_to_seed, T, p): what leaving attributes out saves

A warm-up run first (numba JIT, EGL context, shader compile) so the figures are steady-state.
Each case runs ``--repeat`` times; the median is printed with its per-stage split and the ratios
to the cold run.  ``--grid N`` seeds an N x N plane instead of the scene's 8 x 8 (more work).

    .venv/bin/python benchmarks/bench_scene.py [--repeat 3] [--grid 8]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
from pathlib import Path

from flowkit.integrate.attributes import ATTRIBUTES
from flowkit.scene import load_scene, run_scene

SCENE = Path(__file__).resolve().parents[1] / "examples" / "hotroom_scene.toml"


def restyled(scene):
    """Only colours change: a render-only difference."""
    styles = {n: dataclasses.replace(s, background=(0.95, 0.95, 0.9, 1.0))
              for n, s in scene.styles.items()}
    return dataclasses.replace(scene, styles=styles)


def timed(scene, work: Path, tag: str, **kw):
    out = work / tag
    res = run_scene(scene, out_dir=out, cache_dir=out / "cache", report=None, **kw)
    stages: dict[str, float] = {}
    for s in res.snapshots:
        for k, v in s.seconds.items():
            k = "render" if k.startswith("render ") else k
            stages[k] = stages.get(k, 0.0) + v
    return res.seconds, stages, res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--grid", type=int, default=8, help="seeds: N x N plane (scene: 8)")
    args = ap.parse_args()
    scene = load_scene(SCENE)
    if args.grid != 8:
        scene = dataclasses.replace(
            scene, seeds=f"plane:1,0.6,1:8,0,0:0,0,8:{args.grid},{args.grid}")
    everything = [*ATTRIBUTES, "T", "p"]
    rows = {"cold": [], "style-only": [], "all on": []}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        timed(scene, work, "warmup", extra_attributes=everything)  # JIT, context, shaders
        for r in range(args.repeat):
            rows["cold"].append(timed(scene, work, f"cold{r}"))
            # same cache as the cold run just made; only the styles differ
            hit = run_scene(restyled(scene), out_dir=work / f"cold{r}",
                            cache_dir=work / f"cold{r}" / "cache", report=None)
            assert [s.action for s in hit.snapshots] == ["hit"], "style-only run did not hit"
            stages = {}
            for k, v in hit.snapshots[0].seconds.items():
                k = "render" if k.startswith("render ") else k
                stages[k] = stages.get(k, 0.0) + v
            rows["style-only"].append((hit.seconds, stages, hit))
            rows["all on"].append(timed(scene, work, f"all{r}", extra_attributes=everything))
    res0 = rows["cold"][0][2].snapshots[0]
    print(f"heated-room scene: {res0.n_lines} lines, {res0.n_points} vertices, 2 views "
          f"1600x900; load average {os.getloadavg()[0]:.2f} (2 cores shared; noisy)")
    print(f"{'case':12s} {'wall s':>8s} {'x cold':>7s}  stages (median s)")
    cold = statistics.median(r[0] for r in rows["cold"])
    for name, runs in rows.items():
        wall = statistics.median(r[0] for r in runs)
        keys = list(runs[0][1])
        split = ", ".join(f"{k} {statistics.median(r[1].get(k, 0.0) for r in runs):.3f}"
                          for k in keys)
        print(f"{name:12s} {wall:8.3f} {wall / cold:7.2f}  {split}")
    tr_cold = statistics.median(r[1]["trace"] for r in rows["cold"])
    tr_all = statistics.median(r[1]["trace"] for r in rows["all on"])
    print(f"trace stage alone: all attributes on / scene's (speed, T) = {tr_all / tr_cold:.2f}x")


if __name__ == "__main__":
    main()
