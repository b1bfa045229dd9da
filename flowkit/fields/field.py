"""A vector field plus named scalar fields, all as node (point) data on one Grid."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import interp
from .grid import Grid


class FieldError(ValueError):
    """Field arrays that do not fit the grid or each other."""


@dataclass(eq=False)
class Field:
    """``vector`` is (nx, ny, nz, 3) float64; ``scalars`` maps names to (nx, ny, nz) float64.

    ``source`` names where the data came from (a file path, an analytic field) so that errors
    and summaries can say so; ``time`` is the snapshot time when known, in seconds (since
    ``time_origin``, an ISO date, where the file's times are dates); ``notes`` records how the
    data was obtained (e.g. "resampled from an unstructured mesh by linear interpolation").
    ``units`` maps array names (the vector's and the scalars') to the units the file states
    (UDUNITS/CF spelling, e.g. "m/s", "K"); ``length_units`` are the grid coordinates' units.
    Unknown units are left out: nothing is guessed.
    """

    grid: Grid
    vector: np.ndarray
    scalars: dict[str, np.ndarray] = field(default_factory=dict)
    vector_name: str = "U"
    source: str = "<memory>"
    time: float | None = None
    notes: list[str] = field(default_factory=list)
    units: dict[str, str] = field(default_factory=dict)
    length_units: str | None = None
    time_origin: str | None = None

    def __post_init__(self):
        shape = self.grid.shape
        v = np.asarray(self.vector)
        if v.shape != shape + (3,):
            raise FieldError(
                f"{self.source}: vector '{self.vector_name}' has shape {v.shape}, "
                f"expected {shape + (3,)} (nx, ny, nz, 3) for the grid"
            )
        self.vector = np.ascontiguousarray(v, dtype=np.float64)
        checked = {}
        for name, a in self.scalars.items():
            a = np.asarray(a)
            if a.shape != shape:
                raise FieldError(
                    f"{self.source}: scalar '{name}' has shape {a.shape}, expected {shape} (nx, ny, nz)"
                )
            checked[name] = np.ascontiguousarray(a, dtype=np.float64)
        self.scalars = checked

    # -- sampling -------------------------------------------------------------------------
    def sample(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Trilinear vector at points (n, 3) -> (values (n, 3), status (n,) int8).

        Status is ``interp.INSIDE``, ``interp.OUTSIDE`` (values NaN, never extrapolated) or
        ``interp.NAN_CELL`` (a corner node of the cell holds NaN/inf; values NaN).
        """
        pts = _points(points)
        out = np.empty((pts.shape[0], 3))
        status = np.empty(pts.shape[0], np.int8)
        interp.sample_vectors(*self.grid.kernel_args(), self.vector, pts, out, status)
        return out, status

    def sample_scalar(self, name: str, points) -> tuple[np.ndarray, np.ndarray]:
        """Trilinear scalar ``name`` at points (n, 3) -> (values (n,), status (n,) int8)."""
        arr = self.scalar(name)
        pts = _points(points)
        out = np.empty(pts.shape[0])
        status = np.empty(pts.shape[0], np.int8)
        interp.sample_scalars(*self.grid.kernel_args(), arr, pts, out, status)
        return out, status

    def sample_with(self, name: str, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The vector and scalar ``name`` at points (n, 3), each point located once: (vectors
        (n, 3), values (n,), status (n,) int8: NAN_CELL where either's cell has a NaN corner);
        the values ``sample`` and ``sample_scalar`` give."""
        arr = self.scalar(name)
        pts = _points(points)
        out = np.empty((pts.shape[0], 3))
        out_s = np.empty(pts.shape[0])
        status = np.empty(pts.shape[0], np.int8)
        interp.sample(*self.grid.kernel_args(), self.vector, arr, pts, out, out_s, status)
        return out, out_s, status

    def scalar(self, name: str) -> np.ndarray:
        try:
            return self.scalars[name]
        except KeyError:
            have = ", ".join(sorted(self.scalars)) or "none"
            raise KeyError(f"{self.source}: no scalar field '{name}' (available: {have})") from None

    # -- statistics -----------------------------------------------------------------------
    def speed(self) -> np.ndarray:
        return np.sqrt(np.einsum("...i,...i->...", self.vector, self.vector))

    def typical_speed(self) -> float:
        """Median of the finite nonzero node speeds (0 for an all-zero field)."""
        s = self.speed().ravel()
        s = s[np.isfinite(s) & (s > 0)]
        return float(np.median(s)) if s.size else 0.0

    def arrays(self) -> dict[str, np.ndarray]:
        return {self.vector_name: self.vector, **self.scalars}

    def summary(self) -> str:
        lines = [f"field: {self.source}"]
        if self.time is not None:
            date = (f" s since {self.time_origin} = {date_of(self.time, self.time_origin)}"
                    if self.time_origin else "")
            lines.append(f"time: {self.time:.10g}{date}")
        lines.append(self.grid.describe())
        if self.length_units:
            lines.append(f"lengths in {self.length_units}")
        lines.append("arrays (point data):")
        for name, a in self.arrays().items():
            unit = f" [{self.units[name]}]" if self.units.get(name) else ""
            lines.append("  " + _describe_array(name, a, is_vector=a is self.vector, unit=unit))
        for n in self.notes:
            lines.append(f"note: {n}")
        return "\n".join(lines)


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


def _describe_array(name: str, a: np.ndarray, is_vector: bool, unit: str = "") -> str:
    finite = np.isfinite(a)
    n_nan = int(np.isnan(a).sum())
    n_inf = int(np.isinf(a).sum())
    kind = "vector (3)" if is_vector else "scalar"
    if is_vector:
        mag = np.sqrt(np.einsum("...i,...i->...", a, a))
        ok = np.isfinite(mag)
        rng = f"|{name}| in [{mag[ok].min():.6g}, {mag[ok].max():.6g}]" if ok.any() else "no finite values"
        comps = " ".join(
            f"{c}:[{a[..., i][finite[..., i]].min():.4g}, {a[..., i][finite[..., i]].max():.4g}]"
            for i, c in enumerate("xyz") if finite[..., i].any()
        )
        rng += f" ({comps})"
    else:
        rng = f"range [{a[finite].min():.6g}, {a[finite].max():.6g}]" if finite.any() else "no finite values"
    bad = f", {n_nan} NaN" if n_nan else ""
    bad += f", {n_inf} inf" if n_inf else ""
    return f"{name}{unit}: {kind}, {rng}{bad}"
