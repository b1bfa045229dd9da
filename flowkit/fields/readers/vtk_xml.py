"""VTK XML ImageData (.vti) and RectilinearGrid (.vtr), parsed with xml.etree + numpy.

Every encoding VTK writes is read: ``ascii``, ``binary`` (base64 inline) and ``appended``
(``raw`` or ``base64``), uncompressed or compressed in blocks (zlib or lzma), with UInt32 or UInt64
headers, little- or big-endian; files of several pieces are assembled into the whole extent.
``TimeValue`` in FieldData becomes ``Field.time``.

PointData is read by default.  ``data="cell"`` reads CellData instead and places each value at its
cell centre: the Field's grid is then the grid of cell centres (one node fewer per axis, half a
cell inside the nodes' bounds); values are not averaged, and Field.notes says so.
"""

from __future__ import annotations

import base64
import binascii
import lzma
import re
import xml.etree.ElementTree as ET
import zlib

import numpy as np

from ._common import ReaderError, existing, foam_units, make_field

TYPES = {
    "Int8": "i1",
    "UInt8": "u1",
    "Int16": "i2",
    "UInt16": "u2",
    "Int32": "i4",
    "UInt32": "u4",
    "Int64": "i8",
    "UInt64": "u8",
    "Float32": "f4",
    "Float64": "f8",
}
KINDS = {".vti": "ImageData", ".vtr": "RectilinearGrid"}


def read_vtk_xml(path, vector="U", data="point", periodic=(False, False, False), period=None):
    path = existing(path)
    if data not in ("point", "cell"):
        raise ReaderError(f"{path}: data must be 'point' or 'cell', got {data!r}")
    doc = _Document(path)
    kind = doc.root.get("type")
    if kind not in KINDS.values():
        raise ReaderError(
            f"{path}: VTK XML type '{kind}' is not ImageData or RectilinearGrid "
            "(.vtu files are read by vtu.py)"
        )
    grid_el = doc.find(doc.root, kind)
    whole = _extent(path, grid_el.get("WholeExtent"), "WholeExtent")
    shape = tuple(int(whole[2 * a + 1] - whole[2 * a] + 1) for a in range(3))
    if kind == "ImageData":
        axes = _image_axes(path, grid_el, whole)
    else:
        axes = [np.full(n, np.nan) for n in shape]
    point, cell = {}, {}
    pieces = grid_el.findall("Piece")
    if not pieces:
        raise ReaderError(f"{path}: no Piece element (truncated or corrupt)")
    filled = np.zeros(shape, bool)
    for piece in pieces:
        ext = _extent(path, piece.get("Extent"), "Piece Extent")
        lo = [int(ext[2 * a] - whole[2 * a]) for a in range(3)]
        pshape = tuple(int(ext[2 * a + 1] - ext[2 * a] + 1) for a in range(3))
        sl = tuple(slice(o, o + n) for o, n in zip(lo, pshape))
        csl = tuple(slice(o, o + max(n - 1, 1)) for o, n in zip(lo, pshape))
        filled[sl] = True
        if kind == "RectilinearGrid":
            coords = doc.find(piece, "Coordinates").findall("DataArray")
            if len(coords) != 3:
                raise ReaderError(
                    f"{path}: Coordinates must hold 3 DataArrays, found {len(coords)}"
                )
            for a, el in enumerate(coords):
                axes[a][sl[a]] = doc.array(el, pshape[a])
        for section, store, pts in (("PointData", point, True), ("CellData", cell, False)):
            sec = piece.find(section)
            if sec is None:
                continue
            if not pts and section == "CellData" and data == "point":
                # cell arrays are only named, never decoded, unless asked for
                for el in sec.findall("DataArray"):
                    store.setdefault(el.get("Name"), None)
                continue
            dims = pshape if pts else tuple(max(n - 1, 1) for n in pshape)
            for el in sec.findall("DataArray"):
                name, nc = el.get("Name"), int(el.get("NumberOfComponents", 1))
                flat = doc.array(el, int(np.prod(dims)) * nc)
                a = flat.reshape(dims[::-1] + (nc,)).transpose(2, 1, 0, 3)
                if name not in store:
                    full = (shape if pts else tuple(max(n - 1, 1) for n in shape)) + (nc,)
                    store[name] = np.empty(full, a.dtype)
                store[name][sl if pts else csl] = a
    if not filled.all():
        raise ReaderError(f"{path}: the pieces do not cover the WholeExtent {whole.tolist()}")
    if kind == "RectilinearGrid" and any(np.isnan(c).any() for c in axes):
        raise ReaderError(f"{path}: RectilinearGrid coordinates missing for part of the extent")
    time = doc.time_value()
    notes = []
    arrays, other = (point, cell) if data == "point" else (cell, point)
    skipped = [n for n, a in arrays.items() if a.shape[-1] not in (1, 3)]
    if skipped:
        notes.append(f"arrays with neither 1 nor 3 components not loaded: {', '.join(skipped)}")
    arrays = {
        n: (a[..., 0] if a.shape[-1] == 1 else a) for n, a in arrays.items() if n not in skipped
    }
    if vector not in arrays and f"{vector}_x" not in arrays and vector in other:
        if data == "point":
            raise ReaderError(
                f"{path}: array '{vector}' is cell data, not point data; point data "
                f"arrays: {', '.join(arrays) or 'none'}. Pass data='cell' to use cell "
                "data (values placed at cell centres)"
            )
        raise ReaderError(
            f"{path}: array '{vector}' is point data, not cell data; cell data "
            f"arrays: {', '.join(arrays) or 'none'}"
        )
    if data == "cell":
        axes = [0.5 * (c[1:] + c[:-1]) for c in axes]
        notes.append(
            "cell data: each value placed at its cell centre (grid of cell centres, one "
            "node fewer per axis than the file's points); not averaged to points"
        )
    elif other:
        notes.append(f"cell data not loaded (pass data='cell' to use it): {', '.join(other)}")
    units, length = foam_units(path, arrays)
    return make_field(
        path, *axes, arrays, vector, time=time, notes=notes, periodic=periodic, period=period,
        units=units, length_units=length,
    )


def _extent(path, text, what):
    try:
        e = np.array(text.split(), dtype=np.int64)
    except (AttributeError, ValueError):
        e = np.zeros(0)
    if e.size != 6 or np.any(e[1::2] < e[0::2]):
        raise ReaderError(f"{path}: bad {what} {text!r}, expected 6 integers x0 x1 y0 y1 z0 z1")
    return e


def _image_axes(path, el, whole):
    def vec(attr, default, n=3):
        try:
            v = np.array(el.get(attr, default).split(), dtype=float)
        except ValueError:
            v = np.zeros(0)
        if v.size != n:
            raise ReaderError(f"{path}: ImageData {attr}={el.get(attr)!r}, expected {n} numbers")
        return v

    origin, spacing = vec("Origin", "0 0 0"), vec("Spacing", "1 1 1")
    direction = vec("Direction", "1 0 0 0 1 0 0 0 1", 9)
    if not np.array_equal(direction, np.eye(3).ravel()):
        raise ReaderError(
            f"{path}: ImageData Direction {direction.tolist()} is not the identity; "
            "flowkit grids are axis-aligned (resample the data first)"
        )
    if np.any(spacing <= 0):
        raise ReaderError(f"{path}: ImageData Spacing {spacing.tolist()} must be positive")
    return [
        origin[a] + spacing[a] * np.arange(whole[2 * a], whole[2 * a + 1] + 1) for a in range(3)
    ]


class _Document:
    """The XML tree plus the appended-data block, and the decoder of DataArrays."""

    def __init__(self, path):
        self.path = path
        raw = path.read_bytes()
        self.appended, self.encoding = None, None
        start = raw.find(b"<AppendedData")
        if start >= 0:
            tag_end = raw.find(b">", start)
            end = raw.rfind(b"</AppendedData>")
            if tag_end < 0 or end < 0:
                self.corrupt("the AppendedData section is not closed")
            m = re.search(rb'encoding\s*=\s*["\'](\w+)["\']', raw[start:tag_end])
            self.encoding = m.group(1).decode() if m else "raw"
            under = raw.find(b"_", tag_end, end)
            if under < 0:
                self.corrupt("AppendedData without its '_' marker")
            self.appended = raw[under + 1 : end]
            if self.encoding == "base64":
                self.appended = self.appended.strip()
            raw = raw[:start] + raw[end + len(b"</AppendedData>") :]
        try:
            self.root = ET.fromstring(raw)
        except ET.ParseError as e:
            self.corrupt(f"XML parse error: {e}")
        if self.root.tag != "VTKFile":
            raise ReaderError(f"{path}: not a VTK XML file (root element <{self.root.tag}>)")
        little = self.root.get("byte_order", "LittleEndian") == "LittleEndian"
        self.order = "<" if little else ">"
        htype = self.root.get("header_type", "UInt32")
        if htype not in ("UInt32", "UInt64"):
            raise ReaderError(f"{path}: header_type {htype!r} is not UInt32 or UInt64")
        self.header = np.dtype(self.order + TYPES[htype])
        comp = self.root.get("compressor")
        self.decompress = {
            None: None,
            "": None,
            "vtkZLibDataCompressor": zlib.decompress,
            "vtkLZMADataCompressor": lzma.decompress,
        }.get(comp, "?")
        if self.decompress == "?":
            raise ReaderError(
                f"{path}: compressor {comp!r} is not supported "
                "(zlib and lzma are; re-save with zlib)"
            )
        self.offsets = sorted(
            int(el.get("offset"))
            for el in self.root.iter("DataArray")
            if el.get("format") == "appended"
        )

    def corrupt(self, why):
        raise ReaderError(f"{self.path}: VTK file is truncated or corrupt ({why})")

    def find(self, parent, tag):
        el = parent.find(tag)
        if el is None:
            raise ReaderError(
                f"{self.path}: no <{tag}> element in <{parent.tag}> (truncated or corrupt?)"
            )
        return el

    def time_value(self):
        for el in self.root.iter("DataArray"):
            if el.get("Name") == "TimeValue":
                return float(self.array(el, None)[0])
        return None

    def array(self, el, count):
        """The flat values of a DataArray; ``count`` values expected (None: any)."""
        name, t = el.get("Name"), el.get("type")
        if t not in TYPES:
            raise ReaderError(f"{self.path}: array '{name}' has type {t!r}, not a numeric VTK type")
        dt = np.dtype(self.order + TYPES[t])
        fmt = el.get("format", "ascii")
        try:
            if fmt == "ascii":
                a = np.array((el.text or "").split(), dtype=dt)
            elif fmt == "binary":
                a = np.frombuffer(self.block(_b64(el.text or ""), name), dt)
            elif fmt == "appended":
                if self.appended is None:
                    self.corrupt(f"array '{name}' is appended but there is no AppendedData")
                off = int(el.get("offset"))
                if self.encoding == "raw":
                    a = np.frombuffer(self.block(self.appended, name, off), dt)
                else:
                    nxt = [o for o in self.offsets if o > off]
                    text = self.appended[off : nxt[0] if nxt else len(self.appended)]
                    a = np.frombuffer(self.block(_b64(text.decode("ascii")), name), dt)
            else:
                raise ReaderError(f"{self.path}: array '{name}' has unknown format {fmt!r}")
        except (ValueError, binascii.Error, zlib.error, lzma.LZMAError) as e:
            if isinstance(e, ReaderError):
                raise
            self.corrupt(f"array '{name}': {e}")
        if count is not None and a.size != count:
            self.corrupt(f"array '{name}' holds {a.size} values, expected {count}")
        return a.astype(dt.newbyteorder("="), copy=False)

    def block(self, buf, name, pos=0):
        """Bytes of one binary array at ``buf[pos:]``: header, then data (maybe compressed)."""
        hs = self.header.itemsize
        if self.decompress is None:
            n = int(self._ints(buf, pos, 1, name)[0])
            data = buf[pos + hs : pos + hs + n]
            if len(data) != n:
                self.corrupt(f"array '{name}' needs {n} bytes, {len(data)} present")
            return data
        nb = int(self._ints(buf, pos, 1, name)[0])
        h = self._ints(buf, pos, 3 + nb, name)
        bs, last, sizes = int(h[1]), int(h[2]), h[3:].astype(np.int64)
        out, at = [], pos + hs * (3 + nb)
        for b, s in enumerate(sizes):
            chunk = buf[at : at + s]
            if len(chunk) != s:
                self.corrupt(f"array '{name}' block {b} needs {s} bytes, {len(chunk)} present")
            out.append(self.decompress(chunk))
            at += s
        data = b"".join(out)
        want = (nb - 1) * bs + (last or bs) if nb else 0
        if len(data) != want:
            self.corrupt(f"array '{name}' decompressed to {len(data)} bytes, expected {want}")
        return data

    def _ints(self, buf, pos, n, name):
        need = n * self.header.itemsize
        if len(buf) < pos + need:
            self.corrupt(f"array '{name}' header cut short")
        return np.frombuffer(buf, self.header, n, pos)


def _b64(text: str) -> bytes:
    """Decode base64 that may be several padded streams back to back (VTK encodes the header of
    compressed data separately from the blocks)."""
    text = "".join(text.split())
    return b"".join(base64.b64decode(p, validate=True) for p in re.findall(r"[^=]+=*", text))
