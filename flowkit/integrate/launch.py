"""What a tracing backend is handed for one pass: ``Launch``, one documented object.

``trace`` runs a batch of lines in passes (``trace.Setup.run``); each pass calls the backend
(``lanes.advance`` for numba, ``OpenCLAdvance``, or a user's callable) with a ``Launch``: which
lines to advance, the method, the options, the field and the lines' state and output buffers.
The backend advances every line ``active[n]`` until it is done or has written ``B`` vertices
into row n of the output buffers, and leaves its state in ``sf``/``si`` so that the next pass
continues it bit for bit.  Every array is the caller's (no copies); the column layouts of the
state and option rows are ``schema.py``'s.  The numba functions keep taking the arrays one by
one (``Launch.arrays()``, in their order): compiled code takes no Python objects.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from ..fields.bricks import NO_BRICKS


@dataclass(frozen=True)
class FieldArrays:
    """The field as the kernels read it: ``Grid.kernel_args()`` and the vector array."""

    gx: np.ndarray  # node coordinates of each axis, increasing
    gy: np.ndarray
    gz: np.ndarray
    period: np.ndarray  # (3,) period of each axis, 0 on a bounded one
    inv: np.ndarray  # (3,) 1 / node spacing where every axis is uniform, else zeros
    vec: np.ndarray  # (nx, ny, nz, 3) velocity at the nodes, C-contiguous, float64 or float32;
    # a bricked field: the pool of its resident bricks
    bk: np.ndarray = field(default_factory=lambda: NO_BRICKS)  # a bricked field's table
    # (fields/bricks.py), empty otherwise

    @classmethod
    def of(cls, fld) -> FieldArrays:
        return cls(*fld.grid.kernel_args(), fld.vector)


@dataclass(frozen=True)
class MethodArrays:
    """A Runge–Kutta method as the kernels read it (``Method.kernel_arrays()``)."""

    c: np.ndarray  # (s,) nodes
    a: np.ndarray  # (s, s) stage coefficients
    b: np.ndarray  # (s,) weights of y1
    e: np.ndarray  # (s,) error weights
    e2: np.ndarray  # (s,) second error weights (DOP853), zeros otherwise
    p: np.ndarray  # (s, q) dense output coefficients
    info: np.ndarray  # (NMI,) int64, columns schema.METHOD_INFO (stages, n_err, ...)

    @classmethod
    def of(cls, method) -> MethodArrays:
        return cls(*method.kernel_arrays())


@dataclass(frozen=True)
class Launch:
    """One pass of a backend over the lines ``active`` (indices into the per-line arrays)."""

    active: np.ndarray  # (n_active,) int64: the lines of this pass; row n of the outputs is
    # line active[n]
    seeds: np.ndarray  # (n, 3) start points
    dirs: np.ndarray  # (n,) +1 forward, -1 backward
    spacings: np.ndarray  # (n,) vertex spacing in arc length (EMIT_SPACING)
    phases: np.ndarray  # (n,) arc length of the first resampled vertex
    field: FieldArrays
    method: MethodArrays
    fo: np.ndarray  # (NFO,) float options, columns schema.FLOAT_OPTIONS
    io: np.ndarray  # (NIO,) int options, columns schema.INT_OPTIONS
    sf: np.ndarray  # (n, NF) float state, columns schema.FLOAT_STATE
    si: np.ndarray  # (n, NI) int64 state, columns schema.INT_STATE (zeros: not started)
    out_p: np.ndarray  # (n_active, B, 3) vertices written this pass
    out_par: np.ndarray  # (n_active, B, 2 + columns) time, arc length (and a backend's own)
    out_n: np.ndarray  # (n_active,) int64: vertices written this pass
    stiff: np.ndarray | None = None  # the Rosenbrock stepper's table (rosenbrock.table) for
    # lines that step with it (io[P_ROS], si[:, I_ROS]); numba only

    def arrays(self) -> tuple:
        """Every array, in the order the numba kernels take them."""
        return (self.active, self.seeds, self.dirs, self.spacings, self.phases,
                *_values(self.field), *_values(self.method), self.fo, self.io, self.sf, self.si,
                self.out_p, self.out_par, self.out_n)


def _values(obj) -> tuple:
    """The fields of a dataclass, as they are (``dataclasses.astuple`` would copy the arrays)."""
    return tuple(getattr(obj, f.name) for f in fields(obj))
