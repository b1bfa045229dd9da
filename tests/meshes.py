"""Small unstructured meshes for the tests, written as VTK XML .vtu files in any encoding.

A mesh is (points, cells): each cell a (VTK type, node list) pair, or for a polyhedron
(42, list of faces, each a node list).  The writer follows the VTK XML format as foamToVTK and
VTK write it (legacy polyhedron layout: 'faces' and 'faceoffsets'), so that the reader is tested
on files it did not write itself.
"""

from __future__ import annotations

import base64
import zlib

import numpy as np

from flowkit.fields.mesh import cube_faces

TET, VOXEL, HEX, WEDGE, PYRAMID, POLY = 10, 11, 12, 13, 14, 42
A = np.array([[0.3, -1.2, 0.5], [2.0, 0.1, -0.7], [0.4, 0.9, -1.1]])
B = np.array([0.25, -0.5, 1.5])
C = np.array([1.0, -2.0, 3.0])
VTK_TYPE = {"f8": "Float64", "f4": "Float32", "i8": "Int64", "i4": "Int32", "u1": "UInt8"}


def linear_u(p):
    return np.asarray(p) @ A.T + B


def linear_t(p):
    return np.asarray(p) @ C + 4.0


def block(n=(4, 4, 4), hole=None, kinds="hex"):
    """Unit cubes on an n lattice of cells (nodes at integer coordinates), each cube as
    ``kinds`` says (a function of its (i, j, k) or a fixed name): "hex", "poly" (the cube as a
    polyhedron, its -x face split into four quads about a new centre node: a split-hex
    polyhedron as snappyHexMesh makes them), "wedges" (two), "pyramids" (six about a new
    centre node), "tets" (five).  ``hole``: (lo, hi) cell index range left out, a cubic
    obstacle."""
    nx, ny, nz = n
    idx = np.arange((nx + 1) * (ny + 1) * (nz + 1)).reshape(nx + 1, ny + 1, nz + 1)
    g = np.stack(np.meshgrid(*(np.arange(m + 1.0) for m in n), indexing="ij"), -1)
    points = list(g.reshape(-1, 3))
    cells = []

    def new_point(p):
        points.append(np.asarray(p, float))
        return len(points) - 1

    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if hole and all(hole[0][a] <= (i, j, k)[a] < hole[1][a] for a in range(3)):
                    continue
                c = [idx[i, j, k], idx[i + 1, j, k], idx[i + 1, j + 1, k], idx[i, j + 1, k],
                     idx[i, j, k + 1], idx[i + 1, j, k + 1], idx[i + 1, j + 1, k + 1],
                     idx[i, j + 1, k + 1]]
                kind = kinds((i, j, k)) if callable(kinds) else kinds
                cells += cube_cells(kind, c, new_point, points)
    return np.array(points), cells


def cube_cells(kind, c, new_point, points):
    if kind == "hex":
        return [(HEX, c)]
    if kind == "wedges":  # split along the diagonal 0-2 / 4-6; VTK wedge order
        return [(WEDGE, [c[0], c[2], c[1], c[4], c[6], c[5]]),
                (WEDGE, [c[0], c[3], c[2], c[4], c[7], c[6]])]
    if kind == "tets":
        return [(TET, t) for t in ([c[0], c[1], c[3], c[4]], [c[1], c[2], c[3], c[6]],
                                   [c[1], c[3], c[4], c[6]], [c[3], c[4], c[6], c[7]],
                                   [c[1], c[4], c[5], c[6]])]
    if kind == "pyramids":  # each face with the centre as apex; faces listed outward
        centre = new_point(np.mean([points[q] for q in c], axis=0))
        return [(PYRAMID, f[::-1] + [centre]) for f in cube_faces(c)]
    if kind == "poly":  # the -x face (3, 0, 4, 7) split about its centre into four quads
        f0 = cube_faces(c)[5]
        mids = [new_point((points[f0[a]] + points[f0[(a + 1) % 4]]) / 2) for a in range(4)]
        fc = new_point(np.mean([points[q] for q in f0], axis=0))
        quads = [[f0[a], mids[a], fc, mids[a - 1]] for a in range(4)]
        # the edge midpoints split the neighbouring faces' edges too
        return [(POLY, [_with_midpoints(f, f0, mids) for f in cube_faces(c)[:5]] + quads)]
    raise ValueError(kind)


def _with_midpoints(face, f0, mids):
    out = []
    for a in range(len(face)):
        p, q = face[a], face[(a + 1) % len(face)]
        out.append(p)
        for b in range(4):
            if {p, q} == {f0[b], f0[(b + 1) % 4]}:
                out.append(mids[b])
    return out


def write_vtu(path, points, cells, point_data=None, cell_data=None, encoding="appended",
              compress=False, header="UInt64", b64=False, pieces=1, layout="legacy"):
    """Write the mesh; ``point_data``/``cell_data``: name -> array (n[, 3]).  ``pieces`` > 1
    splits the cells into pieces, each with its own copy of the points.  ``layout``: the
    polyhedron arrays as foamToVTK writes them ("legacy": faces, faceoffsets) or VTK 9.4
    ("vtk94": face_connectivity, face_offsets, polyhedron_to_faces, polyhedron_offsets)."""
    point_data = point_data if point_data is not None else {
        "U": linear_u(points), "T": linear_t(points).astype(np.float32)}
    cell_data = cell_data or {}
    hdt = np.dtype("<u8" if header == "UInt64" else "<u4")
    appended = []

    def data_array(name, a, ncomp=1):
        a = np.ascontiguousarray(a)
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        vt = VTK_TYPE[a.dtype.str[1:]]
        attrs = f'type="{vt}" Name="{name}" NumberOfComponents="{ncomp}"'
        if encoding == "ascii":
            return (f'<DataArray {attrs} format="ascii">'
                    f'{" ".join(map(repr, a.ravel().tolist()))}</DataArray>')
        raw = a.tobytes()
        if compress:
            bs = 64  # tiny blocks: several per array
            blocks = [zlib.compress(raw[i:i + bs]) for i in range(0, len(raw), bs)] or [b""]
            head = np.array([len(blocks), bs, len(raw) % bs, *map(len, blocks)], hdt).tobytes()
            body = b"".join(blocks)
        else:
            head, body = np.array([len(raw)], hdt).tobytes(), raw
        if encoding == "binary":
            text = (base64.b64encode(head).decode() + base64.b64encode(body).decode()
                    if compress else base64.b64encode(head + body).decode())
            return f'<DataArray {attrs} format="binary">{text}</DataArray>'
        blob = head + body
        if b64:
            blob = (base64.b64encode(head) + base64.b64encode(body) if compress
                    else base64.b64encode(blob))
        offset = sum(len(b) for b in appended)
        appended.append(blob)
        return f'<DataArray {attrs} format="appended" offset="{offset}"/>'

    parts = []
    splits = np.array_split(np.arange(len(cells)), pieces)
    for sel in splits:
        parts.append(f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{len(sel)}">')
        parts.append("<PointData>")
        parts += [data_array(n, a, 1 if np.ndim(a) == 1 else a.shape[1])
                  for n, a in point_data.items()]
        parts.append("</PointData><CellData>")
        parts += [data_array(n, np.asarray(a)[sel], 1 if np.ndim(a) == 1 else np.shape(a)[1])
                  for n, a in cell_data.items()]
        parts.append("</CellData><Points>")
        parts.append(data_array("Points", np.asarray(points, float), 3))
        parts.append("</Points><Cells>")
        parts += _cell_arrays([cells[i] for i in sel], layout, data_array)
        parts.append("</Cells></Piece>")
    comp = ' compressor="vtkZLibDataCompressor"' if compress and encoding != "ascii" else ""
    head = (f'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
            f'byte_order="LittleEndian" header_type="{header}"{comp}>\n<UnstructuredGrid>\n'
            '<FieldData><DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" '
            'format="ascii">2.5</DataArray></FieldData>\n')
    body = (head + "\n".join(parts) + "\n</UnstructuredGrid>\n").encode()
    if appended:
        enc = "base64" if b64 else "raw"
        body += f'<AppendedData encoding="{enc}">\n_'.encode() + b"".join(appended)
        body += b"\n</AppendedData>\n"
    path.write_bytes(body + b"</VTKFile>\n")
    return path


def _cell_arrays(cells, layout, data_array):
    conn, offsets, types, faces, foff = [], [], [], [], []
    fconn, fends, p2f, pends = [], [], [], []
    for t, nodes in cells:
        types.append(t)
        if t == POLY:
            uniq = list(dict.fromkeys(q for f in nodes for q in f))
            conn += uniq
            faces += [len(nodes)] + [x for f in nodes for x in [len(f), *f]]
            foff.append(len(faces))
            for f in nodes:
                fconn += f
                fends.append(len(fconn))
                p2f.append(len(fends) - 1)
        else:
            conn += list(nodes)
            foff.append(-1)
        offsets.append(len(conn))
        pends.append(len(p2f))
    out = [data_array("connectivity", np.array(conn, np.int64)),
           data_array("offsets", np.array(offsets, np.int64)),
           data_array("types", np.array(types, np.uint8))]
    if POLY in types:
        if layout == "legacy":
            out += [data_array("faces", np.array(faces, np.int64)),
                    data_array("faceoffsets", np.array(foff, np.int64))]
        else:
            out += [data_array("face_connectivity", np.array(fconn, np.int64)),
                    data_array("face_offsets", np.array(fends, np.int64)),
                    data_array("polyhedron_to_faces", np.array(p2f, np.int64)),
                    data_array("polyhedron_offsets", np.array(pends, np.int64))]
    return out
