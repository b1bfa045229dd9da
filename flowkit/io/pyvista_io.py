"""Bridges to PyVista (VTK data in numpy form), an optional extra: ``pip install pyvista``.

- ``field_from_pyvista(grid)``: a Field from a ``pyvista.ImageData`` (axis-aligned) or
  ``pyvista.RectilinearGrid`` with point data (``flowkit.fields.from_pyvista``).  VTK orders
  points x fastest; flowkit's arrays are indexed [i, j, k], so each array is reordered once.
- ``lines_to_pyvista(lines)``: a ``pyvista.PolyData`` of polylines with the per-vertex
  attributes as point data and the per-line data as cell data (``Lines.to_pyvista``).
- ``lines_from_pyvista(poly, cls)``: Lines (``cls``) from a PolyData of polylines, e.g. what
  PyVista's own ``streamlines()`` returns, so the two can be compared (``Lines.from_pyvista``).

Lines' methods call this module, so it takes their class from them rather than importing it.
"""

from __future__ import annotations

import numpy as np

from ..fields.field import Field
from ..fields.grid import Grid


def _pyvista():
    try:
        import pyvista
    except ImportError:
        raise ImportError("the PyVista bridge needs pyvista: pip install 'flowkit[pyvista]'"
                          ) from None
    return pyvista


def field_from_pyvista(grid, vector: str | None = None, source: str = "<pyvista>") -> Field:
    """A Field from a ``pyvista.ImageData`` or ``pyvista.RectilinearGrid``: ``vector`` names
    its 3-component point array (default: the active vectors, else the only one), every
    1-component point array becomes a scalar."""
    pv = _pyvista()
    kind = type(grid).__name__
    if isinstance(grid, pv.ImageData):
        if not np.allclose(np.asarray(grid.direction_matrix), np.eye(3)):
            raise ValueError(f"{source}: an ImageData with a rotated direction matrix; flowkit "
                             "grids are axis-aligned (resample it onto an axis-aligned one)")
        g = Grid.regular(grid.origin, grid.spacing, grid.dimensions)
    elif isinstance(grid, pv.RectilinearGrid):
        g = Grid.from_axes(grid.x, grid.y, grid.z, where=source)
    else:
        raise TypeError(f"{source}: a pyvista.{kind}; flowkit reads ImageData and "
                        "RectilinearGrid (resample other grids onto one, e.g. with "
                        "pyvista.ImageData(...).sample(mesh))")
    shape = g.shape
    names = grid.point_data.keys()  # (pyvista's attributes: a mapping with keys())
    arrays = {n: np.asarray(grid.point_data[n]) for n in names}
    vectors = [n for n, a in arrays.items() if a.ndim == 2 and a.shape[1] == 3]
    if vector is None:
        active = grid.active_vectors_name
        vector = active if active in vectors else (vectors[0] if len(vectors) == 1 else None)
    if vector not in vectors:
        cells = list(grid.cell_data.keys())
        hint = (f"; cell data ({', '.join(cells)}): grid.cell_data_to_point_data() first"
                if cells else "")
        raise ValueError(f"{source}: pyvista.{kind} has no 3-component point array "
                         f"{vector!r} to trace (vectors: {', '.join(vectors) or 'none'}){hint}")

    def nodes(a):  # VTK's x-fastest order -> [i, j, k(, c)]
        a = a.reshape((*shape[::-1], *a.shape[1:]))
        return np.ascontiguousarray(a.transpose(2, 1, 0, *range(3, a.ndim)))

    scalars = {n: nodes(a) for n, a in arrays.items() if a.ndim == 1}
    return Field(g, nodes(arrays[vector]), scalars, vector_name=vector, source=source)


def lines_to_pyvista(lines):
    """A ``pyvista.PolyData``: one polyline per line, attributes as point and cell data."""
    pv = _pyvista()
    n = lines.n_vertices
    cells = np.empty(len(lines) + lines.n_points, np.int64)
    starts = lines.offsets[:-1] + np.arange(len(lines))
    cells[starts] = n
    mask = np.ones(cells.size, bool)
    mask[starts] = False
    cells[mask] = np.arange(lines.n_points)
    poly = pv.PolyData(np.asarray(lines.points, np.float64), lines=cells)
    for k, v in lines.point_data.items():
        poly.point_data[k] = v
    for k, v in lines.line_data.items():
        poly.cell_data[k] = v
    return poly


def lines_from_pyvista(poly, cls):
    """Lines (``cls``) from a PolyData of polylines (its points reordered line by line, as the
    lines' connectivity visits them); point data and cell data come along."""
    _pyvista()
    cells = np.asarray(poly.lines, np.int64)
    counts, ids, i = [], [], 0
    while i < cells.size:  # [n, id0 .. id(n-1), n, ...]
        k = int(cells[i])
        counts.append(k)
        ids.append(cells[i + 1:i + 1 + k])
        i += 1 + k
    order = np.concatenate(ids) if ids else np.zeros(0, np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts, dtype=np.int64)])
    pts = np.asarray(poly.points, np.float64)[order]
    pnames, cnames = poly.point_data.keys(), poly.cell_data.keys()
    pdata = {k: np.asarray(poly.point_data[k])[order] for k in pnames if not k.startswith("vtk")}
    ldata = {k: np.asarray(poly.cell_data[k]) for k in cnames
             if len(poly.cell_data[k]) == len(counts)}
    return cls(pts, offsets, pdata, ldata, {"source": "pyvista"})
