"""Write a Field as .npz, flowkit HDF5 (.h5), VTK XML ImageData (.vti) or RectilinearGrid (.vtr).

Every writer writes atomically (a temporary file in the same folder, then os.replace) and its
output reads back through ``load_field`` to the same grid, arrays and time.  Arrays are written
as float64 unless ``dtype`` says otherwise (e.g. float32 to halve the size).
"""

from __future__ import annotations

import base64
import contextlib
import os
import tempfile
import zlib
from pathlib import Path
from xml.sax.saxutils import quoteattr

import h5py
import numpy as np

from .field import Field
from .readers.hdf5 import FORMAT, FORMAT_VERSION

WRITERS_EXT = (".npz", ".h5", ".hdf5", ".vti", ".vtr")


@contextlib.contextmanager
def atomic_path(path):
    """A temporary path beside ``path``; moved onto ``path`` only when the block succeeds."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent or ".")
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file ordinary permissions
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def save_field(
    field: Field, path, *, dtype=None, compression="gzip", encoding="appended", compress=True
) -> Path:
    """Write ``field`` in the format of ``path``'s extension; returns the path.

    ``compression`` (HDF5: "gzip", "lzf" or None), ``encoding`` (VTK: "ascii", "binary" or
    "appended" raw) and ``compress`` (VTK: zlib blocks) only apply to their formats.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext == ".npz":
        _write_npz(field, path, dtype)
    elif ext in (".h5", ".hdf5"):
        save_series([field], path, dtype=dtype, compression=compression, single=True)
    elif ext in (".vti", ".vtr"):
        _write_vtk(field, path, ext, dtype, encoding, compress)
    else:
        raise ValueError(
            f"{path}: cannot write extension '{path.suffix}'; known: {', '.join(WRITERS_EXT)}"
        )
    return path


def _cast(a, dtype):
    return a if dtype is None else a.astype(dtype)


# -- npz -------------------------------------------------------------------------------------
def _write_npz(field, path, dtype):
    arrays = {
        "x": field.grid.x,
        "y": field.grid.y,
        "z": field.grid.z,
        field.vector_name: _cast(field.vector, dtype),
        **{n: _cast(a, dtype) for n, a in field.scalars.items()},
    }
    if field.time is not None:
        arrays["time"] = np.float64(field.time)
    if any(field.grid.periodic):
        arrays["period"] = np.array(field.grid.period)
    clash = {"x", "y", "z", "time", "period"} & ({field.vector_name} | set(field.scalars))
    if clash:
        raise ValueError(f"{path}: array name(s) {sorted(clash)} are reserved in .npz fields")
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


# -- HDF5 ------------------------------------------------------------------------------------
def save_series(
    fields, path, *, dtype=None, compression="gzip", single=False, attrs=None
) -> Path:
    """Write fields sharing one grid into one flowkit HDF5 file (layout in readers/hdf5.py):
    /snapshots/NNNN groups, or with ``single=True`` and one field the single-snapshot layout.
    ``attrs`` adds root attributes (e.g. provenance)."""
    fields = list(fields)
    path = Path(path)
    if not fields:
        raise ValueError(f"{path}: no fields to write")
    g0 = fields[0].grid
    for i, f in enumerate(fields):
        if f.grid != g0:
            raise ValueError(
                f"{path}: snapshot {i} ({f.source}) is on a different grid than snapshot 0"
            )
    opts = {} if compression is None else {"compression": compression, "shuffle": True}
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as h:
        h.attrs["flowkit_format"] = FORMAT
        h.attrs["flowkit_format_version"] = FORMAT_VERSION
        h.attrs["vector_name"] = fields[0].vector_name
        h.attrs.update(attrs or {})
        if any(g0.periodic):
            h.attrs["period"] = np.array(g0.period)
        for name, c in zip("xyz", g0.axes):
            ds = h.create_dataset(name, data=c)
            if fields[0].length_units:
                ds.attrs["units"] = fields[0].length_units
        if single and len(fields) == 1:
            _write_snapshot(h, fields[0], dtype, opts)
            if fields[0].notes:
                h.attrs["notes"] = list(fields[0].notes)
        else:
            for i, f in enumerate(fields):
                _write_snapshot(h.create_group(f"snapshots/{i:04d}"), f, dtype, opts)
    return path


def _write_snapshot(g, field, dtype, opts):
    if field.time is not None:
        g.attrs["time"] = float(field.time)
        if field.time_origin:
            g.attrs["time_origin"] = field.time_origin
    arrays = {f"vectors/{field.vector_name}": field.vector,
              **{f"scalars/{n}": a for n, a in field.scalars.items()}}
    for key, a in arrays.items():
        ds = g.create_dataset(key, data=_cast(a, dtype), **opts)
        unit = field.units.get(key.split("/", 1)[1])
        if unit:
            ds.attrs["units"] = unit  # CF: what the readers give back as Field.units


# -- VTK XML ---------------------------------------------------------------------------------
_VTK_TYPES = {"float64": "Float64", "float32": "Float32"}
_BLOCK = 1 << 15  # VTK's default compression block size


def _write_vtk(field, path, ext, dtype, encoding, compress):
    if encoding not in ("ascii", "binary", "appended"):
        raise ValueError(
            f"{path}: encoding must be 'ascii', 'binary' or 'appended', got {encoding!r}"
        )
    g = field.grid
    kind = "ImageData" if ext == ".vti" else "RectilinearGrid"
    extent = " ".join(f"0 {n - 1}" for n in g.shape)
    if kind == "ImageData":
        if not g.uniform:
            raise ValueError(
                f"{path}: .vti needs a uniform grid; this one is rectilinear (write .vtr)"
            )
        spacing = [_exact_spacing(c) for c in g.axes]
        head = (
            f'<ImageData WholeExtent="{extent}" Origin="{_nums(g.origin)}" '
            f'Spacing="{_nums(spacing)}" Direction="1 0 0 0 1 0 0 0 1">'
        )
    else:
        head = f'<RectilinearGrid WholeExtent="{extent}">'
    appended = []
    compressor = ' compressor="vtkZLibDataCompressor"' if compress and encoding != "ascii" else ""

    def data_array(name, a, ncomp=1):
        a = np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<"), copy=False)
        vt = _VTK_TYPES[str(a.dtype.newbyteorder("="))]
        attrs = (
            f'type="{vt}" Name={quoteattr(name)} NumberOfComponents="{ncomp}" '
            f'NumberOfTuples="{a.size // ncomp}"'
        )
        if encoding == "ascii":
            text = " ".join(map(repr, a.ravel().tolist()))
            return f'<DataArray {attrs} format="ascii">{text}</DataArray>'
        blob = _block(a.tobytes(), compress)
        if encoding == "binary":
            if compress:  # VTK encodes the header of compressed data separately
                text = base64.b64encode(blob[0]).decode() + base64.b64encode(blob[1]).decode()
            else:
                text = base64.b64encode(blob[0] + blob[1]).decode()
            return f'<DataArray {attrs} format="binary">{text}</DataArray>'
        offset = sum(len(b) for b in appended)
        appended.append(blob[0] + blob[1])
        return f'<DataArray {attrs} format="appended" offset="{offset}"/>'

    def nodes(a):  # [i, j, k(, c)] -> VTK order, x fastest
        return _cast(a, dtype).transpose(2, 1, 0, *range(3, a.ndim))

    parts = [
        '<?xml version="1.0"?>',
        (
            f'<VTKFile type="{kind}" version="1.0" byte_order="LittleEndian" '
            f'header_type="UInt64"{compressor}>'
        ),
        head,
    ]
    if field.time is not None:
        parts += ["<FieldData>", data_array("TimeValue", np.array([field.time])), "</FieldData>"]
    parts.append(f'<Piece Extent="{extent}">')
    scal = f" Scalars={quoteattr(next(iter(field.scalars)))}" if field.scalars else ""
    parts.append(f"<PointData Vectors={quoteattr(field.vector_name)}{scal}>")
    parts.append(data_array(field.vector_name, nodes(field.vector), 3))
    parts += [data_array(n, nodes(a)) for n, a in field.scalars.items()]
    parts.append("</PointData><CellData/>")
    if kind == "RectilinearGrid":
        parts += [
            "<Coordinates>",
            *(data_array(n, c) for n, c in zip("xyz", g.axes)),
            "</Coordinates>",
        ]
    parts += ["</Piece>", f"</{kind}>"]
    body = "\n".join(parts).encode()
    if appended:
        body += b'\n<AppendedData encoding="raw">\n_' + b"".join(appended) + b"\n</AppendedData>"
    with atomic_path(path) as tmp:
        tmp.write_bytes(body + b"\n</VTKFile>\n")


def _block(raw: bytes, compress: bool) -> tuple[bytes, bytes]:
    """(header, data) of one binary DataArray with a UInt64 header (zlib in VTK's blocks)."""
    if not compress:
        return np.array([len(raw)], "<u8").tobytes(), raw
    comp = [zlib.compress(raw[i : i + _BLOCK]) for i in range(0, len(raw), _BLOCK)]
    header = np.array([len(comp), _BLOCK, len(raw) % _BLOCK, *map(len, comp)], "<u8")
    return header.tobytes(), b"".join(comp)


def _exact_spacing(c: np.ndarray) -> float:
    """A spacing h for which c[0] + h * arange(n) reproduces the axis exactly when one exists
    (so .vti round-trips Grid.regular grids bit for bit); else the mean spacing."""
    h0 = (c[-1] - c[0]) / (c.size - 1)
    i = np.arange(c.size)
    for cand in (h0, c[1] - c[0]):
        h = cand
        for _ in range(4):
            if np.array_equal(c[0] + h * i, c):
                return float(h)
            h = np.nextafter(h, np.inf)
        h = cand
        for _ in range(4):
            h = np.nextafter(h, -np.inf)
            if np.array_equal(c[0] + h * i, c):
                return float(h)
    return float(h0)


def _nums(v) -> str:
    return " ".join(repr(float(x)) for x in v)
