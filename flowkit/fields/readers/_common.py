"""Pieces every reader shares: the error type, file checks, and arrays -> Field."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..field import Field
from ..grid import Grid, GridError
from ..stored import Stored, kept_dtype


class ReaderError(ValueError):
    """A file that cannot be read as a field; the message names the file and the problem."""


def existing(path) -> Path:
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if p.is_dir():
        raise ReaderError(f"{p}: is a directory, expected a field file")
    return p


def grid_from_axes(where, x, y, z, periodic=(False, False, False), period=None) -> Grid:
    try:
        return Grid.from_axes(x, y, z, periodic=periodic, period=period, where=str(where))
    except GridError as e:
        raise ReaderError(str(e)) from None


def vectors_and_scalars(where, shape, arrays: dict, vector: str):
    """Split named node arrays (x-index first) into the chosen vector and the scalars.

    The vector is ``arrays[vector]`` of shape (nx, ny, nz, 3), or the three arrays
    ``vector_x``, ``vector_y``, ``vector_z`` of shape (nx, ny, nz).  Every other (nx, ny, nz)
    array is a scalar; other 3-component arrays are left out with a note (a Field holds one
    vector).  Any other shape is an error that states the shape expected.
    """
    shape = tuple(shape)
    notes = []
    comps = [f"{vector}_{c}" for c in "xyz"]
    for name, a in arrays.items():
        if a.shape not in (shape, shape + (3,)):
            raise ReaderError(
                f"{where}: array '{name}' has shape {a.shape}, expected {shape} (nx, ny, nz) "
                f"for a scalar or {shape + (3,)} for a vector on the grid"
            )
    if vector in arrays:
        vec = arrays[vector]
        if vec.shape != shape + (3,):
            raise ReaderError(
                f"{where}: '{vector}' is a scalar array of shape {vec.shape}, "
                f"not a vector of shape {shape + (3,)}; "
                f"vectors in the file: {_names(vector_names(arrays))}"
            )
        used = {vector}
    elif all(c in arrays for c in comps):
        parts = [arrays[c] for c in comps]
        if any(isinstance(a, Stored) for a in parts):  # stacked when read, not now
            parts = [Stored.of(a, n) for a, n in zip(parts, comps)]
            vec = Stored.stacked(parts, f"{where}: {vector}")
        else:
            vec = np.stack(parts, axis=-1)
        used = set(comps)
    else:
        raise ReaderError(
            f"{where}: no vector '{vector}' (as one (nx, ny, nz, 3) array or as "
            f"{', '.join(comps)}); vectors in the file: {_names(vector_names(arrays))}"
        )
    scalars = {}
    for name, a in arrays.items():
        if name in used:
            continue
        if a.ndim == 4:
            notes.append(
                f"vector '{name}' not loaded "
                f"(a Field holds one vector; pick it with vector='{name}')"
            )
        else:
            scalars[name] = a
    return vec, scalars, notes


def vector_names(arrays: dict) -> list[str]:
    """Names usable as ``vector``: 3-component arrays and NAME_x/NAME_y/NAME_z triples."""
    names = [n for n, a in arrays.items() if a.ndim == 4 and a.shape[-1] == 3]
    for n in arrays:
        if n.endswith("_x") and all(n[:-2] + s in arrays for s in ("_y", "_z")):
            names.append(n[:-2])
    return names


def _names(names) -> str:
    return ", ".join(sorted(names)) if names else "none"


def dtype_note(arrays: dict) -> list[str]:
    """Say when the file stored arrays in a type a Field does not hold (float32 and float64
    stay as they are; anything else becomes float64)."""
    stored = [a.stored if isinstance(a, Stored) else a.dtype for a in arrays.values()]
    kinds = sorted({str(d) for d in stored if kept_dtype(d) != d.newbyteorder("=")})
    return (
        [f"arrays stored as {', '.join(kinds)} in the file, converted to float64"] if kinds else []
    )


# Units of the fields an OpenFOAM export names, where the name fixes them.  p, p_rgh and alphat
# are left out: kinematic (m2/s2, m2/s) in incompressible solvers, Pa and kg/m/s in compressible.
OPENFOAM_UNITS = {"U": "m/s", "T": "K", "k": "m2/s2", "epsilon": "m2/s3", "omega": "1/s",
                  "nut": "m2/s", "nuTilda": "m2/s", "rho": "kg/m3"}


def openfoam_export(path) -> bool:
    """Whether a VTK file was written by OpenFOAM's foamToVTK (its header comment names the
    case), so its lengths are metres and the OPENFOAM_UNITS names mean what they say."""
    try:
        with open(path, "rb") as f:
            head = f.read(512)
    except OSError:
        return False
    return b"<!-- case=" in head


def foam_units(path, names) -> tuple[dict[str, str], str | None]:
    """(units by array name, length units) of an OpenFOAM export; nothing for other files."""
    if not openfoam_export(path):
        return {}, None
    units = {n: OPENFOAM_UNITS[n] for n in names if n in OPENFOAM_UNITS}
    for n in names:  # NAME_x/_y/_z components of a known vector
        if n[-2:] in ("_x", "_y", "_z") and n[:-2] in OPENFOAM_UNITS:
            units[n[:-2]] = OPENFOAM_UNITS[n[:-2]]
    return units, "m"


def make_field(
    where,
    x,
    y,
    z,
    arrays: dict,
    vector: str = "U",
    *,
    time=None,
    notes=(),
    periodic=(False, False, False),
    period=None,
    units=None,
    length_units=None,
    time_origin=None,
) -> Field:
    """A Field from 1-D axes and named node arrays indexed [i, j, k] (x first).  ``units``:
    array name -> units as the file states them (the vector's under its own name).  An axis
    whose nodes decrease (latitudes from north to south, depths downwards) is reversed, the
    arrays with it, and a note says so."""
    axes, flipped = [], []
    for a, c in enumerate((x, y, z)):
        c = np.asarray(c)
        if c.ndim == 1 and c.size >= 2 and np.all(np.diff(c) < 0):
            c = c[::-1]
            arrays = {n: v.flipped((a,)) if isinstance(v, Stored) else np.flip(v, axis=a)
                      for n, v in arrays.items()}
            flipped.append("xyz"[a])
        axes.append(c)
    if flipped:
        note = (f"nodes decreasing along {', '.join(flipped)} in the file: reversed to "
                "increasing, the data with them")
        notes = [*notes, note]
    grid = grid_from_axes(where, *axes, periodic, period)
    vec, scalars, more = vectors_and_scalars(where, grid.shape, arrays, vector)
    notes = [*notes, *dtype_note({vector: vec, **scalars}), *more]
    kept = {vector, *scalars}
    units = {str(n): str(u) for n, u in (units or {}).items() if n in kept and str(u).strip()}
    return Field(
        grid,
        vec,
        scalars,
        vector_name=vector,
        source=str(where),
        time=None if time is None else float(time),
        notes=notes,
        units=units,
        length_units=str(length_units) if length_units else None,
        time_origin=time_origin,
    )


def select_snapshot(where, times: list, snapshot=None, time=None) -> int:
    """Index of the snapshot asked for by position (negative counts from the end) or by time.

    With neither given the first snapshot is used (as ParaView opens a series at its first time).
    """
    n = len(times)
    if snapshot is not None and time is not None:
        raise ReaderError(f"{where}: give snapshot= or time=, not both")
    if time is not None:
        t = np.asarray(times, dtype=float)
        hit = np.flatnonzero(np.isclose(t, float(time), rtol=1e-9, atol=0))
        if hit.size == 0:
            raise ReaderError(f"{where}: no snapshot at time {time!r}; times: {fmt_times(times)}")
        return int(hit[0])
    i = 0 if snapshot is None else int(snapshot)
    if not -n <= i < n:
        raise ReaderError(
            f"{where}: snapshot {snapshot} out of range; the file holds {n} "
            f"snapshot(s) (0..{n - 1}), times: {fmt_times(times)}"
        )
    return i % n


def fmt_times(times) -> str:
    return ", ".join(f"{t:.10g}" for t in times)
