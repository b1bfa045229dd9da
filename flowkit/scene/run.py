"""Run a scene: for every snapshot, lines (from the cache, or traced), the lines file, one
image per view, then (with ``[outputs] animation``) one animation per view; each stage reports its
progress and time.

With ``workers`` > 1 and several snapshots to trace (or one, with ``[trace] distribute =
"blocks"``), the traces run on a Dask LocalCluster (``flowkit.distributed.trace_distributed``
with the scene's ``distribute``, one file per snapshot, float64 positions so the cache holds
exactly what a local trace gives); loading cached lines and rendering stay in this process (one
OpenGL context).  Without flowkit.distributed the snapshots run one after the other, and the run
says so.
"""

from __future__ import annotations

import importlib.util
import itertools
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..integrate import trace as tracing
from ..integrate.sample import sample
from ..lines import Lines
from ..seeding import needs_field, trace_spec
from ..seeding.prune import prune
from .cache import LinesCache
from .model import Scene, SceneError, load_scene, placeholders
from .plan import Plan, Snapshot, make_plan, still_views


@dataclass
class SnapshotResult:
    index: int
    time: float
    action: str                       # hit | extend | trace | retrace | trace (no cache)
    n_lines: int = 0
    n_points: int = 0
    lines_path: Path | None = None
    images: dict[str, Path] = field(default_factory=dict)
    animations: dict[str, list[Path]] = field(default_factory=dict)  # view -> files written
    uploaded: tuple[str, ...] = ()    # attributes the renderer put on the GPU
    seconds: dict[str, float] = field(default_factory=dict)


@dataclass
class RunResult:
    plan: Plan
    snapshots: list[SnapshotResult]
    notes: list[str]
    seconds: float = 0.0


def stderr_report(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def run_scene(scene: Scene | str | Path, *, snapshot=None, out_dir=None, cache_dir=None,
              use_cache: bool | None = None, workers: int | None = None, extra_attributes=(),
              report=stderr_report, ctx=None) -> RunResult:
    """Run ``scene`` (a Scene or a scene file path).

    snapshot          overrides the scene's selection: "all", a position, or a list
    out_dir           where relative output paths go (default: the scene file's directory)
    cache_dir         overrides the scene's [cache] dir; use_cache overrides [cache] enabled
    extra_attributes  traced besides those the styles read (benchmarks: "everything on")
    report            callable taking one progress line (None: silent)
    ctx               moderngl context (default: the process's headless EGL context)
    """
    t0 = time.perf_counter()
    scene = scene if isinstance(scene, Scene) else load_scene(scene)
    report = report or (lambda msg: None)
    plan = make_plan(scene, snapshot, extra_attributes)
    out = Path(out_dir) if out_dir is not None else scene.base
    try:  # before any work: an output directory that cannot be made fails now, not after tracing
        out.mkdir(parents=True, exist_ok=True)
        if not os.access(out, os.W_OK):
            raise PermissionError(f"{out} is not writable")
    except OSError as e:
        raise SceneError(f"output directory {out}: {e.strerror or e}") from None
    enabled = scene.cache_enabled if use_cache is None else use_cache
    cache = LinesCache(cache_dir or scene.cache_dir) if enabled else None
    notes = []
    _check_patterns(scene, plan)
    traced = {}
    if workers is not None and workers > 1:
        traced = _trace_on_cluster(plan, cache, workers, notes, report)
    elif scene.distribute != "auto":
        notes.append(f"[trace] distribute = {scene.distribute!r} splits a trace across Dask "
                     "workers (--workers N, N > 1); traced in this process")
    for n in notes:
        report(f"note: {n}")
    for v, why in still_views(scene).items():  # say so rather than write a still loop
        notes.append(f"no animation for view '{v}': {why}")
        report(f"warning: {notes[-1]}")
    results = []
    for k, snap in enumerate(plan.snapshots):
        tag = f"[{k + 1}/{len(plan.snapshots)} snapshot {snap.index} t={snap.time:.10g}]"
        results.append(_run_snapshot(plan, snap, cache, out, ctx, lambda m, t=tag: report(
            f"{t} {m}"), traced.get(snap.index)))
    total = time.perf_counter() - t0
    n_anim = sum(len(r.animations) for r in results)
    report(f"scene done: {len(results)} snapshot(s), "
           f"{sum(len(r.images) for r in results)} image(s)"
           + (f", {n_anim} animation(s)" if n_anim else "") + f" in {total:.2f} s")
    return RunResult(plan, results, notes, total)


def _trace_on_cluster(plan: Plan, cache, workers: int, notes: list, report) -> dict:
    """Trace every snapshot that needs a trace on ``workers`` Dask processes; {index: Lines}."""
    todo = [s for s in plan.snapshots if cache is None or cache.decide(
        cache.get(cache.key(cache.inputs(plan, s))), plan.attributes)[0] in ("trace", "retrace")]
    distribute = plan.scene.distribute
    if len(todo) < (1 if distribute == "blocks" else 2):  # (blocks: a field no process holds)
        return {}
    try:
        from ..distributed import trace_distributed
    except ImportError:
        notes.append(f"--workers {workers}: the Dask scale-out (flowkit.distributed) is not "
                     "available; snapshots run one after the other")
        return {}
    if needs_field(plan.scene.seeds) or plan.scene.prune:
        notes.append(f"--workers {workers}: {plan.scene.seeds.split(':')[0]} seeds are placed in "
                     "each snapshot's field (and pruning compares lines with each other); "
                     "snapshots run one after the other"
                     + (" in this process, not in blocks" if distribute == "blocks" else ""))
        return {}
    import tempfile

    from ..integrate.seeds import parse_seed_spec
    from ..io.lines_h5 import read_lines

    src = plan.scene.field
    if src.kind == "dataset":
        from ..datasets import hotroom_path

        source = hotroom_path()
    else:
        source = src.location
    t0 = time.perf_counter()
    tim: dict = {}
    with tempfile.TemporaryDirectory(prefix="flowkit-scene-") as tmp:
        paths = trace_distributed(source, parse_seed_spec(plan.scene.seeds),
                                  Path(tmp) / "lines.h5", plan.options, workers=workers,
                                  snapshots=[s.index for s in todo], per_snapshot=True,
                                  vector=src.vector, load=src.load_options,
                                  position_dtype="float64", progress=False,
                                  distribute=distribute, timings=tim)
        traced = {s.index: read_lines(p) for s, p in zip(todo, paths)}
    n = len(todo)
    report(f"trace: {n} snapshot{'s' if n > 1 else ''} on {workers} Dask workers, distribute "
           f"{tim['distribute']}: {tim['distribute_why']} ({time.perf_counter() - t0:.2f} s)")
    return traced


def _check_patterns(scene: Scene, plan: Plan) -> None:
    anim = scene.outputs.animation
    if anim is not None and anim.lower().endswith(".mp4") and not importlib.util.find_spec(
            "imageio"):  # refuse before tracing, not after
        raise ValueError(f"{scene.path} [outputs]: animation = {anim!r}: MP4 needs the optional "
                         "imageio and imageio-ffmpeg (pip install 'flowkit[video]'); or write "
                         ".gif / .png")
    if len(plan.snapshots) < 2:
        return
    for key in ("lines", "images", "animation"):
        pat = getattr(scene.outputs, key)
        if pat is not None and not placeholders(pat) & {"snapshot", "time"}:
            raise ValueError(f"{scene.path} [outputs]: {key} = {pat!r} would be overwritten by "
                             f"each of the {len(plan.snapshots)} snapshots; put {{snapshot}} or "
                             f"{{time}} in it")


class _Stage:
    """Times one stage and reports it when done."""

    def __init__(self, res: SnapshotResult, name: str, report):
        self.res, self.name, self.report = res, name, report

    def __enter__(self):
        self.t = time.perf_counter()
        return self

    def __exit__(self, exc_type, *exc):
        dt = time.perf_counter() - self.t
        self.res.seconds[self.name] = self.res.seconds.get(self.name, 0.0) + dt
        if exc_type is None:
            self.report(f"{self.name}: {getattr(self, 'msg', 'done')} ({dt:.2f} s)")


def _run_snapshot(plan: Plan, snap: Snapshot, cache: LinesCache | None, out: Path, ctx,
                  report, traced: Lines | None = None) -> SnapshotResult:
    scene = plan.scene
    res = SnapshotResult(snap.index, snap.time, "trace")
    entry = key = None
    if cache is not None:
        with _Stage(res, "cache", report) as st:
            inputs = cache.inputs(plan, snap)
            key = cache.key(inputs)
            entry = cache.get(key)
            res.action, missing = cache.decide(entry, plan.attributes)
            st.msg = {"hit": "hit, no tracing",
                      "extend": f"lines cached; {', '.join(missing)} to add on their vertices",
                      "retrace": f"lines cached without {', '.join(missing)}, which only the "
                                 "integrator gives: tracing again",
                      "trace": "miss"}[res.action]
    if traced is not None:  # traced on the cluster
        lines = traced
        if cache is not None:
            with _Stage(res, "cache", report) as st:
                cache.store(key, lines, inputs)
                st.msg = f"stored {key[:12]}"
    elif res.action == "hit":
        with _Stage(res, "read cache", report):
            lines = cache.read(entry, plan.attributes)
    else:
        with _Stage(res, "load field", report) as st:
            fld = snap.load(scene.field.vector, **scene.field.load_options)
            seeds = plan.seed_points(fld)
            st.msg = f"{fld.grid.shape} nodes, " + (
                f"{len(seeds)} seeds" if seeds is not None else "evenly spaced seeding")
        if res.action == "extend":
            with _Stage(res, "attributes", report) as st:
                # the attributes a trace would compute, on the very vertices it produced
                lines = sample(cache.read(entry), fld, missing,
                               seeds=seeds if "distance_to_seed" in missing else None)
                entry = cache.store(key, lines, inputs)
                st.msg = f"{', '.join(missing)} computed on {lines.n_points} cached vertices"
        else:
            with _Stage(res, "trace", report) as st:
                if seeds is not None:
                    lines = tracing.trace(fld, seeds, plan.options)
                else:
                    lines = trace_spec(fld, scene.seeds, plan.options)
                pruned = ""
                if scene.prune is not None:
                    n = len(lines)
                    lines = prune(lines, *scene.prune, period=fld.grid.period)
                    pruned = f" ({n - len(lines)} pruned)"
                st.msg = (f"{len(lines)} lines{pruned}, {lines.n_points} vertices, attributes "
                          f"{', '.join(plan.attributes) or 'none'}")
            if cache is not None:
                with _Stage(res, "cache", report) as st:
                    cache.store(key, lines, inputs)
                    st.msg = f"stored {key[:12]}"
    lines = _only(lines, plan.attributes)
    res.n_lines, res.n_points = len(lines), lines.n_points
    fmt = {"snapshot": snap.index, "time": snap.time}
    if scene.outputs.lines:
        from ..io.lines_h5 import write_lines

        with _Stage(res, "write lines", report) as st:
            path = _out(out, scene.outputs.lines.format(**fmt))
            stamp = {"scene_lines_key": f"{key}:{','.join(plan.attributes)}"} if key else {}
            if stamp and _stamp(path) == stamp["scene_lines_key"]:
                st.msg = f"{path} unchanged (same lines and attributes)"
            else:
                write_lines(lines, path, attrs=stamp)
                st.msg = str(path)
            res.lines_path = path
    if scene.outputs.images:
        _render(plan, lines, res, out, fmt, ctx, report)
    return res


def _stamp(path: Path) -> str | None:
    """The cache key and attribute set a lines output was written from (None: unknown)."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            v = f.attrs.get("scene_lines_key")
    except OSError:
        return None
    return v.decode() if isinstance(v, bytes) else v


def _only(lines: Lines, names) -> Lines:
    """The lines with exactly the point attributes ``names`` (all per-line data kept)."""
    pd = {a: lines.point_data[a] for a in names}
    return Lines(lines.points, lines.offsets, pd, lines.line_data, lines.attrs)


def _out(out: Path, rel: str) -> Path:
    p = Path(rel).expanduser()
    p = p if p.is_absolute() else out / p
    p.parent.mkdir(parents=True, exist_ok=True)
    return p


def _render(plan: Plan, lines: Lines, res: SnapshotResult, out: Path, fmt: dict, ctx, report):
    from ..render import LineRenderer, save_png
    from ..render.renderer import check_picture

    scene = plan.scene
    with LineRenderer(lines, ctx) as r:
        for v in scene.views.values():
            with _Stage(res, f"render {v.name}", report) as st:
                style = scene.styles[v.style]
                img = r.render(style, v.size, v.camera)
                try:
                    check_picture(img, r.resolve(style, v.camera, v.size),
                                  r.scene_scale(style, v.camera, v.size).per_pixel)
                except ValueError as e:
                    raise ValueError(f"view '{v.name}': {e}") from None
                img = r.overlay(img, style, v.camera)
                path = _out(out, scene.outputs.images.format(view=v.name, style=v.style, **fmt))
                res.images[v.name] = save_png(img, path)
                cam = r.camera_report(style, v.camera, v.size)
                st.msg = f"{path} ({v.size[0]}x{v.size[1]}, {cam})"
        if scene.outputs.animation is not None:
            _animate(scene, r, res, out, fmt, report)
        res.uploaded = tuple(r.uploaded_attributes())


def _animate(scene: Scene, r, res: SnapshotResult, out: Path, fmt: dict, report):
    """One animation per view whose style moves (the others were noted when the run began)."""
    from ..render.animate import render_frames, write_animation

    o = scene.outputs
    still = still_views(scene)
    for v in scene.views.values():
        if v.name in still:
            continue
        name = f"animate {v.name}"
        with _Stage(res, name, report) as st:
            path = _out(out, o.animation.format(view=v.name, style=v.style, **fmt))
            frames = render_frames(r, scene.styles[v.style], o.frames, v.size, v.camera, True)
            res.animations[v.name] = write_animation(frames, path, o.frames, o.fps,
                                                     progress=_ticker(name, o.frames, report))
            shown = path if len(res.animations[v.name]) == 1 else (
                f"{res.animations[v.name][0]} .. {res.animations[v.name][-1].name}")
            st.msg = f"{shown} ({o.frames} frames at {o.fps:g} fps, {v.size[0]}x{v.size[1]})"


def _ticker(name: str, n: int, report):
    """A progress callable for ``n`` frames: a few lines (every quarter), not one per frame."""
    step, done = max(1, n // 4), itertools.count(1)

    def tick():
        k = next(done)
        if k % step == 0 and k < n:
            report(f"{name}: frame {k}/{n}")
    return tick
