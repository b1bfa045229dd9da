"""Similarity pruning: after tracing, drop each line that runs within ``distance`` of a longer
line along most of its length (``fraction`` of its vertices), longest lines first, so a line is
only ever removed in favour of one that is kept.

What was removed, and why, goes into the lines' run metadata (stored in the lines file and
shown by ``flowkit info``): ``prune_distance``, ``prune_fraction``, and per removed line its
``pruned_seed_id``, the seed_id of the kept line it ran beside (``pruned_by``) and the share of
its vertices within the distance of kept lines (``pruned_covered``).  Distances come from the
same spatial hash as evenly spaced seeding (minimum image on periodic axes).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..lines import Lines
from .even import X, Y, Z, _diff, _span, _Store


@njit(cache=True)
def _nearest_owner(geo, head, nxt, pts, owner, query, r):
    """Owner of the nearest hashed vertex within r of each query point (-1: none)."""
    out = np.full(query.shape[0], -1, np.int64)
    n0, n1, n2 = int(geo[2, 0]), int(geo[2, 1]), int(geo[2, 2])
    for n in range(query.shape[0]):
        p = query[n]
        best = r * r
        i0, ni, _ = _span(p[0], r, geo, X)
        j0, nj, _ = _span(p[1], r, geo, Y)
        k0, nk, _ = _span(p[2], r, geo, Z)
        for di in range(ni):
            for dj in range(nj):
                for dk in range(nk):
                    c = (((i0 + di) % n0) * n1 + (j0 + dj) % n1) * n2 + (k0 + dk) % n2
                    v = head[c]
                    while v >= 0:
                        d2 = 0.0
                        for a in range(3):
                            d2 += _diff(p, pts[v], geo, a) ** 2
                        if d2 < best:
                            best = d2
                            out[n] = owner[v]
                        v = nxt[v]
    return out


def arc_lengths(lines: Lines) -> np.ndarray:
    """Polyline length of every line."""
    seg = np.linalg.norm(np.diff(lines.points, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    return cum[lines.offsets[1:] - 1] - cum[lines.offsets[:-1]] if len(lines) else np.zeros(0)


def prune(lines: Lines, distance: float, fraction: float = 0.8, period=None) -> Lines:
    """``lines`` without those lying within ``distance`` of a longer kept line along at least
    ``fraction`` of their vertices; the record of what went is in the result's ``attrs``.
    ``period``: (3,) periods of the field's axes (0: bounded), for lines of periodic fields."""
    if not (np.isfinite(distance) and distance > 0):
        raise ValueError(f"prune: distance must be a positive length, got {distance!r}")
    if not 0 < fraction <= 1:
        raise ValueError(f"prune: fraction must lie in (0, 1], got {fraction!r}")
    period = np.zeros(3) if period is None else np.asarray(period, np.float64)
    ids = lines.line_data.get("seed_id", np.arange(len(lines)))
    order = np.argsort(-arc_lengths(lines), kind="stable")
    b = lines.bounds()
    for a in range(3):
        if period[a] > 0:
            b[a] = [0.0, period[a]]
    pad = np.where(period > 0, 0.0, distance)
    bounds = np.stack([b[:, 0] - pad, b[:, 1] + pad], axis=1)
    hashed = _Store(bounds, period, distance)
    keep = np.zeros(len(lines), bool)
    removed, by, covered = [], [], []
    for i in order:
        p = np.ascontiguousarray(lines.line_points(i), np.float64)
        near = (_nearest_owner(*hashed.hashed[:5], p, float(distance)) if len(p) else
                np.zeros(0, np.int64))
        share = float(np.mean(near >= 0)) if len(p) else 1.0
        if len(p) and share >= fraction:
            removed.append(int(ids[i]))
            by.append(int(ids[np.bincount(near[near >= 0]).argmax()]))
            covered.append(share)
            continue
        keep[i] = True
        hashed.add(p, i, np.zeros(len(p)))
    out = lines[keep]
    out.attrs.update(prune_distance=float(distance), prune_fraction=float(fraction),
                     pruned_seed_id=np.array(removed, np.int64),
                     pruned_by=np.array(by, np.int64), pruned_covered=np.array(covered))
    return out


def parse_prune(text: str) -> tuple[float, float]:
    """``DIST[:FRACTION]`` (the CLI's --prune) -> (distance, fraction; default 0.8)."""
    dist, _, frac = str(text).partition(":")
    try:
        d = float(dist)
        f = float(frac) if frac else 0.8
    except ValueError:
        d = f = float("nan")
    if not (np.isfinite(d) and d > 0 and 0 < f <= 1):
        raise ValueError(f"--prune {text!r}: expected DIST[:FRACTION], a positive distance and a "
                         "fraction in (0, 1] (default 0.8)")
    return d, f
