"""Per-vertex attributes, computed only when requested.

Each attribute names the intermediate results it needs ("params": time/arc length from the
kernel; "velocity": the field sampled at the vertices; "curl": the vorticity, from the node curl
at the corners of the vertices' cells (fields/curl.py); "seed": the seed of each vertex).
:func:`compute` builds each intermediate at most once, and only for the attributes asked for;
any other name is a scalar field of the Field.
"""

from __future__ import annotations

import numpy as np

from ..fields import Field
from ..fields.bricks import GROUP_BYTES, by_bricks, read_whole
from ..fields.curl import CURL_REACH, vorticity_at

# name -> intermediates it needs
ATTRIBUTES = {
    "time": ("params",),
    "arc_length": ("params",),
    "speed": ("velocity",),
    "velocity": ("velocity",),
    "vorticity": ("curl",),
    "vorticity_magnitude": ("curl",),
    "distance_to_seed": ("seed",),
}


def units(field: Field, names) -> dict[str, str]:
    """CF units of the attributes ``names`` traced in ``field``, where the field's units give
    them: time in s (when the vector is a length per second in the grid's length), arc length and
    distance to the seed in the grid's length unit, speed and velocity in the vector's unit,
    vorticity in the vector's unit per length ("1/s" for m/s on a grid in m), scalars as the
    file states.  Attributes whose units are not known are left out."""
    vec, length = field.units.get(field.vector_name), field.length_units
    per = _per_second(vec)
    if per is not None and length is not None and per != length:
        per = None  # a velocity in another length unit than the grid's: time is not in s
    derived = {"time": "s" if per is not None else None,
               "arc_length": length, "distance_to_seed": length,
               "speed": vec, "velocity": vec,
               "vorticity": _per_length(vec, length), "vorticity_magnitude": _per_length(vec, length)}
    out = {}
    for n in names:
        u = derived.get(n) if n in ATTRIBUTES else field.units.get(n)
        if u:
            out[n] = u
    return out


def metadata(field: Field, names) -> dict:
    """Lines.attrs entries that carry units and time: ``units`` (JSON of ``units``; the lines
    file writes them as CF ``units`` on each attribute), ``length_units`` (positions) and
    ``snapshot_time`` (the field's time, when known; ``time_origin`` where times are dates)."""
    import json

    out = {}
    u = units(field, names)
    if u:
        out["units"] = json.dumps(u)
    if field.length_units:
        out["length_units"] = field.length_units
    if field.time is not None:
        out["snapshot_time"] = float(field.time)
    if field.time_origin:
        out["time_origin"] = field.time_origin
    return out


def _per_second(u: str | None) -> str | None:
    """The length unit of a velocity unit ("m/s", "m s-1", "m.s^-1" -> "m"), else None."""
    if not u:
        return None
    t = u.replace("^", "").replace(".", " ").strip()
    for tail in ("/s", " s-1", "/ s"):
        if t.endswith(tail) and t[: -len(tail)].strip():
            return t[: -len(tail)].strip()
    return None


def _per_length(vec: str | None, length: str | None) -> str | None:
    if not vec or not length:
        return None
    if _per_second(vec) == length:
        return "1/s"
    return f"({vec})/{length}"


def check(field: Field, names) -> None:
    """Raise a clear error for a name that is neither a known attribute nor a scalar field."""
    for n in names:
        if n not in ATTRIBUTES and n not in field.scalars:
            have = ", ".join(list(ATTRIBUTES) + sorted(field.scalars))
            raise KeyError(f"{field.source}: unknown attribute '{n}' (available: {have})")


def norm(v: np.ndarray) -> np.ndarray:
    """Length of each row of ``v`` (n, 3): ``np.linalg.norm(v, axis=1)`` to the bit (the same
    sum of squares in the same order), a sixth of its time (numpy reduces a 3-long axis
    slowly: ~1 ms on the viewer's 59k vertices)."""
    x, y, z = np.asarray(v).T
    return np.sqrt((x * x + y * y) + z * z)


def from_field(names) -> list[str]:
    """The attributes of ``names`` read from the field (not from the trace or the seeds)."""
    return [n for n in names if n not in ("time", "arc_length", "distance_to_seed")]


def compute(field: Field, names, points, t, s, seeds_per_vertex,
            bricked: bool = False, pool=None, budget: int = GROUP_BYTES) -> dict[str, np.ndarray]:
    """Attributes ``names`` at the vertices ``points`` (N, 3).  A large field not in memory
    (any, where ``bricked``: the trace read it brick by brick) is read near the vertices only,
    a few bricks at a time (``bricks.by_bricks``, with its ``pool`` and ``budget``)."""
    check(field, names)
    sampled = from_field(names)
    scalars = [n for n in sampled if n not in ATTRIBUTES]
    whole = read_whole(field) and all(read_whole(field, n) for n in scalars)
    # (no vertex: by_bricks would give no array, and the samplers give empty ones)
    if sampled and len(points) and (bricked or not whole):
        # every sampled attribute from one read of the bricks near the vertices
        halo = CURL_REACH if any(ATTRIBUTES.get(n) == ("curl",) for n in sampled) else 0
        out = by_bricks(field, points, lambda f, p: compute(f, sampled, p, None, None, None),
                        scalars, halo, budget, pool)
        rest = compute(field, [n for n in names if n not in out], points, t, s, seeds_per_vertex)
        return {n: out[n] if n in out else rest[n] for n in names}
    cache: dict[str, np.ndarray] = {}
    scalars: dict[str, np.ndarray] = {}  # scalar fields sampled with the velocity
    first = next((n for n in names if n not in ATTRIBUTES), None)
    if first is not None and any(ATTRIBUTES.get(n) == ("velocity",) for n in names):
        # both in one pass: each vertex located once
        cache["velocity"], scalars[first], _ = field.sample_with(first, points)

    def velocity():
        if "velocity" not in cache:
            cache["velocity"] = field.sample(points)[0]
        return cache["velocity"]

    def vorticity():
        if "vorticity" not in cache:
            cache["vorticity"] = vorticity_at(field, points)
        return cache["vorticity"]

    out = {}
    for n in names:
        if n == "time":
            out[n] = t
        elif n == "arc_length":
            out[n] = s
        elif n == "speed":
            out[n] = norm(velocity())
        elif n == "velocity":
            out[n] = velocity()
        elif n == "vorticity":
            out[n] = vorticity()
        elif n == "vorticity_magnitude":
            out[n] = norm(vorticity())
        elif n == "distance_to_seed":
            out[n] = norm(points - seeds_per_vertex)
        else:
            out[n] = scalars[n] if n in scalars else field.sample_scalar(n, points)[0]
    return out
