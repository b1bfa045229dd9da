"""VTK unstructured grids: ``.vtu`` (e.g. OpenFOAM's foamToVTK) and the ``.vtm`` multiblock files
foamToVTK writes beside them, parsed by the XML reader of ``vtk_xml.py`` (every encoding).

Cells: tetrahedra, pyramids, wedges, hexahedra, voxels and polyhedra (VTK_POLYHEDRON, in the
legacy ``faces``/``faceoffsets`` layout foamToVTK writes, or VTK 9.4's ``face_connectivity``
layout), in any mix; several pieces are joined.

When the nodes lie on a rectilinear lattice and no ``resample`` is asked for, the grid is
rebuilt exactly (``find_lattice``).  Otherwise the data is resampled onto a grid by cell
location (``fields/resample.py``): each grid node is interpolated in the mesh cell that
contains it; nodes in no cell (obstacles, outside) are NaN.  ``resample``: "NX,NY,NZ" or
(nx, ny, nz), "spacing:DX", "auto" (the default when the nodes are no lattice: spacing from
the mesh's fine cells, under a node cap), or a Grid; ``bounds`` restricts the grid's box
(default: the mesh's bounds).  Field.notes states the grid and the method; the mesh is split
(its cells checked) and the nodes located when an array is first read, and the note then gives
how many nodes lie in no cell.

Point data by default.  ``data="cell"``: cell data, each node taking its cell's value (constant
per cell, not averaged to points); on a lattice, the values are placed at the cell centroids.

``.vtm``: ``block`` names the dataset to read (default "internal", foamToVTK's volume mesh; a
path such as "boundary/inlet" or the last part of it); patches are surfaces (.vtp) and
cannot be resampled onto a volume grid, which the error says.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..grid import Grid
from ..mesh import POLYHEDRON, Mesh, legacy_faces
from ..resample import Location, Resampled, auto_grid, parse_resample
from ..stored import Stored
from ._common import ReaderError, existing, foam_units, make_field
from .vtk_xml import _Document


def read_vtu(path, vector="U", data="point", resample=None, shape=None, bounds=None, grid=None,
             rtol=1e-6, periodic=(False, False, False), period=None):
    path = existing(path)
    if data not in ("point", "cell"):
        raise ReaderError(f"{path}: data must be 'point' or 'cell', got {data!r}")
    if shape is not None:  # (the older spelling of resample=(nx, ny, nz))
        resample = tuple(shape)
    if grid is not None:
        resample = grid
    try:
        spec = parse_resample(resample)
    except ValueError as e:
        raise ReaderError(f"{path}: {e}") from None
    mesh, point, cell, time = read_unstructured(path)
    arrays, other = (point, cell) if data == "point" else (cell, point)
    if vector not in arrays and f"{vector}_x" not in arrays:
        kind = "cell" if data == "point" else "point"
        there = (f" (it is {kind} data" + (": pass data='cell', --data cell)" if kind == "cell"
                                           else ")")) if vector in other else ""
        raise ReaderError(f"{path}: no {data} data array '{vector}'{there}; {data} data arrays: "
                          f"{', '.join(arrays) or 'none'}; {kind} data: "
                          f"{', '.join(other) or 'none'}")
    notes = []
    if data == "point" and cell:
        notes.append(f"cell data not loaded (pass data='cell' to use it): {', '.join(cell)}")
    skipped = [n for n, a in arrays.items() if a.ndim > 2 or (a.ndim == 2 and a.shape[1] != 3)]
    arrays = {n: a for n, a in arrays.items() if n not in skipped}
    if skipped:
        notes.append(f"arrays with neither 1 nor 3 components not loaded: {', '.join(skipped)}")
    if spec is None:
        lattice = _lattice(path, mesh, arrays, data, rtol, notes)
        if lattice is not None:
            axes, nodes = lattice
            units, length = foam_units(path, nodes)
            return make_field(path, *axes, nodes, vector, time=time, notes=notes,
                              periodic=periodic, period=period, units=units, length_units=length)
        spec = ("auto", None)
    lo, hi = mesh.points.min(0), mesh.points.max(0)
    if bounds is None and np.any(hi <= lo):
        a = int(np.flatnonzero(hi <= lo)[0])
        raise ReaderError(f"{path}: every point lies at {'xyz'[a]} = {lo[a]:g}: the mesh has "
                          "no volume to resample onto a grid")
    box = np.stack([lo, hi], 1) if bounds is None else np.asarray(bounds, float)
    if box.shape != (3, 2) or np.any(box[:, 1] <= box[:, 0]):
        raise ReaderError(f"{path}: resampling bounds {box.tolist()} must be ((x0, x1), "
                          "(y0, y1), (z0, z1)) with x0 < x1 etc.")
    if isinstance(spec, Grid):
        target, why = spec, "as given"
    else:
        target, why = auto_grid(mesh, box, spec)
    # located when the first array is read (Location): opening costs the XML alone
    where = Location(mesh, target, why, data, str(path))
    nodes = {n: Stored(target.shape + a.shape[1:], a.dtype, Resampled(where, a, data),
                       f"{path}: {n}") for n, a in arrays.items()}
    notes.insert(0, where.note())
    units, length = foam_units(path, nodes)
    g = spec if isinstance(spec, Grid) else None
    field = make_field(path, *target.axes, nodes, vector, time=time, notes=notes, units=units,
                       length_units=length, periodic=periodic if g is None else g.periodic,
                       period=period if g is None else g.period)
    where.notes = field.notes  # (its first note, rewritten with the NaN count once located)
    return field


def _lattice(path, mesh, arrays, data, rtol, notes):
    """(axes, node arrays) when the points (cell centroids for cell data) form a lattice."""
    pts = mesh.points if data == "point" else mesh.centroids()
    found = find_lattice(pts, rtol)
    if isinstance(found, str):
        return None
    axes, ijk = found
    dev = max(float(np.abs(pts[:, a] - axes[a][ijk[:, a]]).max()) for a in range(3))
    dims = tuple(c.size for c in axes)
    nodes = {}
    for n, a in arrays.items():
        out = np.empty(dims + a.shape[1:], a.dtype)
        out[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = a
        nodes[n] = out
    what = "nodes" if data == "point" else "cell centroids"
    notes.insert(0, f"rectilinear lattice rebuilt exactly from {len(pts)} unstructured {what}: "
                    "each maps to one (i, j, k) and every lattice position is filled exactly "
                    f"once (largest node offset from its lattice line {dev:.3g})")
    if data == "cell":
        notes.append("cell data: each value placed at its cell centroid (mean of the cell's "
                     "nodes); not averaged to points")
    return axes, nodes


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


# -- the XML --------------------------------------------------------------------------------
def read_unstructured(path):
    """(Mesh, point arrays, cell arrays, time) of a .vtu file; pieces joined."""
    doc = _Document(path)
    kind = doc.root.get("type")
    if kind != "UnstructuredGrid":
        raise ReaderError(f"{path}: VTK XML type '{kind}' is not UnstructuredGrid")
    pieces = doc.find(doc.root, kind).findall("Piece")
    if not pieces:
        raise ReaderError(f"{path}: no Piece element (truncated or corrupt)")
    parts = [_piece(doc, p) for p in pieces]
    base = np.cumsum([0] + [len(p[0]) for p in parts])
    cbase = np.cumsum([0] + [p[1].size for p in parts])
    points = np.concatenate([p[0] for p in parts])
    conn = np.concatenate([p[1] + b for p, b in zip(parts, base)])
    offsets = np.concatenate([[0]] + [p[2][1:] + cb for p, cb in zip(parts, cbase)])
    types = np.concatenate([p[3] for p in parts])
    faces = foff = None
    if any(p[4] is not None for p in parts):
        fl, fo, at = [], [], 0
        for p, b in zip(parts, base):
            f, o = p[4] if p[4] is not None else (np.zeros(0, np.int64),
                                                  np.full(len(p[3]), -1, np.int64))
            fl.append(_shift_faces(f, o, b))
            fo.append(np.where(o >= 0, o + at, -1))
            at += f.size
        faces, foff = np.concatenate(fl), np.concatenate(fo)
    mesh = Mesh(points, conn, offsets, types, faces, foff)
    point, cell = {}, {}
    for section, store, size in (("PointData", point, [len(p[0]) for p in parts]),
                                 ("CellData", cell, [len(p[3]) for p in parts])):
        names = None
        chunks: dict[str, list] = {}
        for piece, n in zip(pieces, size):
            sec = piece.find(section)
            els = [] if sec is None else sec.findall("DataArray")
            here = [e.get("Name") for e in els]
            if names is None:
                names = here
            for el in els:
                nc = int(el.get("NumberOfComponents", 1))
                a = doc.array(el, n * nc)
                chunks.setdefault(el.get("Name"), []).append(a.reshape(n, nc) if nc > 1 else a)
        for name in names or []:
            if len(chunks.get(name, [])) == len(pieces):
                store[name] = np.concatenate(chunks[name])
    return mesh, point, cell, doc.time_value()


def _piece(doc, piece):
    """(points, connectivity, offsets from 0, types, (faces, faceoffsets) or None) of a piece."""
    path = doc.path
    try:
        npts = int(piece.get("NumberOfPoints"))
        ncells = int(piece.get("NumberOfCells"))
    except (TypeError, ValueError):
        raise ReaderError(f"{path}: Piece without NumberOfPoints / NumberOfCells") from None
    pel = doc.find(doc.find(piece, "Points"), "DataArray")
    points = doc.array(pel, 3 * npts).reshape(npts, 3).astype(np.float64)
    cells = {el.get("Name"): el for el in doc.find(piece, "Cells").findall("DataArray")}
    for need in ("connectivity", "offsets", "types"):
        if need not in cells:
            raise ReaderError(f"{path}: Cells has no '{need}' array (truncated or corrupt?)")
    offsets = np.concatenate([[0], doc.array(cells["offsets"], ncells).astype(np.int64)])
    conn = doc.array(cells["connectivity"], None).astype(np.int64)
    types = doc.array(cells["types"], ncells).astype(np.int64)
    if np.any(np.diff(offsets) < 0) or offsets[-1] != conn.size:
        doc.corrupt("cell offsets do not match the connectivity")
    if conn.size and (conn.min() < 0 or conn.max() >= npts):
        doc.corrupt(f"the connectivity names points outside 0..{npts - 1}")
    faces = None
    if "faces" in cells and "faceoffsets" in cells:
        f = doc.array(cells["faces"], None).astype(np.int64)
        ends = doc.array(cells["faceoffsets"], ncells).astype(np.int64)
        faces = (f, _starts(ends, types))
    elif "face_connectivity" in cells:
        arrays = [doc.array(cells[n], None).astype(np.int64)
                  for n in ("face_connectivity", "face_offsets", "polyhedron_to_faces",
                            "polyhedron_offsets")]
        faces = legacy_faces(*arrays)
    elif np.any(types == POLYHEDRON):
        c = int(np.flatnonzero(types == POLYHEDRON)[0])
        raise ReaderError(f"{path}: cell {c} is a polyhedron but the file has no face arrays")
    return points, conn, offsets, types, faces


def _starts(ends, types):
    """Start of each polyhedron's record in 'faces' from VTK's 'faceoffsets' (the end of each
    cell's record, -1 for other cells)."""
    starts = np.full(ends.size, -1, np.int64)
    poly = np.flatnonzero(ends >= 0)
    prev = np.concatenate([[0], ends[poly][:-1]])
    starts[poly] = prev
    return starts


def _shift_faces(faces, starts, base):
    """Point ids in a legacy faces stream shifted by ``base`` (for joining pieces)."""
    if base == 0 or faces.size == 0:
        return faces
    out = faces.copy()
    is_id = np.zeros(faces.size, bool)
    for s in starts[starts >= 0]:  # (pieces are rare: a plain walk is enough)
        pos = s + 1
        for _ in range(faces[s]):
            k = faces[pos]
            is_id[pos + 1 : pos + 1 + k] = True
            pos += 1 + k
    out[is_id] += base
    return out


# -- .vtm --------------------------------------------------------------------------------------
def read_vtm(path, vector="U", block="internal", **opts):
    """The dataset ``block`` of a VTK multiblock file, read as its own file."""
    return read_vtu(vtm_block(path, block), vector=vector, **opts)


def vtm_block(path, block="internal") -> Path:
    """The .vtu file of the dataset ``block`` of a VTK multiblock file."""
    path = existing(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise ReaderError(f"{path}: VTK file is truncated or corrupt (XML parse error: {e})")
    sets = []

    def walk(el, prefix):
        for child in el:
            name = child.get("name")
            if child.tag == "DataSet" and child.get("file"):
                sets.append(("/".join([*prefix, name or Path(child.get("file")).stem]),
                             child.get("file")))
            elif child.tag in ("Block", "vtkMultiBlockDataSet", "Piece"):
                walk(child, [*prefix, name] if name else prefix)

    walk(root, [])
    if not sets:
        raise ReaderError(f"{path}: the multiblock file lists no datasets")
    hits = [s for s in sets if s[0] == block] or [s for s in sets if s[0].split("/")[-1] == block]
    if len(hits) != 1:
        raise ReaderError(f"{path}: {'no' if not hits else 'more than one'} block {block!r}; "
                          f"blocks: {', '.join(n for n, _ in sets)}")
    name, file = hits[0]
    target = path.parent / file
    if target.suffix.lower() != ".vtu":
        raise ReaderError(f"{path}: block {name!r} is {target.name}, a surface "
                          f"({target.suffix}), not a volume mesh: only .vtu blocks resample onto "
                          "a grid (the internal mesh is 'internal')")
    return target


__all__ = ["find_lattice", "read_unstructured", "read_vtm", "read_vtu", "vtm_block"]
