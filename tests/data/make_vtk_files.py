"""Regenerate the small VTK XML test files in this folder with the real VTK writers.

Run from the repository root:  .venv/bin/python tests/data/make_vtk_files.py
(needs the `vtk` package; the tests read the committed files without it).

Every file holds, on the same small grid, the linear fields the tests check against exactly:
point data U = A @ p + b (Float64, 3 components) and T = c . p + 4 (Float32); cell data rho =
cell-centre x (Float64) and U_cell; FieldData TimeValue = 1.5.
"""

from pathlib import Path

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk

HERE = Path(__file__).parent
A = np.array([[0.3, -1.2, 0.5], [2.0, 0.1, -0.7], [0.4, 0.9, -1.1]])
B = np.array([0.25, -0.5, 1.5])
C = np.array([1.0, -2.0, 3.0])
IMAGE = {"origin": (-1.0, 0.5, 2.0), "spacing": (0.5, 0.25, 0.2), "dims": (4, 3, 5)}
RECT = (
    np.array([0.0, 0.1, 0.35, 0.9]),
    np.array([-1.0, 0.0, 2.0]),
    np.array([0.0, 1.0, 1.5, 2.5, 4.0]),
)

# name -> (data mode, compressor, header type, byte order, encode appended data, pieces)
VARIANTS = {
    "ascii": ("ascii", None, 32, "little", False, 1),
    "binary": ("binary", None, 32, "little", False, 1),
    "binary_zlib_u64": ("binary", "zlib", 64, "little", False, 1),
    "binary_lzma": ("binary", "lzma", 32, "little", False, 1),
    "appended_raw_u64": ("appended", None, 64, "little", False, 1),
    "appended_raw_zlib": ("appended", "zlib", 32, "little", False, 1),
    "appended_b64": ("appended", None, 32, "little", True, 1),
    "appended_b64_zlib_u64": ("appended", "zlib", 64, "little", True, 1),
    "bigendian_zlib": ("appended", "zlib", 64, "big", False, 1),
    "pieces": ("appended", "zlib", 64, "little", False, 3),
}


def add_arrays(ds, points, centres, point=True, cell=True):
    def arr(name, values, dtype):
        a = numpy_to_vtk(np.ascontiguousarray(values, dtype=dtype), deep=True)
        a.SetName(name)
        return a

    if point:
        ds.GetPointData().AddArray(arr("U", points @ A.T + B, np.float64))
        ds.GetPointData().AddArray(arr("T", points @ C + 4.0, np.float32))
    if cell:
        ds.GetCellData().AddArray(arr("rho", centres[:, 0], np.float64))
        ds.GetCellData().AddArray(arr("U_cell" if point else "U", centres @ A.T + B, np.float64))
    tv = arr("TimeValue", [1.5], np.float64)
    ds.GetFieldData().AddArray(tv)


def flat_points(x, y, z):
    """Points in VTK order (x fastest)."""
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)


def image(point=True):
    img = vtk.vtkImageData()
    img.SetDimensions(*IMAGE["dims"])
    img.SetOrigin(*IMAGE["origin"])
    img.SetSpacing(*IMAGE["spacing"])
    axes = [
        o + h * np.arange(n) for o, h, n in zip(IMAGE["origin"], IMAGE["spacing"], IMAGE["dims"])
    ]
    add_arrays(img, flat_points(*axes), flat_points(*(0.5 * (c[1:] + c[:-1]) for c in axes)), point)
    return img


def rect(point=True):
    g = vtk.vtkRectilinearGrid()
    g.SetDimensions(*(c.size for c in RECT))
    g.SetXCoordinates(numpy_to_vtk(RECT[0], deep=True))
    g.SetYCoordinates(numpy_to_vtk(RECT[1], deep=True))
    g.SetZCoordinates(numpy_to_vtk(RECT[2], deep=True))
    add_arrays(g, flat_points(*RECT), flat_points(*(0.5 * (c[1:] + c[:-1]) for c in RECT)), point)
    return g


def write(writer, data, path, mode, comp, header, order, encode, pieces):
    if pieces > 1:
        # only a pipeline source hands the writer real sub-extents: stream through a reader
        tmp = path.with_name("_tmp" + path.suffix)
        write(type(writer)(), data, tmp, "binary", None, 64, "little", False, 1)
        reader = {".vti": vtk.vtkXMLImageDataReader, ".vtr": vtk.vtkXMLRectilinearGridReader}[
            path.suffix
        ]()
        reader.SetFileName(str(tmp))
        writer.SetInputConnection(reader.GetOutputPort())
    else:
        writer.SetInputData(data)
    writer.SetFileName(str(path))
    {
        "ascii": writer.SetDataModeToAscii,
        "binary": writer.SetDataModeToBinary,
        "appended": writer.SetDataModeToAppended,
    }[mode]()
    if comp == "zlib":
        writer.SetCompressorTypeToZLib()
    elif comp == "lzma":
        writer.SetCompressorTypeToLZMA()
    else:
        writer.SetCompressorTypeToNone()
    writer.SetBlockSize(256)  # several compressed blocks even for tiny arrays
    writer.SetHeaderTypeToUInt64() if header == 64 else writer.SetHeaderTypeToUInt32()
    writer.SetByteOrderToBigEndian() if order == "big" else writer.SetByteOrderToLittleEndian()
    writer.SetEncodeAppendedData(encode)
    writer.SetNumberOfPieces(pieces)
    if not writer.Write():
        raise RuntimeError(f"VTK failed to write {path}")
    if pieces > 1:
        tmp.unlink()


def lattice_vtu(path):
    """Hexahedra on a rectilinear lattice with the points stored in shuffled order."""
    x, y, z = RECT
    nx, ny, nz = x.size, y.size, z.size
    pts = flat_points(x, y, z)
    perm = np.random.default_rng(0).permutation(len(pts))
    inv = np.argsort(perm)  # new index of old point
    ug = vtk.vtkUnstructuredGrid()
    p = vtk.vtkPoints()
    p.SetData(numpy_to_vtk(pts[perm], deep=True))
    ug.SetPoints(p)

    def idx(i, j, k):
        return inv[i + nx * (j + ny * k)]

    centres = []
    for k in range(nz - 1):
        for j in range(ny - 1):
            for i in range(nx - 1):
                corners = [
                    idx(i, j, k),
                    idx(i + 1, j, k),
                    idx(i + 1, j + 1, k),
                    idx(i, j + 1, k),
                    idx(i, j, k + 1),
                    idx(i + 1, j, k + 1),
                    idx(i + 1, j + 1, k + 1),
                    idx(i, j + 1, k + 1),
                ]
                ug.InsertNextCell(vtk.VTK_HEXAHEDRON, 8, [int(c) for c in corners])
                centres.append(pts[[int(np.argmax(inv == c)) for c in corners]].mean(0))
    add_arrays(ug, pts[perm], np.array(centres))
    _write_vtu(ug, path)


def scattered_vtu(path):
    """Tetrahedra on scattered points in the unit cube (not a lattice)."""
    rng = np.random.default_rng(1)
    corners = flat_points([0.0, 1.0], [0.0, 1.0], [0.0, 1.0])
    pts = np.vstack([corners, rng.uniform(0, 1, (40, 3))])
    d = vtk.vtkDelaunay3D()
    poly = vtk.vtkPolyData()
    vp = vtk.vtkPoints()
    vp.SetData(numpy_to_vtk(pts, deep=True))
    poly.SetPoints(vp)
    d.SetInputData(poly)
    d.Update()
    ug = d.GetOutput()
    cc = vtk.vtkCellCenters()
    cc.SetInputData(ug)
    cc.Update()
    from vtk.util.numpy_support import vtk_to_numpy

    centres = vtk_to_numpy(cc.GetOutput().GetPoints().GetData())
    add_arrays(ug, pts, centres)
    _write_vtu(ug, path)


def _write_vtu(ug, path):
    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetInputData(ug)
    w.SetFileName(str(path))
    w.SetDataModeToBinary()
    w.SetHeaderTypeToUInt64()
    w.SetCompressorTypeToNone()
    if not w.Write():
        raise RuntimeError(f"VTK failed to write {path}")


def main():
    for name, opts in VARIANTS.items():
        write(vtk.vtkXMLImageDataWriter(), image(), HERE / f"image_{name}.vti", *opts)
        write(vtk.vtkXMLRectilinearGridWriter(), rect(), HERE / f"rect_{name}.vtr", *opts)
    write(
        vtk.vtkXMLImageDataWriter(),
        image(point=False),
        HERE / "image_cellonly.vti",
        "appended",
        "zlib",
        64,
        "little",
        False,
        1,
    )
    lattice_vtu(HERE / "lattice_shuffled.vtu")
    scattered_vtu(HERE / "scattered_tets.vtu")


if __name__ == "__main__":
    main()
