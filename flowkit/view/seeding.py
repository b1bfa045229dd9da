"""Live seeding: what the viewer needs to trace a rake's lines again, the field, the trace
options and backend (a scene's: ``open_scene``), and where "save seeds" writes the rake's spec.

``LiveSeeding.trace(rake)`` is ``flowkit.trace(field, rake.seeds(), options, backend=...)``
(then the scene's pruning, if it has one): the call a scene makes with that seed spec, the
kernel warm after the first one.  ``save(rake)`` writes the spec, one line, atomically.

``LiveRake`` is the rake as the window edits it: the handle a left drag moves, and when the
lines are traced again.  When the rake has changed, the next frame traces its seeds again
(while dragging too, as long as re-trace and redraw take at most ``LIVE_SECONDS``, the median
of the last ``LIVE_FRAMES``; else on release).  Nothing is traced while the rake stays put.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..integrate.options import TraceOptions
from ..integrate.seeds import parse_rake_spec
from ..integrate.trace import trace
from ..io.atomic import atomic_path
from ..lines import Lines
from ..render.camera import Camera
from .rake import Rake, decimals_for, drag_point, handle_at, project

SEEDS_SUFFIX = ".seeds"  # not .txt/.csv: --seeds reads those as files of points
LIVE_SECONDS = 0.1  # re-trace while dragging the rake while re-trace + redraw take <= this
LIVE_FRAMES = 5  # ... as the median of the last this many


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


class LiveRake:
    """The rake of ``seeding`` as the window edits it (None: no live seeding, no rake): the
    rake, the one the lines shown were traced from, the handle being dragged, the timings."""

    def __init__(self, seeding: LiveSeeding | None):
        self.seeding = seeding
        self.rake: Rake | None = None if seeding is None else seeding.rake
        self.traced = self.rake
        self.handle: str | None = None
        self.reseed_time = self.trace_time = 0.0  # s: last re-trace + redraw, its trace
        self._reseed_times: list[float] = []  # the last LIVE_FRAMES re-trace + redraw times
        self.retraces = 0

    def handle_at(self, setup, size, x: float, y: float) -> str | None:
        """The handle at scene pixel (x, y) (within ``rake.GRAB_PX``) of the camera's
        ``setup`` on a scene of ``size``, or None."""
        return None if self.rake is None else handle_at(self.rake, setup, size, x, y)

    def handle_xy(self, setup, size, name: str) -> tuple[float, float]:
        """Scene pixel (x, y) of handle ``name``."""
        x, y = project(setup, size, self.rake.handles()[name])[0][0]
        return float(x), float(y)

    def dragged(self, setup, dx: float, dy: float) -> Rake:
        """The rake with the grabbed handle moved with the mouse (pixels, y down), parallel to
        the screen, inside the field's box."""
        to = drag_point(setup, self.rake.handles()[self.handle], dx, dy)
        return self.rake.moved(self.handle, to, self.seeding.bounds, self.seeding.decimals)

    def due(self) -> bool:
        """Whether the rake changed since its lines were traced and is to be traced now (while
        dragging, only when the last re-traces kept up)."""
        if self.seeding is None or self.rake == self.traced:
            return False
        return self.handle is None or self.live_time() <= LIVE_SECONDS

    def trace(self, show: Callable[[Lines], None]) -> Lines:
        """Trace the rake's seeds (``LiveSeeding.trace``: the scene's call and options) and
        ``show`` the lines."""
        t0 = time.perf_counter()
        lines = self.seeding.trace(self.rake)
        self.trace_time = time.perf_counter() - t0
        self.traced = self.rake
        self.seeding.source = None
        show(lines)
        self.retraces += 1
        return lines

    def timed(self, seconds: float) -> None:
        """A re-trace and its redraw took ``seconds``."""
        self.reseed_time = seconds
        self._reseed_times = [*self._reseed_times[1 - LIVE_FRAMES:], seconds]

    def live_time(self) -> float:
        """The median of the last ``LIVE_FRAMES`` re-trace + redraw times (s; 0 before the
        first): a drag traces at every frame while it is at most ``LIVE_SECONDS``, so that one
        slow frame (another process on the cores) does not stop the lines following."""
        t = sorted(self._reseed_times)
        return 0.0 if not t else t[len(t) // 2]

    def save(self, path=None) -> Path:
        """Write the rake's seed spec (what ``flowkit trace --seeds`` and a scene's ``[seeds]
        spec`` take) atomically to ``path`` (default ``seeding.save_to``, beside the scene),
        and print where."""
        path = self.seeding.save(self.rake, path)
        print(f"flowkit view: saved seeds to {path}: {self.rake.spec()}", flush=True)
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
    field = snap.load(scene.field.vector, **scene.field.load_options)
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
