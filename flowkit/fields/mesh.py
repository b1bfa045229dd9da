"""Unstructured volume meshes as a VTK UnstructuredGrid holds them, turned into interpolation
elements for resampling.

Tetrahedra, pyramids, wedges and hexahedra (VTK's node order; voxels reordered to hexahedra) are
elements as they are, each interpolated by its own shape functions (``resample.py``).  A
polyhedron (VTK_POLYHEDRON, faces listed per cell) is split into tetrahedra about its face and
cell centroids, as foamToVTK's ``-poly-decomp`` does: each face edge, the face's centroid and the
cell's centroid make one tetrahedron (a triangular face is one tetrahedron with the cell
centroid).  The centroids are the means of the face's and the cell's nodes, so a value there is
the mean of those nodes' values and a linear field stays exactly linear in every tetrahedron.

Cells are checked as they are split: an inverted or zero-volume cell and a polyhedron whose
faces do not close (an edge used by one face only) are a ``MeshError`` naming the cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..jit import inline, kernel

TET, VOXEL, HEX, WEDGE, PYRAMID, POLYHEDRON = 10, 11, 12, 13, 14, 42
NODES = {TET: 4, PYRAMID: 5, WEDGE: 6, HEX: 8, VOXEL: 8}
NAMES = {TET: "tetrahedron", VOXEL: "voxel", HEX: "hexahedron", WEDGE: "wedge",
         PYRAMID: "pyramid", POLYHEDRON: "polyhedron"}
# orientation of a valid cell in the parametric frame of resample._shape: VTK lists a wedge's
# base so that its normal points away from the top, the other cells towards it
SIGN = {TET: 1.0, PYRAMID: 1.0, WEDGE: -1.0, HEX: 1.0}
# volume of each parametric cell (det J at its centre times this: about the cell's volume)
PARAM_VOLUME = {TET: 1 / 6, PYRAMID: 1 / 3, WEDGE: 1 / 2, HEX: 1.0}
DEGENERATE = 1e-12  # |volume| below this times its longest extent cubed: degenerate


class MeshError(ValueError):
    """A mesh cell that cannot be interpolated in; the message names the cell and the problem."""


@dataclass
class Mesh:
    """A VTK UnstructuredGrid: ``points`` (n, 3); cell c's nodes are
    ``connectivity[offsets[c]:offsets[c + 1]]`` (``offsets`` starts with 0), its VTK type
    ``types[c]``; a polyhedron's faces are ``faces[faceoffsets[c] ...]`` in VTK's legacy layout
    (number of faces, then per face its node count and nodes)."""

    points: np.ndarray
    connectivity: np.ndarray
    offsets: np.ndarray
    types: np.ndarray
    faces: np.ndarray | None = None
    faceoffsets: np.ndarray | None = None

    @property
    def n_cells(self) -> int:
        return int(self.types.size)

    def counts(self) -> dict[str, int]:
        """Cells by kind name, in VTK type order."""
        kinds, n = np.unique(self.types, return_counts=True)
        return {NAMES.get(int(k), f"VTK type {int(k)}"): int(c) for k, c in zip(kinds, n)}

    def cell_sizes(self) -> np.ndarray:
        """Each cell's size: the cube root of its nodes' bounding-box volume (a polyhedron's
        nodes are its faces' nodes: the box of the tetrahedra it is split into), from the
        points alone, without splitting anything."""
        p = self.points[self.connectivity]
        if not p.size:
            return np.zeros(self.n_cells)
        starts = np.minimum(self.offsets[:-1], len(p) - 1)  # (an empty cell: size 0)
        ext = np.maximum.reduceat(p, starts) - np.minimum.reduceat(p, starts)
        ext[np.diff(self.offsets) == 0] = 0.0
        return np.cbrt(np.prod(np.maximum(ext, 0.0), axis=1))

    def centroids(self) -> np.ndarray:
        """The mean of each cell's nodes (n_cells, 3)."""
        sums = np.add.reduceat(self.points[self.connectivity], self.offsets[:-1], axis=0)
        return sums / np.diff(self.offsets)[:, None]


@dataclass
class Elements:
    """What the resampling kernels interpolate in.  ``conn[e, :NODES[kind[e]]]`` are element
    e's nodes (padded with its first node), indices into ``points``: the mesh's points followed
    by the centroids the polyhedra were split about; centroid k is the mean of the mesh points
    ``members[ptr[k]:ptr[k + 1]]``.  ``cell[e]`` is the mesh cell element e belongs to
    (elements of a cell are consecutive, cells in order).  ``lo``, ``hi``: each element's
    bounding box; ``affine``: whether its map is affine (every tetrahedron; a hexahedron whose
    trilinear cross terms vanish, a parallelepiped as a snappyHexMesh background is made of; a
    wedge whose top is its base moved; to 1e-12 of its size): then one solve inverts it."""

    points: np.ndarray
    conn: np.ndarray
    kind: np.ndarray
    cell: np.ndarray
    ptr: np.ndarray
    members: np.ndarray
    n_tets: int  # tetrahedra the polyhedra were split into
    lo: np.ndarray
    hi: np.ndarray
    affine: np.ndarray

    def extend(self, values: np.ndarray) -> np.ndarray:
        """Point values (n_mesh_points, ...) with the centroids' values appended (float64)."""
        v = np.asarray(values, dtype=np.float64)
        if self.ptr.size <= 1:
            return v
        sums = np.add.reduceat(v[self.members], self.ptr[:-1], axis=0)
        shape = (-1,) + (1,) * (v.ndim - 1)
        return np.concatenate([v, sums / np.diff(self.ptr).reshape(shape)])


def elements(mesh: Mesh) -> Elements:
    """Split ``mesh`` into interpolation elements, checking every cell (MeshError)."""
    types = mesh.types.astype(np.int64)
    known = np.isin(types, [*NODES, POLYHEDRON])
    if not known.all():
        c = int(np.flatnonzero(~known)[0])
        raise MeshError(f"cell {c}: VTK cell type {types[c]} is not a volume cell flowkit "
                        "interpolates in (tetrahedron, pyramid, wedge, hexahedron, voxel, "
                        "polyhedron)")
    size = np.diff(mesh.offsets)
    fixed = types != POLYHEDRON
    want = np.zeros(256, np.int64)
    want[list(NODES)] = list(NODES.values())
    want = want[types[fixed]]
    if np.any(size[fixed] != want):
        c = int(np.flatnonzero(fixed)[np.flatnonzero(size[fixed] != want)[0]])
        raise MeshError(f"cell {c} ({NAMES[int(types[c])]}) has {size[c]} nodes, expected "
                        f"{NODES[int(types[c])]}")
    poly = np.flatnonzero(~fixed)
    if poly.size and (mesh.faces is None or mesh.faceoffsets is None):
        raise MeshError(f"cell {int(poly[0])} (polyhedron) has no faces: the file lacks the "
                        "'faces' and 'faceoffsets' arrays")
    faces = mesh.faces if poly.size else np.zeros(1, np.int64)
    foff = mesh.faceoffsets if poly.size else np.zeros(1, np.int64)
    # per cell: elements it makes and centroids it adds; a polyhedron's are counted by walking
    # its faces (and its faces checked on the way)
    n_el = np.where(fixed, 1, 0).astype(np.int64)
    n_ctr = np.zeros(types.size, np.int64)
    n_mem = np.zeros(types.size, np.int64)
    bad = np.full(2, -1, np.int64)  # (cell, problem code)
    _count_poly(poly, faces.astype(np.int64), foff.astype(np.int64), mesh.connectivity,
                mesh.offsets, n_el, n_ctr, n_mem, bad)
    if bad[0] >= 0:
        raise MeshError(f"cell {bad[0]} (polyhedron): {POLY_PROBLEMS[bad[1]]}")
    el_start = np.concatenate([[0], np.cumsum(n_el)])
    ctr_start = np.concatenate([[0], np.cumsum(n_ctr)])
    mem_start = np.concatenate([[0], np.cumsum(n_mem)])
    m = int(el_start[-1])
    conn = np.empty((m, 8), np.int64)
    kind = np.empty(m, np.int8)
    cell = np.repeat(np.arange(types.size, dtype=np.int64), n_el)
    n_pts = mesh.points.shape[0]
    ptr = np.empty(int(ctr_start[-1]) + 1, np.int64)
    members = np.empty(int(mem_start[-1]), np.int64)
    ptr[-1] = members.size
    _fill(types, mesh.connectivity, mesh.offsets, faces.astype(np.int64), foff.astype(np.int64),
          el_start, ctr_start, mem_start, n_pts, conn, kind, ptr, members)
    pts = mesh.points
    if ptr.size > 1:
        sums = np.add.reduceat(pts[members], ptr[:-1], axis=0)
        pts = np.concatenate([pts, sums / np.diff(ptr)[:, None]])
    pts = np.ascontiguousarray(pts, np.float64)
    det = np.empty(m)
    lo, hi = np.empty((m, 3)), np.empty((m, 3))
    lin = np.zeros(m, np.int8)
    _geometry(conn, kind, pts, det, lo, hi, lin)
    el = Elements(pts, conn, kind, cell, ptr, members, int(n_el[~fixed].sum()), lo, hi,
                  lin.view(np.bool_))
    _check_volumes(el, types, det)
    return el


def legacy_faces(face_conn, face_ends, poly_faces, poly_ends):
    """VTK 9.4's polyhedron layout (faces as their own cells, each polyhedron a list of faces)
    -> (the legacy 'faces' stream, each cell's start in it or -1)."""
    fstart = np.concatenate([[0], face_ends[:-1]])
    pstart = np.concatenate([[0], poly_ends[:-1]])
    nf = poly_ends - pstart
    rec = np.concatenate([[0], np.cumsum(1 + face_ends[poly_faces] - fstart[poly_faces])])
    length = np.where(nf > 0, 1 + rec[poly_ends] - rec[pstart], 0)
    starts = np.concatenate([[0], np.cumsum(length)[:-1]])
    out = np.empty(int(length.sum()), np.int64)
    _legacy_fill(face_conn, fstart, face_ends, poly_faces, pstart, poly_ends, starts, out)
    return out, np.where(nf > 0, starts, -1)


def cube_faces(c) -> list[list[int]]:
    """The six faces of the hexahedron with VTK-ordered nodes ``c``, each listed outward."""
    return [[c[0], c[3], c[2], c[1]], [c[4], c[5], c[6], c[7]], [c[0], c[1], c[5], c[4]],
            [c[1], c[2], c[6], c[5]], [c[2], c[3], c[7], c[6]], [c[3], c[0], c[4], c[7]]]


POLY_PROBLEMS = {
    0: "its faces do not close (an edge belongs to one face only): open faces",
    1: "a face has fewer than 3 nodes",
    2: "its face list runs past the end of the 'faces' array",
    3: "no faces listed (faceoffsets is -1)",
}


def _check_volumes(el: Elements, types: np.ndarray, det: np.ndarray) -> None:
    """Inverted (wrong orientation) or zero-volume cells are errors (``det``: det J at each
    element's parametric centre).  A polyhedron's volume is the sum of its tetrahedra's; only
    its size is checked (faces may be listed either way round)."""
    box = np.max(el.hi - el.lo, axis=1) ** 3
    scale = np.full(el.kind.size, 1.0 / 6.0)  # a polyhedron's tetrahedra: either orientation
    fixed = types[el.cell] != POLYHEDRON
    for k, s in SIGN.items():
        scale[fixed & (el.kind == k)] = s * PARAM_VOLUME[k]
    vol = det * scale  # positive for a valid fixed cell
    starts = np.flatnonzero(np.concatenate([[True], el.cell[1:] != el.cell[:-1]]))
    size = np.add.reduceat(np.abs(vol), starts)
    cells = el.cell[starts]
    degenerate = size <= DEGENERATE * np.maximum.reduceat(box, starts)
    inverted = ~degenerate & (types[cells] != POLYHEDRON) & (vol[starts] <= 0)
    for what, mask in (("degenerate (zero volume)", degenerate),
                       ("inverted (its nodes in the wrong order: negative volume)", inverted)):
        if mask.any():
            c = int(cells[np.flatnonzero(mask)[0]])
            raise MeshError(f"cell {c} ({NAMES[int(types[c])]}) is {what}")


# -- shape functions ----------------------------------------------------------------------------
@inline
def shape(kind, i, r, s, t):
    """(N_i, dN_i/dr, dN_i/ds, dN_i/dt) at parametric (r, s, t) for node i of a VTK cell: the
    hexahedron's unit cube, the pyramid as VTK's (the cube with its top collapsed to the apex),
    the wedge's triangle times [0, 1], the tetrahedron's barycentric coordinates.  Each sums to
    one, so a field linear in space is reproduced exactly in every cell."""
    if kind == 12 or (kind == 14 and i < 4):
        q = i & 3
        fr, dr = (r, 1.0) if (q == 1 or q == 2) else (1.0 - r, -1.0)
        fs, ds = (s, 1.0) if q >= 2 else (1.0 - s, -1.0)
        if kind == 12 and i >= 4:
            ft, dt = t, 1.0
        else:
            ft, dt = 1.0 - t, -1.0
        return fr * fs * ft, dr * fs * ft, fr * ds * ft, fr * fs * dt
    if kind == 14:
        return t, 0.0, 0.0, 1.0
    if kind == 13:
        ft, dt = (t, 1.0) if i >= 3 else (1.0 - t, -1.0)
        q = i % 3
        if q == 0:
            return (1.0 - r - s) * ft, -ft, -ft, (1.0 - r - s) * dt
        if q == 1:
            return r * ft, ft, 0.0, r * dt
        return s * ft, 0.0, ft, s * dt
    if i == 0:
        return 1.0 - r - s - t, -1.0, -1.0, -1.0
    if i == 1:
        return r, 1.0, 0.0, 0.0
    if i == 2:
        return s, 0.0, 1.0, 0.0
    return t, 0.0, 0.0, 1.0


@inline
def n_nodes(k):
    return 4 if k == 10 else (5 if k == 14 else (6 if k == 13 else 8))


@inline
def centre(k):
    """(r, s, t) of a cell's parametric centroid."""
    if k == 10:
        return 0.25, 0.25, 0.25
    if k == 13:
        return 1.0 / 3.0, 1.0 / 3.0, 0.5
    return 0.5, 0.5, (0.2 if k == 14 else 0.5)


@inline
def map_point(k, e, conn, pts, r, s, t):
    """The point (x, y, z) at (r, s, t) of element e (kind k) and the Jacobian
    d(x, y, z)/d(r, s, t) there, row by row."""
    x = y = z = 0.0
    j00 = j01 = j02 = j10 = j11 = j12 = j20 = j21 = j22 = 0.0
    for i in range(n_nodes(k)):
        n, dr, ds, dt = shape(k, i, r, s, t)
        p = conn[e, i]
        px, py, pz = pts[p, 0], pts[p, 1], pts[p, 2]
        x += n * px
        y += n * py
        z += n * pz
        j00 += dr * px
        j01 += ds * px
        j02 += dt * px
        j10 += dr * py
        j11 += ds * py
        j12 += dt * py
        j20 += dr * pz
        j21 += ds * pz
        j22 += dt * pz
    return x, y, z, j00, j01, j02, j10, j11, j12, j20, j21, j22


# -- compiled: polyhedra walked face by face; volumes ------------------------------------------
@kernel()
def _count_poly(poly, faces, foff, connectivity, offsets, n_el, n_ctr, n_mem, bad):
    """Per polyhedron: tetrahedra (one per face edge, one per triangular face), centroids (the
    cell's and one per non-triangular face) and their member counts; checks that every edge
    is shared by two faces (bad = (cell, code) of the first failure)."""
    for c in poly:
        at = foff[c]
        if at < 0:
            bad[0], bad[1] = c, 3
            return
        nf = faces[at]
        pos = at + 1
        tets, ctr, mem = 0, 1, offsets[c + 1] - offsets[c]
        for _ in range(nf):
            if pos >= faces.size or pos + faces[pos] >= faces.size:
                bad[0], bad[1] = c, 2
                return
            k = faces[pos]
            if k < 3:
                bad[0], bad[1] = c, 1
                return
            if k == 3:
                tets += 1
            else:
                tets += k
                ctr += 1
                mem += k
            pos += 1 + k
        # every directed edge a->b must meet its edge in another face (b->a, or a->b when
        # neighbouring faces are listed the other way round): count each edge's uses
        p = at + 1
        for f in range(nf):
            k = faces[p]
            for i in range(k):
                a, b = faces[p + 1 + i], faces[p + 1 + (i + 1) % k]
                uses = 0
                q = at + 1
                for g in range(nf):
                    kk = faces[q]
                    if g != f:
                        for j in range(kk):
                            u, v = faces[q + 1 + j], faces[q + 1 + (j + 1) % kk]
                            if (u == a and v == b) or (u == b and v == a):
                                uses += 1
                    q += 1 + kk
                if uses != 1:
                    bad[0], bad[1] = c, 0
                    return
            p += 1 + k
        n_el[c] = tets
        n_ctr[c] = ctr
        n_mem[c] = mem


@kernel()
def _legacy_fill(face_conn, fstart, fend, poly_faces, pstart, pend, starts, out):
    for c in range(pstart.size):
        if pend[c] == pstart[c]:
            continue
        pos = starts[c]
        out[pos] = pend[c] - pstart[c]
        pos += 1
        for q in range(pstart[c], pend[c]):
            f = poly_faces[q]
            out[pos] = fend[f] - fstart[f]
            pos += 1
            for i in range(fstart[f], fend[f]):
                out[pos] = face_conn[i]
                pos += 1


@kernel()
def _fill(types, connectivity, offsets, faces, foff, el_start, ctr_start, mem_start, n_pts, conn,
          kind, ptr, members):
    """The elements of every cell, in cell order, and the centroids' member lists."""
    n = types.size
    for c in range(n):
        e = el_start[c]
        o0, o1 = offsets[c], offsets[c + 1]
        t = types[c]
        if t != 42:
            if t == 11:  # voxel: x-fastest corners, reordered to a hexahedron's
                for i in range(8):
                    conn[e, i] = connectivity[o0 + (0, 1, 3, 2, 4, 5, 7, 6)[i]]
                kind[e] = 12
            else:
                for i in range(8):
                    conn[e, i] = connectivity[o0 + (i if i < o1 - o0 else 0)]
                kind[e] = t
            continue
        g = ctr_start[c]
        m = mem_start[c]
        cc = n_pts + g  # the cell centroid: the mean of the cell's unique nodes
        ptr[g] = m
        for i in range(o0, o1):
            members[m] = connectivity[i]
            m += 1
        g += 1
        at = foff[c]
        nf = faces[at]
        pos = at + 1
        for _ in range(nf):
            k = faces[pos]
            if k == 3:
                conn[e, 0] = cc
                for i in range(3):
                    conn[e, 1 + i] = faces[pos + 1 + i]
                for i in range(4, 8):
                    conn[e, i] = cc
                kind[e] = 10
                e += 1
            else:
                fc = n_pts + g
                ptr[g] = m
                for i in range(k):
                    members[m] = faces[pos + 1 + i]
                    m += 1
                g += 1
                for i in range(k):
                    conn[e, 0] = cc
                    conn[e, 1] = fc
                    conn[e, 2] = faces[pos + 1 + i]
                    conn[e, 3] = faces[pos + 1 + (i + 1) % k]
                    for j in range(4, 8):
                        conn[e, j] = cc
                    kind[e] = 10
                    e += 1
            pos += 1 + k


@kernel()
def _geometry(conn, kind, pts, det, lo, hi, lin):
    """Per element: det J at its parametric centre (a tetrahedron's: six times its signed
    volume), its bounding box, and whether its map is affine."""
    for e in range(kind.size):
        k = kind[e]
        r, s, t = centre(k)
        _, _, _, j00, j01, j02, j10, j11, j12, j20, j21, j22 = map_point(k, e, conn, pts, r, s, t)
        det[e] = (j00 * (j11 * j22 - j12 * j21) - j01 * (j10 * j22 - j12 * j20)
                  + j02 * (j10 * j21 - j11 * j20))
        size = 0.0
        for a in range(3):
            lo[e, a], hi[e, a] = np.inf, -np.inf
            for i in range(n_nodes(k)):
                lo[e, a] = min(lo[e, a], pts[conn[e, i], a])
                hi[e, a] = max(hi[e, a], pts[conn[e, i], a])
            size = max(size, hi[e, a] - lo[e, a])
        if k == 10:
            lin[e] = 1
        elif k == 12 or k == 13:
            flat = True
            for a in range(3):
                p0, p1, p2, p3 = (pts[conn[e, 0], a], pts[conn[e, 1], a], pts[conn[e, 2], a],
                                  pts[conn[e, 3], a])
                if k == 13:  # the top (3, 4, 5) is the base (0, 1, 2) moved by one vector
                    p4, p5 = pts[conn[e, 4], a], pts[conn[e, 5], a]
                    terms = (p3 - p0 - p4 + p1, p3 - p0 - p5 + p2, 0.0, 0.0)
                else:  # the trilinear map's cross terms
                    p4, p5, p6, p7 = (pts[conn[e, 4], a], pts[conn[e, 5], a],
                                      pts[conn[e, 6], a], pts[conn[e, 7], a])
                    terms = (p0 - p1 + p2 - p3, p4 - p5 + p6 - p7, p0 - p1 - p4 + p5,
                             p0 - p3 - p4 + p7)
                for v in terms:
                    if abs(v) > 1e-12 * size:
                        flat = False
            lin[e] = 1 if flat else 0
