"""Lines: many polylines in one contiguous array, with per-vertex and per-line data."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np


def finite_rows(points: np.ndarray) -> np.ndarray:
    """Which rows of ``points`` (N, 3) are finite: ``np.all(np.isfinite(points), axis=1)`` in
    a quarter of its time (numpy reduces a 3-long axis slowly; ~0.6 ms saved on 59k)."""
    f = np.isfinite(points)
    return f[:, 0] & f[:, 1] & f[:, 2]


@dataclass(eq=False)
class Lines:
    """``points`` (N, 3); line i is ``points[offsets[i]:offsets[i + 1]]``.

    ``point_data`` maps attribute names to arrays with N rows ((N,) or (N, k));
    ``line_data`` maps names to arrays with one row per line (``seed_id``, ``reason``,
    ``n_accepted``, ``n_rejected``...); ``attrs`` holds run metadata (method, tolerances, source).
    """

    points: np.ndarray
    offsets: np.ndarray
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    line_data: dict[str, np.ndarray] = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)

    def __post_init__(self):
        self.points = np.asarray(self.points)
        self.offsets = np.asarray(self.offsets, dtype=np.int64)
        n, L = self.points.shape[0], self.offsets.size - 1
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise ValueError(f"Lines.points must be (N, 3), got {self.points.shape}")
        if L < 0 or self.offsets[0] != 0 or self.offsets[-1] != n or np.any(np.diff(self.offsets) < 0):
            raise ValueError("Lines.offsets must start at 0, end at len(points) and not decrease")
        for k, v in self.point_data.items():
            if len(v) != n:
                raise ValueError(f"point attribute '{k}' has {len(v)} rows, expected {n}")
        for k, v in self.line_data.items():
            if len(v) != L:
                raise ValueError(f"line attribute '{k}' has {len(v)} rows, expected {L}")

    @property
    def units(self) -> dict[str, str]:
        """Units per attribute (from ``attrs["units"]``, JSON), e.g. {"time": "s"}; a lines file
        stores each as the CF ``units`` of the attribute's variable."""
        import json

        u = self.attrs.get("units")
        return dict(json.loads(u)) if isinstance(u, str) and u.startswith("{") else {}

    @classmethod
    def empty(cls) -> Lines:
        """No lines: no vertices, no attributes."""
        return cls(np.zeros((0, 3)), np.zeros(1, np.int64))

    # -- shape ---------------------------------------------------------------------------
    def __len__(self) -> int:
        """The number of lines."""
        return self.offsets.size - 1

    @property
    def n_points(self) -> int:
        """The number of vertices of all lines together."""
        return self.points.shape[0]

    @property
    def n_vertices(self) -> np.ndarray:
        """Vertex count of each line, (L,) int64 (``arc_length()`` gives their lengths)."""
        return np.diff(self.offsets)

    @property
    def lengths(self) -> np.ndarray:
        """Vertex count of each line: the same as ``n_vertices``, the older name."""
        return self.n_vertices

    def arc_length(self) -> np.ndarray:
        """Arc length of each line along its vertices, (L,) float64 (0 for a line of one
        vertex; a segment with a non-finite end counts 0)."""
        d = np.diff(self.points.astype(np.float64), axis=0)
        seg = np.sqrt(np.einsum("ij,ij->i", d, d))
        line = self.line_index()
        same = (line[1:] == line[:-1]) & np.isfinite(seg)
        return np.bincount(line[1:][same], weights=seg[same], minlength=len(self))

    def line_index(self) -> np.ndarray:
        """Line number of every vertex, (N,)."""
        return np.repeat(np.arange(len(self)), self.lengths)

    # -- access --------------------------------------------------------------------------
    def __getitem__(self, key) -> Lines:
        """The lines selected, as Lines: ``lines[i]`` (one line: its ``points``, every
        per-vertex attribute in ``point_data`` and its per-line values in ``line_data``, each
        an array of one row), ``lines[a:b]``, ``lines[mask]`` (a boolean per line) or
        ``lines[indices]`` (negative ones count from the end), in the order given."""
        if isinstance(key, (int, np.integer)):
            idx = np.array([self._line(key)])
        elif isinstance(key, slice):
            idx = np.arange(len(self))[key]
        else:
            idx = self._indices(key)
        starts, stops = self.offsets[idx], self.offsets[idx + 1]
        counts = stops - starts
        rows = _ranges(starts, counts)
        return Lines(
            self.points[rows],
            np.concatenate([[0], np.cumsum(counts)]),
            {k: v[rows] for k, v in self.point_data.items()},
            {k: v[idx] for k, v in self.line_data.items()},
            dict(self.attrs),
        )

    def _indices(self, key) -> np.ndarray:
        """Line numbers from a boolean mask or integer indices; anything else is refused with
        what is expected."""
        idx = np.asarray(key)
        if idx.dtype == bool:
            if idx.shape != (len(self),):
                raise IndexError(f"a line mask has one boolean per line ({len(self)}), got "
                                 f"shape {idx.shape}")
            return np.flatnonzero(idx)
        if idx.ndim != 1 or not (np.issubdtype(idx.dtype, np.integer) or idx.size == 0):
            hint = (f"; the per-vertex attribute is lines.point_data[{key!r}]"
                    if isinstance(key, str) else "")
            raise TypeError(f"lines[...] takes a line number, a slice, a boolean per line or "
                            f"integer line numbers, got {key!r}{hint}")
        idx = idx.astype(np.int64)
        bad = (idx < -len(self)) | (idx >= len(self))
        if bad.any():
            raise IndexError(f"line {idx[bad][0]} out of range for {len(self)} lines")
        return np.where(idx < 0, idx + len(self), idx)

    def __iter__(self) -> Iterator[Lines]:
        """Each line in turn, as ``lines[i]``."""
        for i in range(len(self)):
            yield self[i]

    def where(self, mask=None, *, reason=None) -> Lines:
        """The lines selected by ``mask`` (a boolean per line) and/or by ``reason``: a name as
        ``flowkit info`` prints it ("max_length", "out_of_domain", ...), a ``Reason``, or a list
        of them; a line traced in both directions matches when either end stopped so."""
        keep = np.ones(len(self), bool)
        if mask is not None:
            m = np.asarray(mask)
            if m.dtype != bool or m.shape != (len(self),):
                raise ValueError(f"Lines.where: mask must be {len(self)} booleans (one per "
                                 f"line), got {m.dtype} of shape {m.shape}")
            keep &= m
        if reason is not None:
            codes = _reason_codes(reason)
            hit = np.isin(self.line_data["reason"], codes)
            if "reason_backward" in self.line_data:
                hit |= np.isin(self.line_data["reason_backward"], codes)
            keep &= hit
        return self[keep]

    def line_points(self, i: int) -> np.ndarray:
        """The vertices of line ``i``, (n, 3) (a view)."""
        return self.points[self.offsets[self._line(i)]:self.offsets[self._line(i) + 1]]

    def line_attribute(self, name: str, i: int) -> np.ndarray:
        """Per-vertex attribute ``name`` along line ``i`` (a view): ``lines[i]`` gives every
        attribute of one line at once."""
        if not isinstance(name, str):
            raise TypeError(f"line_attribute(name, i): name is an attribute's name (one of "
                            f"{', '.join(self.point_data) or 'none'}), got {name!r}")
        if name not in self.point_data:
            raise KeyError(f"no per-vertex attribute '{name}' (available: "
                           f"{', '.join(self.point_data) or 'none'})")
        i = self._line(i)
        return self.point_data[name][self.offsets[i]:self.offsets[i + 1]]

    def _line(self, i) -> int:
        if not isinstance(i, (int, np.integer)):
            raise TypeError(f"a line number is an integer, got {i!r}")
        j = int(i) + (len(self) if i < 0 else 0)
        if not 0 <= j < len(self):
            raise IndexError(f"line {i} out of range for {len(self)} lines")
        return j

    # -- what it holds, in a few lines --------------------------------------------------
    def __repr__(self) -> str:
        n = self.n_vertices
        out = [f"<Lines: {len(self)} line{'s' * (len(self) != 1)}, {self.n_points} vertices ({self.points.dtype})"
               + (f", {n.min()}-{n.max()} per line" if len(self) else "")]
        if self.n_points:
            out.append("  bounds: " + "  ".join(f"{a} [{lo:.6g}, {hi:.6g}]"
                                                 for a, (lo, hi) in zip("xyz", self.bounds())))
        units = self.units
        if self.point_data:
            out.append("  per vertex: " + ", ".join(
                f"{k} {v.dtype}" + (f" x{v.shape[1]}" if v.ndim > 1 else "")
                + (f" [{units[k]}]" if k in units else "") for k, v in self.point_data.items()))
        if self.line_data:
            out.append(f"  per line: {', '.join(self.line_data)}")
        for key, title in (("reason", "reasons"), ("reason_backward", "reasons backward")):
            if key in self.line_data and len(self):
                out.append(f"  {title}: " + _reason_counts(self.line_data[key]))
        return "\n".join(out) + ">"

    def _repr_html_(self) -> str:
        import html

        return f"<pre>{html.escape(repr(self))}</pre>"

    # -- to other tools -----------------------------------------------------------------
    def to_pyvista(self):
        """A ``pyvista.PolyData`` of polylines, attributes as point and cell data (needs
        pyvista: ``flowkit.io.pyvista_io``)."""
        from .io.pyvista_io import lines_to_pyvista

        return lines_to_pyvista(self)

    @classmethod
    def from_pyvista(cls, poly) -> Lines:
        """Lines from a ``pyvista.PolyData`` of polylines, e.g. PyVista's ``streamlines()``."""
        from .io.pyvista_io import lines_from_pyvista

        return lines_from_pyvista(poly, cls)

    def to_pandas(self):
        """One row per vertex: ``line`` and ``vertex`` (its index along the line), x, y, z,
        every per-vertex attribute (a k-component one as NAME_0 ... NAME_k-1, a 3-component
        one as NAME_x, NAME_y, NAME_z) and every per-line value repeated on its vertices
        (``reason`` as its name).  Needs pandas."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Lines.to_pandas needs pandas: pip install pandas") from None
        line = self.line_index()
        cols = {"line": line, "vertex": np.arange(self.n_points) - self.offsets[line]}
        cols.update({c: self.points[:, i] for i, c in enumerate("xyz")})
        for k, v in self.point_data.items():
            if v.ndim == 1:
                cols[k] = v
            else:
                names = "xyz" if v.shape[1] == 3 else [str(j) for j in range(v.shape[1])]
                cols.update({f"{k}_{c}": v[:, j] for j, c in enumerate(names)})
        for k, v in self.line_data.items():
            if k in cols:
                continue
            cols[k] = _reason_labels(v[line]) if k.startswith("reason") else v[line]
        return pd.DataFrame(cols)

    def to_xarray(self):
        """The CF contiguous ragged array the lines file holds (dimensions ``obs`` for the
        vertices and ``trajectory`` for the lines, ``rowSize`` the vertex count of each):
        ``to_dataframe`` of its per-vertex variables then gives one row per vertex.
        Needs xarray."""
        try:
            import xarray as xr
        except ImportError:
            raise ImportError("Lines.to_xarray needs xarray: pip install xarray") from None
        units = self.units
        data = {"rowSize": ("trajectory", self.n_vertices, {"sample_dimension": "obs"})}
        data.update({c: ("obs", self.points[:, i]) for i, c in enumerate("xyz")})
        for k, v in self.point_data.items():
            dims = ("obs",) if v.ndim == 1 else ("obs", f"{k}_component")
            data[k] = (dims, v, {"units": units[k]} if k in units else {})
        for k, v in self.line_data.items():
            data[k] = ("trajectory", v)
        attrs = {k: v for k, v in self.attrs.items() if isinstance(v, (str, int, float))}
        return xr.Dataset(data, attrs={**attrs, "featureType": "trajectory"})

    @staticmethod
    def concatenate(parts: list[Lines]) -> Lines:
        """The lines of ``parts`` one after the other (None parts skipped); every part must
        carry the same attributes.  ``attrs`` are the first part's."""
        parts = [p for p in parts if p is not None]
        if not parts:
            return Lines.empty()
        keys_p, keys_l = set(parts[0].point_data), set(parts[0].line_data)
        for p in parts[1:]:
            if set(p.point_data) != keys_p or set(p.line_data) != keys_l:
                raise ValueError(
                    "cannot concatenate Lines with different attributes: the first part has "
                    f"{_names(keys_p)} per vertex and {_names(keys_l)} per line, another "
                    f"{_names(p.point_data)} and {_names(p.line_data)}")
        sizes = np.array([0] + [p.n_points for p in parts])
        offsets = np.concatenate([[0]] + [p.offsets[1:] + s for p, s in zip(parts, np.cumsum(sizes)[:-1])])
        return Lines(
            np.concatenate([p.points for p in parts]),
            offsets,
            {k: np.concatenate([p.point_data[k] for p in parts]) for k in keys_p},
            {k: np.concatenate([p.line_data[k] for p in parts]) for k in keys_l},
            dict(parts[0].attrs),
        )

    def equals(self, other: Lines, rtol: float = 0.0, atol: float = 0.0) -> bool:
        """Same vertices, offsets and attributes (within rtol/atol for floats)."""
        if not np.array_equal(self.offsets, other.offsets):
            return False
        if set(self.point_data) != set(other.point_data) or set(self.line_data) != set(other.line_data):
            return False
        pairs = [(self.points, other.points)]
        pairs += [(v, other.point_data[k]) for k, v in self.point_data.items()]
        pairs += [(v, other.line_data[k]) for k, v in self.line_data.items()]
        return all(a.shape == b.shape and np.allclose(a, b, rtol=rtol, atol=atol, equal_nan=True) for a, b in pairs)

    def bounds(self) -> np.ndarray:
        """(3, 2) [min, max] of the finite vertices."""
        p = self.points[finite_rows(self.points)]
        if p.size == 0:
            return np.zeros((3, 2))
        return np.stack([p.min(axis=0), p.max(axis=0)], axis=1)


def _names(keys) -> str:
    return "[" + ", ".join(sorted(keys)) + "]"


def _reason_codes(reason) -> list[int]:
    from .integrate.reasons import REASON_NAMES, Reason

    out = []
    for r in ([reason] if isinstance(reason, (str, int, np.integer)) else list(reason)):
        if isinstance(r, str):
            if r.lower() not in REASON_NAMES:
                raise ValueError(f"unknown reason '{r}'; reasons: {', '.join(REASON_NAMES)}")
            out.append(REASON_NAMES.index(r.lower()))
        else:
            out.append(int(Reason(int(r))))
    return out


def _reason_labels(codes: np.ndarray) -> np.ndarray:
    from .integrate.reasons import REASON_NAMES

    names = np.array(REASON_NAMES + ["unknown"])
    c = np.asarray(codes, np.int64)
    return names[np.where((c >= 0) & (c < len(REASON_NAMES)), c, len(REASON_NAMES))]


def _reason_counts(codes: np.ndarray) -> str:
    labels, n = np.unique(_reason_labels(codes), return_counts=True)
    order = np.argsort(-n, kind="stable")
    return ", ".join(f"{labels[i]} {n[i]}" for i in order)


def _ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Concatenation of arange(s, s + c) for each (s, c), without a Python loop."""
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    line_of = np.repeat(np.arange(counts.size), counts)
    first = np.cumsum(counts) - counts
    return starts[line_of] + (np.arange(total) - first[line_of])
