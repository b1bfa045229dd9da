"""Seed points for tracing: every function returns a C-contiguous (n, 3) float64 array.

- ``points(values)``: explicit points ((n, 3) or one (3,) point).
- ``from_file(path)``: ``.npy`` (pickles refused) or ``.csv``/``.txt`` with 3 columns x, y, z
  (comma, semicolon or whitespace separated; an optional header line; ``#`` comments).
- ``line(p0, p1, n)``: a rake of n points from p0 to p1, both ends included.
- ``plane(origin, u, v, nu, nv)``: nu x nv lattice on the parallelogram origin + a u + b v,
  a, b in [0, 1]; point ``i + nu * j`` is origin + i/(nu-1) u + j/(nv-1) v.
- ``box(lo, hi, n, random=False, seed=0)``: lattice with n nodes per axis (int: n per axis, a
  flat axis lo == hi gets one; or (nx, ny, nz)), ends included, 'ij' order (z fastest, as
  ``Grid.node_points``); or, with ``random=True``, n (or nx*ny*nz) uniform random points drawn
  with ``numpy.random.default_rng(seed)``.
- ``random_in(domain, n, seed=0)``: n uniform random points in a Field's grid (points in NaN
  cells rejected and redrawn), a Grid, an analytic field (its ``default_bounds``) or (3, 2) bounds.
- ``parse_seed_spec(spec, field=None)``: the CLI's ``--seeds`` value, see ``SPEC_HELP``;
  ``density`` and ``where`` draw from the field's data (flowkit.seeding.data).
- ``line_spec``, ``plane_spec``, ``points_spec``: the spec strings of those forms (exact: they
  parse back to the same points), e.g. for a rake placed in the viewer; ``parse_rake_spec``
  the arguments of a ``line:`` or ``plane:`` spec (the viewer's rake starts from them).

``even:DSEP[:DTEST[:SEED]]`` grows evenly spaced lines rather than giving seed points: it is
parsed by ``parse_even_spec`` and traced by ``flowkit.seeding.trace_spec``.

Errors are ``SeedError`` (a ValueError) naming the file, line, spec or argument at fault.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..fields.bricks import read_whole
from ..fields.field import Field
from ..fields.grid import Grid
from ..fields.interp import INSIDE
from ..seeding.errors import SeedError

SPEC_HELP = (
    "a .npy/.csv/.txt file of x,y,z points; points:x,y,z[:x,y,z...]; "
    "line:x0,y0,z0:x1,y1,z1:n; plane:ox,oy,oz:ux,uy,uz:vx,vy,vz:nu,nv; "
    "box:x0,y0,z0:x1,y1,z1:n[:random[:seed]] (n or nx,ny,nz); random:n[:seed] (in the field); "
    "density:n:ATTRIBUTE[:seed] (probability proportional to speed, vorticity_magnitude, a "
    "scalar or grad(SCALAR)); where:EXPR:n[:seed] (uniform where EXPR holds, e.g. T>302 and "
    "speed<0.1); even:DSEP[:DTEST[:seed]] (evenly spaced lines; lengths in world units, or "
    "with a d suffix a fraction of the domain diagonal, e.g. 1/30d)"
)
FILE_TYPES = (".npy", ".csv", ".txt")


CHECK_ONLY = object()  # as parse_seed_spec's field: check the spec's own parts, make no seeds


def points(values, where: str = "seed points") -> np.ndarray:
    """Explicit points as (n, 3) float64; a single (3,) point gives (1, 3)."""
    try:
        p = np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise SeedError(f"{where}: not an array of numbers ({e})") from None
    if p.ndim == 1 and p.shape == (3,):
        p = p[None]
    if p.ndim != 2 or p.shape[1] != 3:
        raise SeedError(f"{where}: expected shape (n, 3) (x, y, z per row), got {p.shape}")
    bad = ~np.all(np.isfinite(p), axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise SeedError(f"{where}: point {i} is not finite: {p[i].tolist()} ({int(bad.sum())} such)")
    return np.ascontiguousarray(p)


def from_file(path) -> np.ndarray:
    """Points from ``.npy`` (float array (n, 3), never unpickled) or ``.csv``/``.txt``."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in FILE_TYPES:
        raise SeedError(f"{path}: unknown seed file type '{ext}'; use one of {', '.join(FILE_TYPES)}")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: seed file not found")
    if ext == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except ValueError as e:
            if "allow_pickle" in str(e):
                raise SeedError(f"{path}: holds pickled Python objects; refused (never unpickled)") from None
            raise SeedError(f"{path}: not a readable .npy array ({e})") from None
        except (OSError, EOFError) as e:
            raise SeedError(f"{path}: not a readable .npy array ({e})") from None
        if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
            raise SeedError(f"{path}: array of dtype {arr.dtype}, expected numbers")
        p = points(arr, where=str(path))
    else:
        p = _read_text(path)
    if p.shape[0] == 0:
        raise SeedError(f"{path}: holds no seed points")
    return p


def _read_text(path: Path) -> np.ndarray:
    rows = []
    first = True
    with open(path, encoding="utf-8", errors="replace") as fh:
        for lineno, text in enumerate(fh, 1):
            s = text.split("#", 1)[0].strip()
            if not s:
                continue
            parts = [x for x in re.split(r"[,;\s]+", s) if x]
            try:
                vals = [float(x) for x in parts]
            except ValueError:
                if first:  # a header line such as "x,y,z"
                    first = False
                    continue
                raise SeedError(f"{path} line {lineno}: not numbers: {s!r}") from None
            first = False
            if len(vals) != 3:
                raise SeedError(f"{path} line {lineno}: expected 3 columns (x, y, z), got {len(vals)}: {s!r}")
            if not all(np.isfinite(vals)):
                raise SeedError(f"{path} line {lineno}: non-finite coordinate: {s!r}")
            rows.append(vals)
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def _count(n, what: str) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise SeedError(f"{what} must be a positive integer, got {n!r}")
    return int(n)


def line(p0, p1, n: int) -> np.ndarray:
    """A rake: n points evenly spaced from p0 to p1, both included (n = 1 gives p0)."""
    a, b = points(p0, "line start")[0], points(p1, "line end")[0]
    return np.ascontiguousarray(np.linspace(a, b, _count(n, "line: n")))


def plane(origin, u, v, nu: int, nv: int) -> np.ndarray:
    """nu x nv lattice on the parallelogram spanned by edge vectors u and v from origin."""
    o, eu, ev = (points(x, f"plane {w}")[0] for x, w in ((origin, "origin"), (u, "u"), (v, "v")))
    nu, nv = _count(nu, "plane: nu"), _count(nv, "plane: nv")
    if not np.linalg.norm(np.cross(eu, ev)) > 1e-12 * np.linalg.norm(eu) * np.linalg.norm(ev):
        raise SeedError(f"plane: u {eu.tolist()} and v {ev.tolist()} must be nonzero and not parallel")
    a = np.linspace(0.0, 1.0, nu) if nu > 1 else np.zeros(1)
    b = np.linspace(0.0, 1.0, nv) if nv > 1 else np.zeros(1)
    pts = o + b[:, None, None] * ev + a[None, :, None] * eu
    return np.ascontiguousarray(pts.reshape(-1, 3))


def box(lo, hi, n, random: bool = False, seed: int = 0) -> np.ndarray:
    """Lattice (n per axis, or (nx, ny, nz); ends included) or n random points in [lo, hi]."""
    lo, hi = points(lo, "box lo")[0], points(hi, "box hi")[0]
    if np.any(hi < lo):
        raise SeedError(f"box: lo {lo.tolist()} must not exceed hi {hi.tolist()} on any axis")
    if np.ndim(n) == 0:
        n = _count(n, "box: n")
        counts = [1 if lo[a] == hi[a] else n for a in range(3)]
    else:
        if np.shape(n) != (3,):
            raise SeedError(f"box: n must be an integer or 3 integers (nx, ny, nz), got {n!r}")
        counts = [_count(c, f"box: n{'xyz'[a]}") for a, c in enumerate(n)]
    if random:
        total = counts[0] * counts[1] * counts[2] if np.ndim(n) else n
        return _uniform(lo, hi, total, np.random.default_rng(seed))
    axes = [np.linspace(lo[a], hi[a], counts[a]) for a in range(3)]
    return np.ascontiguousarray(np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3))


def _uniform(lo, hi, n, rng) -> np.ndarray:
    return lo + (hi - lo) * rng.random((n, 3))


def random_in(domain, n: int, seed: int = 0, max_draws: int = 100) -> np.ndarray:
    """n uniform random points in the domain of a Field, Grid, analytic field or (3, 2) bounds.

    For a Field, points whose cell touches a NaN node are rejected and redrawn (at most
    ``max_draws * n`` draws in all), except where the field is a large file not in memory
    (``bricks.read_whole``): reading all of it to place seeds would cost what the trace
    saves by reading only where lines go, so there a seed in NaN data ends its line at once
    (``seed_outside``).  The result depends only on ``seed``.
    """
    n = _count(n, "random: n")
    rng = np.random.default_rng(seed)
    lo, hi = _bounds(domain).T
    if not isinstance(domain, Field) or not read_whole(domain):
        return _uniform(lo, hi, n, rng)
    kept, have, drawn = [], 0, 0
    while have < n and drawn < max_draws * n:
        batch = _uniform(lo, hi, n, rng)
        drawn += n
        ok = domain.sample(batch)[1] == INSIDE  # (a large field read near the points only)
        kept.append(batch[ok])
        have += int(ok.sum())
    if have < n:
        raise SeedError(
            f"{domain.source}: only {have} of {n} random seeds fell in valid (non-NaN) cells "
            f"after {drawn} draws"
        )
    return np.ascontiguousarray(np.concatenate(kept)[:n])


def _bounds(domain) -> np.ndarray:
    if isinstance(domain, Field):
        b = domain.grid.bounds
    elif isinstance(domain, Grid):
        b = domain.bounds
    elif hasattr(domain, "default_bounds"):  # an analytic field
        b = domain.default_bounds
    else:
        b = np.asarray(domain, dtype=np.float64)
    if b.shape != (3, 2) or not np.all(np.isfinite(b)) or np.any(b[:, 1] < b[:, 0]):
        raise SeedError(f"random: domain bounds must be (3, 2) finite [min, max] rows, got {b.tolist()}")
    return b


# -- the CLI's --seeds value -----------------------------------------------------------------
def parse_seed_spec(spec: str, field=None) -> np.ndarray:
    """Seeds from a spec string: a file path or ``kind:part:part...`` (see ``SPEC_HELP``).

    ``random`` needs ``field`` (Field, Grid, analytic field or bounds) for its domain,
    ``density`` and ``where`` a Field.  With ``field=CHECK_ONLY`` the spec is only checked
    (even, and the parts no field decides) and None is returned.
    """
    spec = str(spec).strip()
    kind, sep, rest = spec.partition(":")
    if sep and kind.lower() == "even":
        parse_even_spec(spec)  # a malformed spec says what is wrong with it first
        if field is CHECK_ONLY:
            return None
        raise SeedError(f"seed spec '{spec}': 'even' grows evenly spaced lines, it gives no seed "
                        "points by itself; trace it with flowkit.seeding.trace_spec (the CLI and "
                        "scenes do)")
    parse = _FORMS.get(kind.lower()) if sep else None
    if parse is None:
        if Path(spec).suffix.lower() in FILE_TYPES:
            return None if field is CHECK_ONLY else from_file(spec)
        raise SeedError(f"seed spec '{spec}': not a seed file nor a known form; allowed: {SPEC_HELP}")
    return parse(_Spec(spec, kind.lower(), rest.split(":")), field)


class _Spec:
    """The parts of one spec, with errors that name the spec and the part."""

    def __init__(self, spec, kind, parts):
        self.spec, self.kind, self.parts = spec, kind, parts

    def error(self, msg):
        return SeedError(f"seed spec '{self.spec}': {msg}; form: {_USAGE[self.kind]}")

    def nparts(self, lo, hi=None):
        hi = lo if hi is None else hi
        if not lo <= len(self.parts) <= hi:
            want = str(lo) if lo == hi else f"{lo} to {hi}"
            raise self.error(f"'{self.kind}' takes {want} parts after '{self.kind}:', got {len(self.parts)}")

    def _numbers(self, i, count, conv, what):
        part = self.parts[i]
        vals = part.split(",")
        try:
            out = [conv(v) for v in vals]
        except ValueError:
            out = None
        if out is None or len(out) != count or (conv is float and not np.all(np.isfinite(out))):
            raise self.error(f"part {i + 1} '{part}' must be {what}")
        return out

    def point(self, i):
        return self._numbers(i, 3, float, "a point x,y,z (3 comma-separated finite numbers)")

    def count(self, i, name="n", minimum=1):
        what = f"{name}, an integer >= {minimum}"
        n = self._numbers(i, 1, int, what)[0]
        if n < minimum:
            raise self.error(f"part {i + 1} '{self.parts[i]}' must be {what}")
        return n

    def counts(self, i, k, name):
        if len(self.parts[i].split(",")) != k:
            return None
        vals = self._numbers(i, k, int, f"{name}, {k} comma-separated positive integers")
        if min(vals) < 1:
            raise self.error(f"part {i + 1} '{self.parts[i]}' must be {name}, positive integers")
        return vals


def _need_field(s: _Spec, field, what: str):
    if field is None:
        raise s.error(f"'{s.kind}' {what}, but no field was given")
    if not isinstance(field, Field):
        raise s.error(f"'{s.kind}' {what}: needs a gridded Field, got {type(field).__name__}")


def _named(s: _Spec, make, *args):
    """``make(*args)``, its SeedError restated as an error of the spec ``s``."""
    try:
        return make(*args)
    except SeedError as e:
        raise s.error(str(e)) from None


def _seed_part(s: _Spec, i: int) -> int:
    return s.count(i, "seed", minimum=0) if len(s.parts) > i else 0


def _density_form(s: _Spec, field):
    from ..seeding.data import density

    s.nparts(2, 3)
    n, seed = s.count(0), _seed_part(s, 2)
    if field is CHECK_ONLY:
        return None
    _need_field(s, field, "weighs the field's data")
    return _named(s, density, field, n, s.parts[1].strip(), seed)


def _where_form(s: _Spec, field):
    from ..seeding.data import where

    s.nparts(2, 3)
    n, seed = s.count(1), _seed_part(s, 2)
    if field is CHECK_ONLY:
        from ..seeding.expr import Expression, ExpressionError

        try:
            Expression(s.parts[0])  # the grammar; the names are the field's to check
        except ExpressionError as e:
            raise s.error(str(e)) from None
        return None
    _need_field(s, field, "tests the field's data")
    return _named(s, where, field, s.parts[0], n, seed)


def _points_form(s: _Spec, field):
    return np.array([s.point(i) for i in range(len(s.parts))], dtype=np.float64)


def _line_args(s: _Spec) -> tuple:
    s.nparts(3)
    return s.point(0), s.point(1), s.count(2)


def _plane_args(s: _Spec) -> tuple:
    s.nparts(4)
    nuv = s.counts(3, 2, "nu,nv")
    if nuv is None:
        raise s.error(f"part 4 '{s.parts[3]}' must be nu,nv, 2 comma-separated positive integers")
    return s.point(0), s.point(1), s.point(2), *nuv


def _line_form(s: _Spec, field):
    return line(*_line_args(s))


def _plane_form(s: _Spec, field):
    return _named(s, plane, *_plane_args(s))


def _box_form(s: _Spec, field):
    s.nparts(3, 5)
    n = s.counts(2, 3, "nx,ny,nz") or s.count(2)
    rand = len(s.parts) > 3
    if rand and s.parts[3].lower() != "random":
        raise s.error(f"part 4 '{s.parts[3]}' must be the word 'random' (or left out for a lattice)")
    seed = _seed_part(s, 4)
    return _named(s, box, s.point(0), s.point(1), n, rand, seed)


def _random_form(s: _Spec, field):
    s.nparts(1, 2)
    n, seed = s.count(0), _seed_part(s, 1)
    if field is CHECK_ONLY:
        return None
    if field is None:
        raise s.error("'random' draws in the field's domain, but no field was given")
    return random_in(field, n, seed)


_FORMS = {"points": _points_form, "line": _line_form, "plane": _plane_form, "box": _box_form,
          "random": _random_form, "density": _density_form, "where": _where_form}
_USAGE = {
    "points": "points:x,y,z[:x,y,z...]",
    "line": "line:x0,y0,z0:x1,y1,z1:n",
    "plane": "plane:ox,oy,oz:ux,uy,uz:vx,vy,vz:nu,nv",
    "box": "box:x0,y0,z0:x1,y1,z1:n[:random[:seed]] (n or nx,ny,nz)",
    "random": "random:n[:seed]",
    "density": "density:n:ATTRIBUTE[:seed] (ATTRIBUTE: speed, vorticity_magnitude, a scalar "
               "field or grad(SCALAR))",
    "where": "where:EXPR:n[:seed] (EXPR: scalar names, numbers, < <= > >= == !=, and or not, "
             "parentheses)",
    "even": "even:DSEP[:DTEST[:seed]] (world units, or a fraction of the domain diagonal with a "
            "d suffix: 0.05d, 1/30d; DTEST default DSEP/2)",
}


# -- evenly spaced lines ---------------------------------------------------------------------
class Length:
    """A length in world units, or ``fraction`` of the domain diagonal (``relative``)."""

    def __init__(self, value: float, relative: bool = False):
        self.value, self.relative = float(value), bool(relative)

    def resolve(self, diagonal: float) -> float:
        return self.value * diagonal if self.relative else self.value

    def __eq__(self, other):
        return isinstance(other, Length) and (self.value, self.relative) == (other.value,
                                                                             other.relative)

    def __repr__(self):
        return f"{self.value!r}{'d' if self.relative else ''}"


class EvenSpec:
    """``even:DSEP[:DTEST[:SEED]]`` parsed: dsep, dtest (None: dsep / 2) and the random seed."""

    def __init__(self, dsep: Length, dtest: Length | None, seed: int):
        self.dsep, self.dtest, self.seed = dsep, dtest, seed

    def distances(self, diagonal: float) -> tuple[float, float]:
        dsep = self.dsep.resolve(diagonal)
        dtest = 0.5 * dsep if self.dtest is None else self.dtest.resolve(diagonal)
        return dsep, dtest


def _length(s: _Spec, i: int, name: str) -> Length:
    text = s.parts[i].strip().lower()
    rel = text.endswith("d")
    num = text[:-1] if rel else text
    try:
        a, slash, b = num.partition("/")
        value = float(a) / float(b) if slash else float(a)
    except (ValueError, ZeroDivisionError):
        value = None
    if value is None or not np.isfinite(value) or value <= 0:
        raise s.error(f"part {i + 1} '{s.parts[i]}' must be {name}, a positive length (world "
                      "units, or a fraction of the domain diagonal with a d suffix: 0.05d, 1/30d)")
    return Length(value, rel)


def parse_even_spec(spec: str) -> EvenSpec | None:
    """The parsed ``even:`` spec, or None when ``spec`` is another form."""
    spec = str(spec).strip()
    kind, sep, rest = spec.partition(":")
    if not sep or kind.lower() != "even":
        return None
    s = _Spec(spec, "even", rest.split(":"))
    s.nparts(1, 3)
    dsep = _length(s, 0, "DSEP")
    dtest = _length(s, 1, "DTEST") if len(s.parts) > 1 and s.parts[1].strip() else None
    if dtest is not None and dtest.relative == dsep.relative and not dtest.value < dsep.value:
        raise s.error(f"DTEST {dtest!r} must be smaller than DSEP {dsep!r}")
    return EvenSpec(dsep, dtest, _seed_part(s, 2))


# -- spec strings of the point forms (exact: repr of a float parses back to the same float) ---
def _point_text(p) -> str:
    return ",".join(repr(float(v)) for v in points(p)[0])


def line_spec(p0, p1, n: int) -> str:
    """The spec of ``line(p0, p1, n)``."""
    return f"line:{_point_text(p0)}:{_point_text(p1)}:{_count(n, 'line: n')}"


def plane_spec(origin, u, v, nu: int, nv: int) -> str:
    """The spec of ``plane(origin, u, v, nu, nv)``."""
    return (f"plane:{_point_text(origin)}:{_point_text(u)}:{_point_text(v)}:"
            f"{_count(nu, 'plane: nu')},{_count(nv, 'plane: nv')}")


def parse_rake_spec(spec: str) -> tuple[str, tuple] | None:
    """The arguments of a ``line:`` or ``plane:`` spec, ("line", (p0, p1, n)) or ("plane",
    (origin, u, v, nu, nv)), checked as ``parse_seed_spec`` checks them; None for other forms.
    ``line(*args)`` / ``plane(*args)`` give the spec's points."""
    spec = str(spec).strip()
    kind, sep, rest = spec.partition(":")
    parts = {"line": _line_args, "plane": _plane_args}.get(kind.lower()) if sep else None
    if parts is None:
        return None
    s = _Spec(spec, kind.lower(), rest.split(":"))
    args = parts(s)
    if s.kind == "plane":
        _named(s, plane, *args)  # u and v must span a plane
    return s.kind, args


def points_spec(values) -> str:
    """The spec of explicit points (at least one)."""
    p = points(values)
    if not len(p):
        raise SeedError("points spec: needs at least one point")
    return "points:" + ":".join(_point_text(q) for q in p)
