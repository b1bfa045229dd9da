"""Per-vertex attributes added to lines already traced: ``flowkit.sample``.

A pipeline that traced once and later needs vorticity, or another snapshot's temperature along
the same lines, samples them onto the vertices instead of tracing again.  The values are the
ones a trace computes (``attributes.compute``: the same trilinear sampling and node curl), so
an attribute sampled from the field the lines were traced in equals the traced one bit for bit
at the same vertices.  A vertex outside the field (another grid) or in a NaN cell gets NaN, and
the lines' metadata says how many.
"""

from __future__ import annotations

import json

import numpy as np

from ..fields import Field
from ..lines import Lines
from . import attributes as _attributes

# attributes that come from the integration, not from the field at a vertex
INTEGRATED = {"time": "integration time is a property of the trace, not of the field at a vertex",
              "arc_length": "arc length accumulates along the trace: Lines.arc_length() gives "
                            "each line's, or trace again with it"}


def sample(lines: Lines, field: Field, attributes, *, rename: dict | None = None,
           seeds=None) -> Lines:
    """``lines`` with the per-vertex ``attributes`` (speed, velocity, vorticity,
    vorticity_magnitude, distance_to_seed, or scalar fields of ``field``) sampled from ``field``
    at their vertices; ``rename`` maps an attribute to the name it gets (e.g.
    ``{"T": "T_1200s"}`` for another snapshot's T).  distance_to_seed needs each line's seed:
    the lines' own (line data ``seed``, as evenly spaced seeding keeps them) or ``seeds``, the
    (n, 3) points the lines were traced from (line data ``seed_id`` indexes them).  The points
    and the other attributes are shared, not copied.  ``attrs["sampled"]`` records, per new
    name, the source and how many of its vertices are NaN (outside the field, or in a NaN
    cell)."""
    names = [attributes] if isinstance(attributes, str) else list(attributes)
    rename = dict(rename or {})
    for n in names:
        if n in INTEGRATED:
            raise ValueError(f"cannot sample '{n}' onto lines: {INTEGRATED[n]}")
    unknown = set(rename) - set(names)
    if unknown:
        raise ValueError(f"rename names {', '.join(sorted(unknown))}, which are not sampled "
                         f"(sampled: {', '.join(names)})")
    _attributes.check(field, names)
    seed_of = None
    if "distance_to_seed" in names:
        seed_of = _seed_per_vertex(lines, seeds)
    elif seeds is not None:
        raise ValueError("seeds are for 'distance_to_seed', which is not sampled")
    points = np.ascontiguousarray(lines.points, dtype=np.float64)
    new = _attributes.compute(field, names, points, None, None, seed_of)
    out_names = {n: rename.get(n, n) for n in names}
    point_data, outside = dict(lines.point_data), {}
    for n, v in new.items():
        point_data[out_names[n]] = v
        nan = np.isnan(v) if v.ndim == 1 else np.isnan(v).any(axis=1)
        outside[out_names[n]] = {"source": field.source, "nan": int(np.count_nonzero(nan))}
    units = lines.units
    units.update({out_names[n]: u for n, u in _attributes.units(field, names).items()})
    attrs = dict(lines.attrs)
    if units:
        attrs["units"] = json.dumps(units)
    previous = json.loads(attrs["sampled"]) if isinstance(attrs.get("sampled"), str) else {}
    attrs["sampled"] = json.dumps({**previous, **outside})
    return Lines(lines.points, lines.offsets, point_data, lines.line_data, attrs)


def _seed_per_vertex(lines: Lines, seeds) -> np.ndarray:
    """The seed of every vertex's line, (N, 3): from the lines' own seeds, else from ``seeds``
    indexed by line data ``seed_id``."""
    if "seed" in lines.line_data:
        return np.repeat(lines.line_data["seed"], lines.n_vertices, axis=0)
    if seeds is None:
        raise ValueError("cannot sample 'distance_to_seed': these lines do not carry their "
                         "seeds (line data 'seed'); pass the points they were traced from "
                         "(seeds=), or trace with it")
    seeds = np.asarray(seeds, dtype=np.float64)
    ids = lines.line_data.get("seed_id")
    if seeds.ndim != 2 or seeds.shape[1] != 3:
        raise ValueError(f"seeds must be the (n, 3) points the lines were traced from, got "
                         f"shape {seeds.shape}")
    if ids is None:
        raise ValueError("these lines have no line data 'seed_id' to find their seeds in seeds=")
    if len(ids) and not (0 <= ids.min() and ids.max() < len(seeds)):
        raise ValueError(f"seed_id runs to {ids.max()}, but seeds= has {len(seeds)} points: "
                         "not the seeds these lines were traced from")
    return seeds[np.repeat(ids, lines.n_vertices)]


def nan_counts(lines: Lines) -> dict[str, int]:
    """Per sampled attribute, its NaN vertices: outside the field or in a NaN cell."""
    s = lines.attrs.get("sampled")
    return {k: int(v["nan"]) for k, v in (json.loads(s) if isinstance(s, str) else {}).items()}
