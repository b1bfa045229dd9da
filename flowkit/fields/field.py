"""A vector field plus named scalar fields, all as node (point) data on one Grid."""

from __future__ import annotations

from collections.abc import MutableMapping
from dataclasses import dataclass, field

import numpy as np

from . import interp
from .bricks import by_bricks, read_whole
from .grid import Grid
from .stored import Stored, as_kept, fmt_bytes


class FieldError(ValueError):
    """Field arrays that do not fit the grid or each other."""


class Arrays(MutableMapping):
    """Scalar fields by name.  A ``Stored`` one (still in its file) is read on first access
    and kept; names, shapes and types are known without reading (``meta``).  An array set by
    name must have the grid's shape."""

    def __init__(self, items: dict, shape: tuple, source: str = "<memory>"):
        self.shape, self.source, self._items = shape, source, {}
        for n, a in items.items():
            self[n] = a

    def __setitem__(self, name, a):
        a = a if isinstance(a, Stored) else np.asarray(a)
        if a.shape != self.shape:
            raise FieldError(f"{self.source}: scalar '{name}' has shape {a.shape}, expected "
                             f"{self.shape} (nx, ny, nz)")
        self._items[name] = a if isinstance(a, Stored) else as_kept(a)

    def __delitem__(self, name):
        del self._items[name]

    def __getitem__(self, name):
        a = self._items[name]
        if isinstance(a, Stored):
            a = self._items[name] = a.read()
        return a

    def __iter__(self):
        return iter(self._items)

    def __len__(self):
        return len(self._items)

    def meta(self, name):
        """The array itself where it is in memory, else its Stored handle (shape, dtype,
        chunks): what a summary needs, without reading."""
        return self._items[name]

    def in_memory(self, name) -> bool:
        return not isinstance(self._items[name], Stored)

    def __repr__(self):
        return f"Arrays({', '.join(self._items)})"


@dataclass(eq=False)
class Field:
    """``vector`` is (nx, ny, nz, 3) node data; ``scalars`` maps names to (nx, ny, nz) node data.

    Arrays are float32 or float64, as the file stores them (other types become float64; the
    integrator computes in float64 either way: see ``stored.py``), and may be given as
    ``Stored`` handles, read when first used: ``vector`` and ``scalars[name]`` read them.

    ``source`` names where the data came from (a file path, an analytic field) so that errors
    and summaries can say so; ``time`` is the snapshot time when known, in seconds (since
    ``time_origin``, an ISO date, where the file's times are dates); ``notes`` records how the
    data was obtained (e.g. "resampled from an unstructured mesh by linear interpolation").
    ``units`` maps array names (the vector's and the scalars') to the units the file states
    (UDUNITS/CF spelling, e.g. "m/s", "K"); ``length_units`` are the grid coordinates' units.
    Unknown units are left out: nothing is guessed.
    """

    grid: Grid
    vector: np.ndarray  # (a property, below: a Stored vector is read on first use)
    scalars: dict[str, np.ndarray] = field(default_factory=dict)
    vector_name: str = "U"
    source: str = "<memory>"
    time: float | None = None
    notes: list[str] = field(default_factory=list)
    units: dict[str, str] = field(default_factory=dict)
    length_units: str | None = None
    time_origin: str | None = None

    def __post_init__(self):
        self._check_vector(self._vector)
        items = self.scalars._items if isinstance(self.scalars, Arrays) else self.scalars
        self.scalars = Arrays(dict(items), self.grid.shape, self.source)

    def _check_vector(self, v):
        if v.shape != self.grid.shape + (3,):
            raise FieldError(
                f"{self.source}: vector '{self.vector_name}' has shape {v.shape}, "
                f"expected {self.grid.shape + (3,)} (nx, ny, nz, 3) for the grid"
            )

    def _get_vector(self) -> np.ndarray:
        if isinstance(self._vector, Stored):
            self._vector = self._vector.read()
        return self._vector

    def _set_vector(self, v):
        v = v if isinstance(v, Stored) else as_kept(v)
        if "vector_name" in self.__dict__:  # (set again after __init__: checked here)
            self._check_vector(v)
        self._vector = v

    @property
    def dtype(self) -> np.dtype:
        """The type the vector is held in (float32 or float64), known without reading it."""
        return self._vector.dtype

    def vector_in_memory(self) -> bool:
        return not isinstance(self._vector, Stored)

    def stored_vector(self) -> Stored:
        """The vector as a Stored handle, without reading it (an array in memory seen as one)."""
        return Stored.of(self._vector, f"{self.source}: {self.vector_name}")

    def vector_box(self, box) -> np.ndarray:
        """The vector at the nodes of ``box`` (three slices), read alone where it is not in
        memory."""
        return self._vector[box] if self.vector_in_memory() else self._vector.read_box(box)

    # -- sampling -------------------------------------------------------------------------
    def sample(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Trilinear vector at points (n, 3) -> (values (n, 3), status (n,) int8).

        Status is ``interp.INSIDE``, ``interp.OUTSIDE`` (values NaN, never extrapolated) or
        ``interp.NAN_CELL`` (a corner node of the cell holds NaN/inf; values NaN).
        """
        pts = _points(points)
        if not read_whole(self):
            got = by_bricks(self, pts, lambda f, p: dict(zip(("v", "s"), f.sample(p))))
            return got.get("v", np.empty((0, 3))), got.get("s", np.empty(0, np.int8))
        out = np.empty((pts.shape[0], 3))
        status = np.empty(pts.shape[0], np.int8)
        interp.sample_vectors(*self.grid.kernel_args(), self.vector, pts, out, status)
        return out, status

    def sample_scalar(self, name: str, points) -> tuple[np.ndarray, np.ndarray]:
        """Trilinear scalar ``name`` at points (n, 3) -> (values (n,), status (n,) int8)."""
        self._known(name)
        pts = _points(points)
        if not read_whole(self, name):
            got = by_bricks(self, pts, lambda f, p: dict(zip("vs", f.sample_scalar(name, p))),
                            [name])
            return got.get("v", np.empty(0)), got.get("s", np.empty(0, np.int8))
        arr = self.scalar(name)
        out = np.empty(pts.shape[0])
        status = np.empty(pts.shape[0], np.int8)
        interp.sample_scalars(*self.grid.kernel_args(), arr, pts, out, status)
        return out, status

    def sample_with(self, name: str, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The vector and scalar ``name`` at points (n, 3), each point located once: (vectors
        (n, 3), values (n,), status (n,) int8: NAN_CELL where either's cell has a NaN corner);
        the values ``sample`` and ``sample_scalar`` give."""
        self._known(name)
        pts = _points(points)
        if not (read_whole(self) and read_whole(self, name)):
            got = by_bricks(self, pts, lambda f, p: dict(zip("vas", f.sample_with(name, p))),
                            [name])
            return (got.get("v", np.empty((0, 3))), got.get("a", np.empty(0)),
                    got.get("s", np.empty(0, np.int8)))
        arr = self.scalar(name)
        out = np.empty((pts.shape[0], 3))
        out_s = np.empty(pts.shape[0])
        status = np.empty(pts.shape[0], np.int8)
        interp.sample(*self.grid.kernel_args(), self.vector, arr, pts, out, out_s, status)
        return out, out_s, status

    def scalar(self, name: str) -> np.ndarray:
        self._known(name)
        return self.scalars[name]

    def _known(self, name: str) -> None:
        if name not in self.scalars:
            have = ", ".join(sorted(self.scalars)) or "none"
            raise KeyError(f"{self.source}: no scalar field '{name}' (available: {have})")

    # -- statistics -----------------------------------------------------------------------
    def speed(self) -> np.ndarray:
        """Node speeds, float64 whatever the vector's type."""
        v = self.vector
        return np.sqrt(np.einsum("...i,...i->...", v, v, dtype=np.float64))

    def typical_speed(self) -> float:
        """Median of the finite nonzero node speeds (0 for an all-zero field)."""
        s = self.speed().ravel()
        s = s[np.isfinite(s) & (s > 0)]
        return float(np.median(s)) if s.size else 0.0

    def arrays(self) -> dict[str, np.ndarray]:
        """Every array by name, the vector first (each read from its file if it is not yet)."""
        return {self.vector_name: self.vector, **self.scalars}

    def array_meta(self) -> dict:
        """Every array by name, the vector first, as it is held now: in memory, or its
        ``Stored`` handle (shape, dtype, nbytes, chunks) where it is not read yet."""
        return {self.vector_name: self._vector, **{n: self.scalars.meta(n) for n in self.scalars}}

    def summary(self, stats: bool = True, progress=None) -> str:
        """What ``flowkit info`` prints: grid, arrays (type, size, chunking, units) and notes;
        with ``stats`` each array's range and NaN/inf counts too, computed slab by slab (an
        array still in its file is read a slab at a time, never whole; ``progress(nbytes)``
        after each slab)."""
        lines = [f"field: {self.source}"]
        if self.time is not None:
            date = (f" s since {self.time_origin} = {date_of(self.time, self.time_origin)}"
                    if self.time_origin else "")
            lines.append(f"time: {self.time:.10g}{date}")
        lines.append(self.grid.describe())
        if self.length_units:
            lines.append(f"lengths in {self.length_units}")
        lines.append("arrays (point data):")
        for name, a in self.array_meta().items():
            unit = f" [{self.units[name]}]" if self.units.get(name) else ""
            is_vector = name == self.vector_name
            line = f"  {name}{unit}: {'vector (3)' if is_vector else 'scalar'}, {_storage(a)}"
            if stats:
                line += ", " + _statistics(name, a, is_vector, progress)
            lines.append(line)
        for n in self.notes:
            lines.append(f"note: {n}")
        return "\n".join(lines)

    def __repr__(self):
        """The summary ``flowkit info`` prints, from the metadata alone (no data is read)."""
        return f"<{self.summary(stats=False)}>"

    def _repr_html_(self) -> str:
        import html

        return f"<pre>{html.escape(repr(self))}</pre>"


# the vector: read from its file on first use (a dataclass field whose attribute is a property,
# so that the generated __init__ and dataclasses.replace go through the setter)
Field.vector = property(Field._get_vector, Field._set_vector,
                        doc="The vector node array, read from its file on first use.")


def date_of(seconds: float, origin: str) -> str:
    """The date ``seconds`` after ``origin`` (an ISO date, ``Field.time_origin``), to the
    millisecond where there are any: ``2024-03-01 12:00:30``."""
    stamp = np.datetime64(origin, "ms") + np.timedelta64(round(seconds * 1000.0), "ms")
    return str(stamp).replace("T", " ").removesuffix(".000")


def _points(points) -> np.ndarray:
    pts = np.ascontiguousarray(np.atleast_2d(np.asarray(points, dtype=np.float64)))
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {np.shape(points)}")
    return pts


def _storage(a) -> str:
    """Type, size and (for an array still in its file) chunking and the type the file stores."""
    text = f"{a.dtype}, {fmt_bytes(a.nbytes)}"
    if isinstance(a, Stored):
        if a.stored.newbyteorder("=") != a.dtype:
            text += f" (stored as {a.stored})"
        text += f", chunks {'x'.join(map(str, a.chunks))}" if a.chunks else ", contiguous"
    return text


def _statistics(name: str, a, is_vector: bool, progress=None) -> str:
    """Range (the magnitude's and each component's for a vector) and NaN/inf counts, over
    slabs: memory bounded by a slab whatever the array's size."""
    n_nan = n_inf = 0
    lo = np.full(4, np.inf)
    hi = np.full(4, -np.inf)
    for slab in Stored.of(a).slabs(progress):
        finite = bool(np.isfinite(slab).all())  # (the common case: no masked copies)
        if not finite:
            n_nan += int(np.isnan(slab).sum())
            n_inf += int(np.isinf(slab).sum())
        if is_vector:
            mag = np.sqrt(np.einsum("...i,...i->...", slab, slab, dtype=np.float64))
            cols = [mag, *(slab[..., i] for i in range(3))]
        else:
            cols = [slab]
        for i, c in enumerate(cols):
            c = c if finite else c[np.isfinite(c)]
            if c.size:
                lo[i], hi[i] = min(lo[i], float(c.min())), max(hi[i], float(c.max()))
    if is_vector:
        rng = (f"|{name}| in [{lo[0]:.6g}, {hi[0]:.6g}]" if np.isfinite(lo[0])
               else "no finite values")
        comps = " ".join(f"{c}:[{lo[i + 1]:.4g}, {hi[i + 1]:.4g}]"
                         for i, c in enumerate("xyz") if np.isfinite(lo[i + 1]))
        rng += f" ({comps})" if comps else ""
    else:
        rng = f"range [{lo[0]:.6g}, {hi[0]:.6g}]" if np.isfinite(lo[0]) else "no finite values"
    bad = f", {n_nan} NaN" if n_nan else ""
    bad += f", {n_inf} inf" if n_inf else ""
    return rng + bad
