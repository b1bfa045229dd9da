"""Live seeding: what the viewer needs to trace a rake's lines again, the field, the trace
options and backend (a scene's: ``open_scene``), and where "save seeds" writes the rake's spec.

``LiveSeeding.trace(rake)`` is ``flowkit.trace(field, rake.seeds(), options, backend=...)``
(then the scene's pruning, if it has one): the call a scene makes with that seed spec, the
kernel warm after the first one.  ``save(rake)`` writes the spec, one line, atomically.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..integrate.options import TraceOptions
from ..integrate.seeds import parse_rake_spec
from ..integrate.trace import trace
from ..io.atomic import atomic_path
from ..lines import Lines
from ..render.camera import Camera
from .rake import Rake, decimals_for

SEEDS_SUFFIX = ".seeds"  # not .txt/.csv: --seeds reads those as files of points


@dataclass
class LiveSeeding:
    field: object  # a gridded Field
    options: TraceOptions
    rake: Rake
    save_to: Path = Path("rake.seeds")  # "save seeds" writes the spec here
    backend: str = "numba"
    prune: tuple[float, float] | None = None  # (distance, fraction), as a scene's [seeds] prune
    source: str | None = None  # the seed spec of the lines shown at first, when not the rake's

    @property
    def bounds(self):
        """The field's box: handles stay inside it; the camera frames it."""
        return self.field.grid.bounds

    @property
    def decimals(self) -> int:
        return decimals_for(self.bounds)

    def trace(self, rake: Rake) -> Lines:
        lines = trace(self.field, rake.seeds(), self.options, backend=self.backend,
                      empty="ignore")  # a rake dragged outside: no lines, no error
        if self.prune is not None:
            from ..seeding.prune import prune

            lines = prune(lines, *self.prune, period=self.field.grid.period)
        return lines

    def save(self, rake: Rake, path=None) -> Path:
        """Write ``rake``'s seed spec (and a newline) to ``path`` (default ``save_to``),
        atomically."""
        path = Path(path) if path is not None else Path(self.save_to)
        with atomic_path(path) as tmp:
            Path(tmp).write_text(rake.spec() + "\n", encoding="utf-8")
        return path


@dataclass
class SceneSession:
    """What ``flowkit view --scene`` opens: the lines, the style file, the view's camera and
    the live seeding."""

    lines: Lines
    style_path: Path
    camera: Camera
    seeding: LiveSeeding
    title: str

    @property
    def units(self) -> dict[str, str]:
        """Units as ``io.lines_h5.read_units`` gives them from a file ("position": x, y, z)."""
        length = self.lines.attrs.get("length_units")
        return {**({"position": str(length)} if length else {}), **self.lines.units}


def open_scene(path, view: str | None = None, snapshot=None, rake: str | None = None,
               style=None) -> SceneSession:
    """Load scene ``path``'s field (``snapshot``: a position, default the first the scene
    selects) and trace its seeds with its options, for the window of ``view`` (default: the
    first).  The rake starts as the scene's seeds when they are a ``line:``/``plane:`` spec,
    else as ``rake`` ("line", "plane" or such a spec; default a line across the domain).
    ``style``: a style file to use instead of the view's (needed when the view's is inline)."""
    from ..scene import load_scene, make_plan
    from ..seeding import trace_spec
    from ..seeding.prune import prune

    scene = load_scene(path)
    name = view or next(iter(scene.views))
    if name not in scene.views:
        raise ValueError(f"{scene.path}: no view {name!r}; the scene's views: "
                         f"{', '.join(scene.views)}")
    v = scene.views[name]
    style_path = Path(style) if style is not None else None
    if style_path is None:
        source = scene.style_sources[v.style]
        if source == "inline":
            raise ValueError(f"{scene.path} [views.{name}]: its style '{v.style}' is inline; the "
                             "viewer edits and watches a style file: give --style FILE, or "
                             "name a style file in [styles]")
        style_path = Path(source)
    plan = make_plan(scene, snapshot)
    snap = plan.snapshots[0]
    field = snap.load(scene.field.vector, scene.field.resample)
    spec = scene.seeds
    if parse_rake_spec(spec) is not None and rake is None:
        start, source = Rake.from_spec(spec), None
    elif rake in (None, "line", "plane"):
        start, source = Rake.default(field.grid.bounds, rake or "line"), spec
    else:
        start, source = Rake.from_spec(rake), spec
    seeding = LiveSeeding(field, plan.options, start, scene.path.with_suffix(SEEDS_SUFFIX),
                          prune=scene.prune, source=source)
    if source is None:
        lines = seeding.trace(start)
    else:
        lines = trace_spec(field, spec, plan.options)
        if scene.prune is not None:
            lines = prune(lines, *scene.prune, period=field.grid.period)
    title = f"flowkit view - {scene.path.name} [{name}] snapshot {snap.index}"
    return SceneSession(lines, style_path, v.camera, seeding, title)
