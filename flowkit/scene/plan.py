"""What a scene computes, and why: the snapshots, the attribute set its styles read, and the text
of ``flowkit scene --explain``.

The attribute set comes from the renderer's own answer, ``Style.attributes()``, for every style a
view draws (a style no view draws costs nothing; neither does a line style its transfer function
never picks).  The style model is walked only to say *which* part reads an attribute; a name
``attributes()`` reports that the walk does not find is still traced, "read by the style".
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..fields.readers import SnapshotRef, load_field, load_series
from ..integrate.attributes import ATTRIBUTES
from ..integrate.options import TraceOptions
from ..integrate.seeds import parse_even_spec, parse_seed_spec
from ..render.style.model import ColorMap
from .model import Scene, SceneError, snapshot_selection

# per-line data every traced line carries anyway: a style may read it at no tracing cost
LINE_ATTRIBUTES = ("seed_id", "reason", "n_accepted", "n_rejected", "reason_backward")
VECTOR_ATTRIBUTES = ("velocity", "vorticity")
COST = {
    "params": "from the integrator (no extra work)",
    "velocity": "field sampled at every vertex (trilinear)",
    "curl": "node curl (second-order differences) at the corners of the vertices' cells, "
            "sampled at every vertex",
    "seed": "seed position per vertex (no sampling)",
}


@dataclass(frozen=True)
class Snapshot:
    """One snapshot of the scene's field: ``index`` is its position in the series."""

    index: int
    time: float
    ref: Path | SnapshotRef

    def load(self, vector: str, **opts):
        """The snapshot's field; ``opts``: load_field's keywords (FieldSource.load_options)."""
        return load_field(self.ref, vector=vector, **opts)


@dataclass(frozen=True)
class Plan:
    scene: Scene
    snapshots: tuple[Snapshot, ...]
    attributes: tuple[str, ...]           # point attributes traced, in first-use order
    line_attributes: tuple[str, ...]      # per-line data styles read (always stored)
    uses: dict[str, tuple[str, ...]]      # attribute -> who reads it
    options: TraceOptions                 # the scene's options with attributes = the set

    def seed_points(self, field) -> np.ndarray | None:
        """The seed points, or None for evenly spaced lines (they place their own seeds)."""
        if parse_even_spec(self.scene.seeds) is not None:
            return None
        return parse_seed_spec(self.scene.seeds, field)

    def explain(self, cache=None) -> str:
        return explain(self, cache)


def make_plan(scene: Scene, snapshot=None, extra_attributes=()) -> Plan:
    """The plan of ``scene``; ``snapshot`` overrides the scene's selection ("all", int, list);
    ``extra_attributes`` are traced too (e.g. to measure what leaving attributes out saves)."""
    uses: dict[str, list[str]] = {}
    for vname, view in scene.views.items():
        sname = view.style
        for attr, role in style_reads(scene.styles[sname]):
            uses.setdefault(attr, []).append(f"view '{vname}': style '{sname}' {role}")
    for a in scene.extra_attributes:
        uses.setdefault(a, []).append("[trace] attributes (stored in the lines file)")
    for a in extra_attributes:
        uses.setdefault(a, []).append("asked for by the caller")
    for a, who in uses.items():
        if a in VECTOR_ATTRIBUTES and not all(w.startswith(("[trace]", "asked")) for w in who):
            raise SceneError(f"{_where(scene)}: {who[0]} reads '{a}', a 3-component attribute; a "
                             f"style maps one value per vertex (use "
                             f"{'speed' if a == 'velocity' else 'vorticity_magnitude'})")
    point = tuple(a for a in uses if a not in LINE_ATTRIBUTES)
    line = tuple(a for a in uses if a in LINE_ATTRIBUTES)
    sel = scene.field.snapshot if snapshot is None else snapshot_selection(
        "option", "--snapshot", snapshot)
    return Plan(scene, _snapshots(scene, sel), point, line,
                {a: tuple(w) for a, w in uses.items()},
                dataclasses.replace(scene.trace, attributes=point))


def style_reads(style) -> list[tuple[str, str]]:
    """(attribute, which part of the style reads it) for every attribute ``style`` reads: its
    transfer function, and the bands (colour, width, shape, pattern) of the line styles drawn."""
    out = []
    if style.transfer is not None:
        out.append((style.transfer.attribute, "transfer function"))
    for lname in style.used_styles():
        prefix = f"line style '{lname}' " if len(style.styles) > 1 else ""
        for i, b in enumerate(style.styles[lname].bands):
            parts = [("colour", b.color), ("width", b.width), ("shape", b.shape),
                     ("pattern", b.pattern)]
            if b.pattern is not None:
                parts.append(("pattern colour", b.pattern.color))
            for role, spec in parts:
                a = getattr(spec, "attribute", None)
                if a is not None:
                    cm = f" ({spec.cmap})" if isinstance(spec, ColorMap) else ""
                    out.append((a, f"{prefix}band {i + 1} {role}{cm}"))
    named = {a for a, _ in out}
    out += [(a, "(read by the style)") for a in style.attributes() if a not in named]
    return out


def still_views(scene: Scene) -> dict[str, str]:
    """Views an ``[outputs] animation`` cannot move -> why: their style has no shape or colour
    pattern, so every frame would be the same picture.  Empty without an animation output."""
    if scene.outputs.animation is None:
        return {}
    return {v.name: f"style '{v.style}' has no band 'shape' or 'pattern' to move, so every frame "
                    "would be the same picture (stills only)"
            for v in scene.views.values() if not scene.styles[v.style].animated}


def _where(scene: Scene) -> str:
    return str(scene.path) if scene.path is not None else "scene"


def _snapshots(scene: Scene, sel) -> tuple[Snapshot, ...]:
    src = scene.field
    if src.kind == "dataset":
        from ..datasets import hotroom_path

        entries = load_series(hotroom_path())
    else:
        entries = load_series(src.location)
    n = len(entries)
    picks = range(n) if sel == "all" else ([sel] if isinstance(sel, int) else list(sel))
    out = []
    for i in picks:
        if not -n <= i < n:
            raise SceneError(f"{_where(scene)} [field]: snapshot = {i!r} is not allowed; expected "
                             f"a position in 0..{n - 1} (or -{n}..-1): {src.location} has {n} "
                             f"snapshot{'s' * (n != 1)}")
        j = i % n
        out.append(Snapshot(j, float(entries[j][0]), entries[j][1]))
    return tuple(out)


def explain(plan: Plan, cache=None) -> str:
    """What will be computed and why; with ``cache`` (a LinesCache), what the cache holds."""
    sc = plan.scene
    src = sc.field
    lines = [f"scene: {_where(sc)}",
             f"field: {src.kind} {src.location} (vector {src.vector})",
             f"snapshots: {len(plan.snapshots)} of the series: "
             + ", ".join(f"{s.index} (t = {s.time:.10g})" for s in plan.snapshots),
             f"seeds: {sc.seeds}" + (f", pruned at distance {sc.prune[0]:g} over "
                                      f"{sc.prune[1]:.0%} of a line" if sc.prune else "")]
    o = plan.options
    lines.append(f"trace: {o.method_name}, rtol {o.rtol}, direction {o.direction}, parameter "
                 f"{o.parameter}, max_length {o.max_length:g}, max_time {o.max_time:g}"
                 + (f", spacing {o.spacing:g}" if o.spacing else "")
                 + (f", count {o.count}" if o.count else ""))
    lines.append("attributes traced: " + (", ".join(plan.attributes) or "none (geometry only)"))
    for a in plan.attributes:
        needs = ATTRIBUTES.get(a)
        cost = "; ".join(COST[n] for n in needs) if needs else (
            f"scalar field '{a}' sampled at every vertex (trilinear)")
        lines.append(f"  {a}: {cost}")
        lines += [f"    read by {w}" for w in plan.uses[a]]
    for a in plan.line_attributes:
        lines.append(f"  {a}: per-line data, stored with every line (no extra work)")
        lines += [f"    read by {w}" for w in plan.uses[a]]
    needed = {n for a in plan.attributes for n in ATTRIBUTES.get(a, ("scalar",))}
    skipped = []
    if "velocity" not in needed:
        skipped.append("velocity sampling (speed, velocity)")
    if "curl" not in needed:
        skipped.append("vorticity curl (vorticity, vorticity_magnitude)")
    if "scalar" not in needed:
        skipped.append("scalar field sampling (e.g. T)")
    if skipped:
        lines.append("not computed (no style reads it): " + "; ".join(skipped))
    drawn = {v.style for v in sc.views.values()}
    for sname, where in sc.style_sources.items():
        note = "" if sname in drawn else "  -- drawn by no view: nothing traced for it"
        lines.append(f"style '{sname}': {where}{note}")
    bounds = None
    for v in sc.views.values():
        cam = v.camera.describe()
        if v.camera.automatic and plan.snapshots:
            if bounds is None:  # the grid only: arrays are read when used
                bounds = plan.snapshots[0].load(src.vector, **src.load_options).grid.bounds
            chosen = v.camera.resolve(bounds, *v.size).describe()
            cam += f" ({chosen} on the field's bounds; chosen on the lines' bounds when drawn)"
        lines.append(f"view '{v.name}': style '{v.style}', {v.size[0]}x{v.size[1]}, camera "
                     f"{cam}, {v.camera.projection}")
    outs = sc.outputs
    lines.append(f"outputs: lines {outs.lines or '(not written)'}; images {outs.images}")
    if outs.animation is not None:
        still = still_views(sc)
        moving = [v for v in sc.views if v not in still]
        lines.append(f"animation: {outs.animation}, {outs.frames} frames at {outs.fps:g} fps "
                     f"(the shapes and patterns move one period), rendered after the stills for "
                     f"view{'s' * (len(moving) != 1)} {', '.join(map(repr, moving)) or 'none'}")
        lines += [f"  warning: no animation for view '{v}': {why}" for v, why in still.items()]
    if cache is not None:
        lines.append(f"cache: {cache.dir}")
        for s in plan.snapshots:
            lines.append(f"  snapshot {s.index}: {cache.status(plan, s)}")
    else:
        lines.append("cache: off")
    return "\n".join(lines)
