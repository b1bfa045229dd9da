"""NumPy ``.npz`` / ``.npy`` fields.

``.npz``: 1-D coordinate arrays ``x``, ``y``, ``z`` (strictly increasing) and named node arrays
indexed ``a[i, j, k]`` with i along x (shape (nx, ny, nz)).  The vector (``vector=``, default
``U``) is either one (nx, ny, nz, 3) array named ``U`` or three (nx, ny, nz) arrays ``U_x``,
``U_y``, ``U_z``.  Every other (nx, ny, nz) array is a scalar field.  Optional: a 0-d ``time``
array, a (3,) ``period`` array (0 = bounded axis) as ``save_field`` writes it.

``.npy``: one (nx, ny, nz, 3) vector array; the grid comes from ``x=, y=, z=`` or from
``origin=`` and ``spacing=`` (default origin 0 and spacing 1, said in the notes).

Files are opened with ``allow_pickle=False``: object arrays are refused, never unpickled.
"""

from __future__ import annotations

import zipfile

import numpy as np

from ..stored import Stored
from ._common import ReaderError, existing, make_field

RESERVED = ("x", "y", "z", "time", "period")


def _guarded(read, path, what, pickled, fix=""):
    """read() with NumPy's pickle refusal and truncation turned into ReaderErrors about ``what``."""
    try:
        return read()
    except ValueError as e:
        if "pickle" in str(e).lower():
            raise ReaderError(f"{path}: {pickled}; refused (flowkit never unpickles files){fix}"
                              ) from None
        raise ReaderError(f"{path}: {what} (truncated or corrupt): {e}") from None
    except (OSError, EOFError, zipfile.BadZipFile) as e:
        raise ReaderError(f"{path}: {what} (truncated or corrupt): {e}") from None


def _load(path):
    return _guarded(lambda: np.load(path, allow_pickle=False), path,
                    "not a readable NumPy file",
                    "holds a pickled object array", ". Save plain numeric arrays instead")


def read_npz(path, vector="U", periodic=(False, False, False), period=None):
    path = existing(path)
    arrays = {}
    with _load(path) as z:
        for name in z.files:
            arrays[name] = _guarded(lambda n=name: z[n], path, f"array '{name}' is unreadable",
                                    f"array '{name}' holds pickled objects")
    missing = [c for c in "xyz" if c not in arrays]
    if missing:
        raise ReaderError(
            f"{path}: missing coordinate array(s) {', '.join(missing)}; an .npz field "
            f"needs 1-D x, y, z; arrays in the file: {', '.join(sorted(arrays)) or 'none'}"
        )
    for c in "xyz":
        if arrays[c].ndim != 1:
            raise ReaderError(
                f"{path}: coordinate array '{c}' has shape {arrays[c].shape}, expected 1-D (n{c},)"
            )
    time = arrays.get("time")
    if time is not None:
        if time.size != 1:
            raise ReaderError(
                f"{path}: array 'time' has shape {time.shape}, expected a single value"
            )
        time = float(time.reshape(()))
    if "period" in arrays and period is None and not any(np.atleast_1d(periodic)):
        p = arrays["period"]
        if p.shape != (3,):
            raise ReaderError(f"{path}: array 'period' has shape {p.shape}, expected (3,)")
        period, periodic = tuple(float(v) for v in p), tuple(bool(v > 0) for v in p)
    data = {k: v for k, v in arrays.items() if k not in RESERVED}
    _check_numeric(path, data)
    return make_field(
        path,
        arrays["x"],
        arrays["y"],
        arrays["z"],
        data,
        vector,
        time=time,
        periodic=periodic,
        period=period,
    )


def read_npy(
    path,
    vector="U",
    x=None,
    y=None,
    z=None,
    origin=(0.0, 0.0, 0.0),
    spacing=(1.0, 1.0, 1.0),
    periodic=(False, False, False),
    period=None,
):
    path = existing(path)
    a = _mapped(path)
    if not isinstance(a, np.ndarray):
        raise ReaderError(f"{path}: expected a single array in a .npy file")
    _check_numeric(path, {vector: a})
    if a.ndim != 4 or a.shape[-1] != 3:
        raise ReaderError(
            f"{path}: array has shape {a.shape}, expected (nx, ny, nz, 3): "
            "a .npy file holds one vector array"
        )
    notes = []
    if x is None or y is None or z is None:
        o = np.broadcast_to(np.asarray(origin, float), (3,))
        h = np.broadcast_to(np.asarray(spacing, float), (3,))
        x, y, z = (o[i] + h[i] * np.arange(a.shape[i]) for i in range(3))
        notes.append(f"grid not stored in the .npy file: origin {tuple(o)}, spacing {tuple(h)}")
    if isinstance(a, np.memmap):  # read when used, a slab at a time
        a = Stored.of(a, str(path))
    return make_field(
        path, x, y, z, {vector: a}, vector, notes=notes, periodic=periodic, period=period
    )


def _mapped(path):
    """The .npy file's array memory-mapped (nothing read yet); where it cannot be mapped
    (objects, a truncated file), as ``_load`` reads it, with its errors."""
    try:
        return np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError):
        return _load(path)


def _check_numeric(path, arrays):
    for name, a in arrays.items():
        if not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
            raise ReaderError(
                f"{path}: array '{name}' has dtype {a.dtype}, expected a numeric array"
            )
