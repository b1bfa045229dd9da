"""Render the OpenCL kernel source from the method's tableau arrays, and cache compiled programs.

The source is ``templates/advance.cl.j2`` (the step loop, ``kernel._advance_lines``) and the
includes it names, one per group of numba helpers they mirror, rendered with flags that say what
the run needs; every tuning constant is rendered from the numba module that defines it.  The
stages are unrolled from ``Method.kernel_arrays()`` (the arrays the numba kernel reads) as literal
coefficients that parse back to exactly the same number (``repr`` of the float64 value; for
float32 the float32-rounded value).  Zero coefficients are left out: adding ``0.0 * k`` never
changes a finite sum, and the numba kernel sums the same non-zero terms in the same order.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from jinja2 import Environment, FileSystemLoader, StrictUndefined

from .. import kernel as K
from .. import schema, stiffness
from .device import CPU_HINT, OpenCLUnavailable

TEMPLATES = Path(__file__).with_name("templates")
# the C source addresses the state (sf, si) and float options (fo) by the schema's names; the
# int options reach it as scalar arguments and the method's integers as literals
SCHEMA_DEFINES = schema.c_defines((schema.FLOAT_STATE, schema.INT_STATE, schema.FLOAT_OPTIONS),
                                  ("I_STATUS", "P_EMIT", "step event"))
# kernel's NORM_/ERR_ ranges for float32, whose squares over- and underflow far sooner (float64
# takes kernel's own)
FLOAT32_RANGES = {"NORM_TINY": 1e-18, "NORM_HUGE": 1e18, "ERR_TINY": 1e-30, "ERR_HUGE": 1e30}


@dataclass(frozen=True)
class Flags:
    """Everything that changes the kernel source; the program cache key (with the device)."""

    method: str
    tableau: bytes  # the method's kernel arrays, so that a changed tableau recompiles
    real: str = "double"  # or "float"
    aware: bool = True
    cross: bool = False  # cell-aware adaptive steps may cross faces (kernel.P_CROSS)
    periodic: bool = False  # any periodic axis: wrap code included
    uniform: bool = True  # all axes uniform: O(1) cell lookup instead of a binary search
    image: bool = False  # field from an image3d with hardware linear filtering
    # per-vertex attributes computed in the kernel (vertex.KERNEL_ATTRS, in that order) and the
    # number of scalar fields sampled; time and arc length need no code (the kernel's t and s)
    attrs: tuple = ()
    scalars: int = 0
    stiff_stage: int = -1  # the stage the stiffness test pairs with f(y1) (kernel.P_STIFF)

    def describe(self) -> str:
        d = asdict(self)
        d.pop("tableau")
        return ", ".join(f"{k}={v}" for k, v in d.items())


def tableau_key(arrays) -> bytes:
    return b"".join(np.ascontiguousarray(a).tobytes() + bytes(str(a.shape), "ascii") for a in arrays)


def literal(x: float, real: str) -> str:
    """A C literal that parses to exactly ``x`` (rounded to float32 first for real=float)."""
    if real == "float":
        x = float(np.float32(x))
    s = repr(float(x))
    if not np.isfinite(x):
        raise ValueError(f"non-finite coefficient {x!r} in a tableau")
    if "e" not in s and "." not in s:
        s += ".0"
    s = s + ("f" if real == "float" else "")
    return f"({s})" if s.startswith("-") else s


def constants(*modules) -> dict:
    """The upper-case numbers (tuning constants, reason codes) of the numba modules the template
    mirrors, read at each render; the state columns and codes come from the schema."""
    out = {}
    for mod in modules:
        out |= {n: v for n, v in vars(mod).items() if n.isupper() and n not in schema.CONSTANTS
                and isinstance(v, (int, float))}
    return out


@cache
def _env() -> Environment:
    return Environment(loader=FileSystemLoader(str(TEMPLATES)), undefined=StrictUndefined,
                       keep_trailing_newline=True, trim_blocks=False, lstrip_blocks=False)


def render(flags: Flags, arrays) -> str:
    """OpenCL C source for the method's ``kernel_arrays()`` under ``flags``."""
    _c, a, b, e, e2, p, ints = arrays
    S, n_err, fs = int(ints[schema.M_STAGES]), int(ints[schema.M_NERR]), int(ints[schema.M_FSAL])
    adaptive, has_e2 = bool(ints[schema.M_ADAPTIVE]), bool(ints[schema.M_HASE2])
    kexp = int(ints[schema.M_KEXP])
    # the test reads the point of a stage computed before the error test
    stiff_stage = flags.stiff_stage if 1 <= flags.stiff_stage < n_err else -1
    q = p.shape[1]
    if q > schema.QMAX:
        raise ValueError(f"method {flags.method}: dense output degree {q} > {schema.QMAX}")
    real = flags.real

    def terms(w):
        return [(m, float(w[m])) for m in range(len(w)) if w[m] != 0.0]

    def wsum(ts):
        """0.0 + w0*k[m0][a] + w1*k[m1][a] + ...: the numba kernel's left-to-right sum."""
        return " + ".join(["R(0.0)"] + [f"{literal(w, real)} * k[{m}][a]" for m, w in ts])

    def stage_code(st):
        return (f"for (int a = 0; a < 3; a++) yt[a] = y[a] + hs * ({wsum(terms(a[st, :st]))});\n"
                f"        rhs(yt[0], yt[1], yt[2], param, inc, G, &C, k, {st} IMGA);")

    ranges = {n: getattr(K, n) for n in FLOAT32_RANGES} if real == "double" else FLOAT32_RANGES
    return _env().get_template("advance.cl.j2").render(
        method=flags.method, real=real, aware=flags.aware, cross=flags.cross, periodic=flags.periodic,
        uniform=flags.uniform, image=flags.image, attrs=flags.attrs, n_scalars=flags.scalars,
        stiff_stage=stiff_stage,
        S=S, q=q, schema=SCHEMA_DEFINES,
        c=SimpleNamespace(**constants(K, stiffness)), rng=SimpleNamespace(**ranges),
        kexp=kexp, adaptive=adaptive, has_e2=has_e2, fs=fs,
        pre_stages=range(1, n_err), post_stages=range(n_err, fs + 1), dense_stages=range(fs + 1, S),
        b_terms=terms(b[:n_err]), e_terms=terms(e[:n_err]), e2_terms=terms(e2[:n_err]),
        p_terms=[terms(p[:, j]) for j in range(q)], wsum=wsum, stage_code=stage_code,
        lit=lambda x: literal(x, real))


# strict IEEE: no contraction into FMA (also set by the pragma), correctly rounded float32 / and sqrt
BUILD_OPTIONS = ("-cl-fp32-correctly-rounded-divide-sqrt",)

_programs: dict = {}


def kernel(ctx, device, flags: Flags, arrays, name: str = "advance"):
    """The compiled kernel ``name`` (``advance``; ``curl_nodes`` with vorticity) for (flags,
    device); each program is built once per process."""
    key = (flags, device.int_ptr)
    knls = _programs.get(key)
    if knls is None:
        import pyopencl as cl

        src = render(flags, arrays)
        try:
            prg = cl.Program(ctx, src).build(options=list(BUILD_OPTIONS), devices=[device])
        except cl.RuntimeError as exc:
            if "unknown target CPU" not in str(exc):
                raise
            raise OpenCLUnavailable(f"{device.name.strip()} cannot compile kernels: "
                                    f"{CPU_HINT}") from None
        knls = _programs[key] = {k.function_name: k for k in prg.all_kernels()}
    return knls[name]


def cached_programs() -> int:
    return len(_programs)
