"""Compile flowkit's kernels ahead of use, so that an image or a cluster is warmed once.

A kernel's machine code depends on the types of its arguments, never on the data: a Field
holds C-contiguous float64 or float32 arrays (as its file stores them), so a short trace on a
small stand-in field of the same type compiles the very specializations that the same options
compile on a user's data, and numba's disk cache keeps
them for every later process (where that cache lives: docs/integrator.md, "Where the compiled
code lives").  The stand-in grid is uniform, so options that run the lock-step on a uniform grid
compile it too.

``WHAT`` names: a set of options from ``OPTION_SETS`` ("default" is what ``flowkit trace`` and
``flowkit.trace`` run with no option named; "all" is every set), compiled for float64 and
float32 fields (``TYPES``; a kernel compiles once per type it reads), or a scene file, whose trace
options (with the attributes its styles read) are compiled, and its views rendered small, for
the renderer's level-of-detail kernels.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba.core import event

LOG = logging.getLogger("flowkit.compile")

# name -> (what it is, TraceOptions fields; "pathlines" runs the pathline integrator)
OPTION_SETS = {
    "default": ("the default trace", {}),
    "attributes": ("attributes speed, T, vorticity", {"attributes": ("speed", "T", "vorticity")}),
    "rk4": ("rk4", {"method": "rk4"}),
    "dop853": ("dop853", {"method": "dop853"}),
    "no-cell-aware": ("--no-cell-aware", {"cell_aware": False}),
    "lockstep": ("fixed-step plain rk4 (the lock-step)",
                 {"method": "rk4", "step": 0.05, "cell_aware": False}),
    "rosenbrock": ("the Rosenbrock method", {"method": "ros34pw2"}),
    "pathlines": ("pathlines", {}),
    "even": ("evenly spaced seeding (seeds even:...)", {"direction": "both"}),
    "meshes": ("unstructured meshes read (.vtu, .vtm: cell location)", {}),
}
EVEN_SPEC = "even:0.25d"  # on the stand-in: a handful of lines, some cut (the walk's two queries)


@dataclass
class Compiled:
    what: str             # the option set or scene
    seconds: float        # wall time of the warm-up trace, compilation included
    compiled: int         # functions numba compiled (0: everything came from the cache)
    compile_seconds: float


def stand_in(scalars=("T",), t: float = 0.0, dtype=np.float64):
    """A small uniform field (9 x 7 x 9 nodes, a swirl with a drift) with the scalar fields
    ``scalars`` (each the x coordinate), at time ``t``, its arrays of type ``dtype``."""
    from .fields import Field, Grid

    g = Grid.regular((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (9, 7, 9))
    x, y, z = np.meshgrid(g.x, g.y, g.z, indexing="ij")
    vec = np.stack([-(z - 4.0), 0.1 + 0.0 * y + 0.01 * t, x - 4.0], axis=-1).astype(dtype)
    return Field(g, vec, {s: x.astype(dtype) for s in scalars}, source="<stand-in>", time=t)


SEEDS = np.array([[3.0, 1.0, 4.0], [5.0, 2.0, 4.0], [4.0, 3.0, 2.5], [2.0, 1.5, 5.5]])


# the types a Field holds (fields/stored.py): option sets compile for each, scenes for their own
TYPES = ("float64", "float32")


def jobs(what, types=TYPES) -> list[tuple[str, callable]]:
    """(label, run) for each name or scene file in ``what``, an option set once per field type
    in ``types``; errors name the unknown one."""
    out = []
    for t in types:
        if t not in TYPES:
            raise ValueError(f"flowkit compile: field type '{t}' is not one of {', '.join(TYPES)}")
    for w in what:
        if w == "all":
            out += jobs(list(OPTION_SETS), types)
        elif w in OPTION_SETS:
            out += [(w if t == TYPES[0] else f"{w} ({t})", _option_set(w, np.dtype(t)))
                    for t in types]
        elif str(w).endswith(".toml") or Path(w).is_file():
            out.append((str(w), _scene(w)))
        else:
            have = ", ".join(list(OPTION_SETS) + ["all"])
            raise ValueError(f"flowkit compile: '{w}' is neither an option set ({have}) nor a "
                             f"scene file")
    return out


def _option_set(name: str, dtype):
    from .integrate.options import TraceOptions

    opts = TraceOptions(max_length=4.0, **OPTION_SETS[name][1])
    if name == "meshes":
        return _meshes
    if name == "pathlines":
        return lambda: _pathlines(opts, dtype)
    return lambda: _trace(opts, EVEN_SPEC if name == "even" else None, dtype)


def _scene(path):
    from .integrate.seeds import parse_even_spec
    from .scene.model import load_scene
    from .scene.plan import make_plan

    plan = make_plan(load_scene(path))  # validates the file now, before anything compiles
    even = parse_even_spec(plan.scene.seeds) is not None  # the seeder's kernels too
    dtype = _scene_dtype(plan)
    return lambda: _render(plan, _trace(plan.options, EVEN_SPEC if even else None, dtype))


def _scene_dtype(plan):
    """The type the scene's field is stored in (its metadata only), float64 where it cannot
    be opened now (a scene may name a file that is written later)."""
    try:
        return plan.snapshots[0].load(plan.scene.field.vector).dtype
    except Exception:  # noqa: BLE001 (warming is best effort; the scene run says what is wrong)
        return np.float64


def _trace(opts, even=None, dtype=np.float64):
    """A short trace on the stand-in (of type ``dtype``) from SEEDS, or evenly spaced lines by
    the spec ``even``."""
    from .integrate.attributes import ATTRIBUTES
    from .integrate.trace import trace
    from .seeding import trace_spec

    scalars = [a for a in opts.attributes if a not in ATTRIBUTES]
    field = stand_in(scalars or ("T",), dtype=dtype)
    opts = opts.replace(max_length=min(opts.max_length, 4.0))
    return trace(field, SEEDS, opts) if even is None else trace_spec(field, even, opts)


def _meshes() -> None:
    """A hexahedron and a polyhedron beside it (the cube, its faces in VTK 9.4's layout too)
    resampled: the kernels of fields/mesh.py and fields/resample.py, whatever the mesh (they
    read int64 and float64 arrays only)."""
    from .fields.mesh import Mesh, cube_faces, legacy_faces
    from .fields.resample import Location, Resampled, auto_grid

    pts = np.array([[x, y, z] for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 1.0, 2.0)])
    hexa = [0, 1, 4, 3, 6, 7, 10, 9]
    cube = [1, 2, 5, 4, 7, 8, 11, 10]
    faces = cube_faces(cube)
    f_ends = np.cumsum([len(f) for f in faces])
    stream, starts = legacy_faces(np.concatenate(faces), f_ends, np.arange(6), np.array([0, 6]))
    mesh = Mesh(pts, np.array(hexa + cube), np.array([0, 8, 16]), np.array([12, 42]),
                stream, starts)
    grid, _ = auto_grid(mesh, np.array([[0.0, 2.0], [0.0, 1.0], [0.0, 1.0]]), ("shape", (5, 3, 3)))
    where = Location(mesh, grid, "", "point", "warm-up mesh")
    Resampled(where, pts[:, 0]).fill(np.empty(grid.shape), 0, grid.shape[0])


def _render(plan, lines) -> None:
    """Each of the scene's views, small: the renderer's level of detail (render/simplify.py)
    compiles here.  Without OpenGL only the tracing is warmed, and the log says so."""
    from .render import LineRenderer
    from .render.context import RenderContextError

    scene = plan.scene
    try:
        with LineRenderer(lines) as r:
            for v in scene.views.values():
                r.render(scene.styles[v.style], (64, 36), v.camera, overlays=True)
    except RenderContextError as e:
        LOG.warning("the renderer's kernels are not compiled (no OpenGL here): %s", e)


def _pathlines(opts, dtype=np.float64):
    from .integrate.pathlines import pathlines

    pathlines([(0.0, stand_in(t=0.0, dtype=dtype)), (1.0, stand_in(t=1.0, dtype=dtype))], SEEDS,
              opts.replace(max_time=1.0))


class _Timer(event.Listener):
    """Counts the outermost numba compilations and their seconds."""

    def __init__(self):
        self.depth = self.count = 0
        self.seconds = 0.0
        self.t0 = 0.0

    def on_start(self, ev):
        self.depth += 1
        if self.depth == 1:
            self.t0 = time.perf_counter()

    def on_end(self, ev):
        self.depth -= 1
        self.count += 1
        if self.depth == 0:
            self.seconds += time.perf_counter() - self.t0


def compile_one(label: str, run) -> Compiled:
    """Run one warm-up job, counting what numba compiled for it."""
    from .integrate import lanes

    timer = _Timer()
    t = time.perf_counter()
    was, lanes.WAIT = lanes.WAIT, True  # the lock-step compiled here, not in the background
    try:
        with event.install_listener("numba:compile", timer):
            run()
    finally:
        lanes.WAIT = was
    return Compiled(label, time.perf_counter() - t, timer.count, timer.seconds)


def warm(what=("default",)) -> list[Compiled]:
    """Compile what ``what`` needs (see ``jobs``) in this process; what each job compiled."""
    return [compile_one(label, run) for label, run in jobs(what)]


_recorder: _Timer | None = None


def record() -> None:
    """From now on, count what numba compiles in this process (idempotent); ``recorded``
    reads it.  On a cluster: ``client.run(record)`` before a job, ``client.run(recorded)``
    after it says what each worker compiled instead of loading from the cache."""
    global _recorder
    if _recorder is None:
        _recorder = _Timer()
        event.register("numba:compile", _recorder)


def recorded() -> tuple[int, float]:
    """(functions compiled, seconds) since ``record`` was first called."""
    return (_recorder.count, _recorder.seconds) if _recorder is not None else (0, 0.0)


def cache_location() -> str:
    """Where numba caches flowkit's kernels in this process (docs/integrator.md says why)."""
    from .integrate import kernel
    from .numba_private import cache_path

    return cache_path(kernel._advance_lines) or "(unknown)"
