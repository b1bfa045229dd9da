"""VTK unstructured grids (.vtu, e.g. from OpenFOAM's foamToVTK) through meshio (the ``io`` extra).

When the nodes lie on a rectilinear lattice the grid is rebuilt exactly (``find_lattice``).
Otherwise, or when ``shape=`` / ``grid=`` is given, the arrays are resampled onto a grid by
piecewise-linear interpolation on a Delaunay triangulation of the nodes (scipy
LinearNDInterpolator), NaN outside the nodes' convex hull; Field.notes states it.

Point data by default; ``data="cell"`` uses cell data placed at the cell centroids (the mean of
each cell's nodes), which on a hexahedral lattice form the lattice of cell centres.
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from ._common import ReaderError, existing, foam_units, make_field


def read_vtu(
    path,
    vector="U",
    data="point",
    shape=None,
    bounds=None,
    grid=None,
    rtol=1e-6,
    periodic=(False, False, False),
    period=None,
):
    path = existing(path)
    try:
        import meshio.vtu
    except ImportError:
        raise ReaderError(
            f"{path}: reading .vtu files needs meshio, in the 'io' extra: pip install 'flowkit[io]'"
        ) from None
    if data not in ("point", "cell"):
        raise ReaderError(f"{path}: data must be 'point' or 'cell', got {data!r}")
    try:
        mesh = meshio.vtu.read(path)  # meshio.read would sys.exit() on a damaged file
    except Exception as e:  # noqa: BLE001 - meshio raises assorted types on damaged files
        raise ReaderError(
            f"{path}: VTK file is truncated or corrupt ({type(e).__name__}: {e})"
        ) from None
    point = dict(mesh.point_data)
    cell = {
        n: np.concatenate([np.asarray(b) for b in blocks]) for n, blocks in mesh.cell_data.items()
    }
    arrays, other = (point, cell) if data == "point" else (cell, point)
    if vector not in arrays and vector in other:
        raise ReaderError(
            f"{path}: array '{vector}' is {'cell' if data == 'point' else 'point'} data, "
            f"not {data} data; {data} data arrays: {', '.join(arrays) or 'none'}"
            + (
                ". Pass data='cell' to use cell data (values at cell centroids)"
                if data == "point"
                else ""
            )
        )
    notes = []
    if data == "point":
        pts = np.asarray(mesh.points, dtype=np.float64)
        if cell:
            notes.append(f"cell data not loaded (pass data='cell' to use it): {', '.join(cell)}")
    else:
        pts = np.concatenate(
            [mesh.points[b.data].astype(np.float64).mean(axis=1) for b in mesh.cells]
        )
        notes.append(
            "cell data: each value placed at its cell centroid (mean of the cell's nodes); "
            "not averaged to points"
        )
    arrays = {
        n: a.reshape(a.shape[0], -1).squeeze(-1) if a.ndim == 2 and a.shape[1] == 1 else a
        for n, a in arrays.items()
    }
    skipped = [n for n, a in arrays.items() if a.ndim > 2 or (a.ndim == 2 and a.shape[1] != 3)]
    arrays = {n: a for n, a in arrays.items() if n not in skipped}
    if skipped:
        notes.append(f"arrays with neither 1 nor 3 components not loaded: {', '.join(skipped)}")
    tv = mesh.field_data.get("TimeValue")
    time = None if tv is None else float(np.asarray(tv).ravel()[0])
    if grid is None and shape is None:
        found = find_lattice(pts, rtol)
        if isinstance(found, str):
            raise ReaderError(
                f"{path}: the {len(pts)} {'nodes' if data == 'point' else 'cell centroids'} "
                f"do not lie on a rectilinear lattice ({found}); pass shape=(nx, ny, nz) "
                "and optionally bounds=((x0, x1), (y0, y1), (z0, z1)) to resample"
            )
        axes, ijk = found
        dev = max(float(np.abs(pts[:, a] - axes[a][ijk[:, a]]).max()) for a in range(3))
        dims = tuple(c.size for c in axes)
        nodes = {}
        for n, a in arrays.items():
            out = np.empty(dims + a.shape[1:], a.dtype)
            out[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = a
            nodes[n] = out
        notes.insert(
            0,
            f"rectilinear lattice rebuilt exactly from {len(pts)} unstructured "
            f"{'nodes' if data == 'point' else 'cell centroids'}: each maps to one "
            f"(i, j, k) and every lattice position is filled exactly once "
            f"(largest node offset from its lattice line {dev:.3g})",
        )
        units, length = foam_units(path, nodes)
        return make_field(
            path, *axes, nodes, vector, time=time, notes=notes, periodic=periodic, period=period,
            units=units, length_units=length,
        )
    target = grid if grid is not None else _grid(path, pts, shape, bounds)
    nodes, note = resample(pts, arrays, target)
    notes.insert(0, note)
    units, length = foam_units(path, nodes)
    return make_field(
        path,
        *target.axes,
        nodes,
        vector,
        time=time,
        notes=notes,
        units=units,
        length_units=length,
        periodic=periodic if grid is None else grid.periodic,
        period=period if grid is None else grid.period,
    )


def find_lattice(points, rtol=1e-6):
    """(axes, ijk) when the points are exactly the nodes of a rectilinear lattice, else the reason.

    Per axis, coordinates closer than ``rtol`` times the axis extent are one lattice line (at the
    smallest of them).  The points form a lattice when the product of the line
    counts equals the number of points and every (i, j, k) position is hit exactly once.
    """
    points = np.asarray(points, dtype=np.float64)
    axes, ijk = [], np.empty(points.shape, np.int64)
    for a in range(3):
        c = points[:, a]
        order = np.argsort(c, kind="stable")
        s = c[order]
        tol = rtol * max(s[-1] - s[0], np.abs(s).max(), 1e-300)
        new = np.concatenate([[True], np.diff(s) > tol])
        line = np.cumsum(new) - 1
        ijk[order, a] = line
        axes.append(s[new])  # the smallest of each line's coordinates: exact when they agree
    dims = tuple(c.size for c in axes)
    if int(np.prod(dims)) != len(points):
        n = int(np.prod(dims))
        return f"{dims[0]} x {dims[1]} x {dims[2]} distinct coordinates would need {n} positions"
    flat = np.ravel_multi_index(ijk.T, dims)
    hits = np.bincount(flat, minlength=len(points))
    if np.any(hits != 1):
        k = int(np.flatnonzero(hits != 1)[0])
        return f"lattice position {np.unravel_index(k, dims)} holds {hits[k]} points"
    return axes, ijk


def _grid(path, pts, shape, bounds) -> Grid:
    shape = tuple(int(n) for n in shape)
    if len(shape) != 3 or min(shape) < 2:
        raise ReaderError(f"{path}: resampling shape {shape} must be 3 integers >= 2")
    b = np.stack([pts.min(0), pts.max(0)], axis=1) if bounds is None else np.asarray(bounds, float)
    if b.shape != (3, 2) or np.any(b[:, 1] <= b[:, 0]):
        raise ReaderError(
            f"{path}: resampling bounds {b.tolist()} must be ((x0, x1), (y0, y1), (z0, z1)) "
            "with x0 < x1 etc."
        )
    return Grid.regular(b[:, 0], (b[:, 1] - b[:, 0]) / (np.array(shape) - 1), shape)


def resample(points, arrays: dict, grid: Grid):
    """Arrays on scattered points -> node arrays on ``grid`` (linear on Delaunay tetrahedra)."""
    from scipy.interpolate import LinearNDInterpolator
    from scipy.spatial import Delaunay

    tri = Delaunay(points)
    q = grid.node_points().reshape(-1, 3)
    out = {}
    for n, a in arrays.items():
        v = LinearNDInterpolator(tri, a.astype(np.float64), fill_value=np.nan)(q)
        out[n] = v.reshape(grid.shape + a.shape[1:])
    outside = (
        int(np.isnan(next(iter(out.values()))).reshape(q.shape[0], -1).any(1).sum()) if out else 0
    )
    note = (
        f"resampled from {len(points)} unstructured points onto a {grid.kind} grid of shape "
        f"{grid.shape} by linear interpolation on their Delaunay tetrahedralisation "
        f"(scipy LinearNDInterpolator); NaN outside their convex hull ({outside} grid nodes)"
    )
    return out, note
