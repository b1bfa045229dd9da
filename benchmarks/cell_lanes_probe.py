"""How much faster cell-aware dopri5 could be in lock-step: a bare lock-step of W lines, every
step ending on a cell face (the ``faces`` stepping of docs/integrator.md), next to flowkit's
scalar kernel doing the same work on the ABC benchmark problem, one thread each.

The probe does what an interior cell-aware step needs and nothing else: the step capped at 1.25
times the straight-line exit time, the stages from the polynomial of the cell the step starts
in (one loop over the lanes per stage: vector code), the embedded error and an I controller, and
for an accepted step that leaves its cell the face crossing on the dense output (flowkit's own
``_root`` and ``_dense``), the move into the neighbour cell and its gather, one lane at a time.
No boundary, NaN, stagnation or output handling: a line stops at its arc length or when it
leaves the domain.  So its time per step is a bound for a lock-step kernel, not a kernel; its
step counts are compared with flowkit's to show it does the same work.

    .venv/bin/python benchmarks/cell_lanes_probe.py [--nodes-per-period 64] [--rtol 1e-6]
"""

from __future__ import annotations

import argparse
import math
import time

import common as C  # run as a script: benchmarks/ is on sys.path
import numba
import numpy as np
from numba import njit

from flowkit import trace
from flowkit.integrate.kernel import _dense, _root
from flowkit.integrate.methods import METHODS
from flowkit.jit import prefetch

W = 32  # lanes


@njit(inline="always")
def _gather(vec, i, j, k, coef, w):
    for c in range(3):
        v000, v100 = vec[i, j, k, c], vec[i + 1, j, k, c]
        v010, v110 = vec[i, j + 1, k, c], vec[i + 1, j + 1, k, c]
        v001, v101 = vec[i, j, k + 1, c], vec[i + 1, j, k + 1, c]
        v011, v111 = vec[i, j + 1, k + 1, c], vec[i + 1, j + 1, k + 1, c]
        coef[0, c, w] = v000
        coef[1, c, w] = v100 - v000
        coef[2, c, w] = v010 - v000
        coef[3, c, w] = v001 - v000
        coef[4, c, w] = v110 - v100 - v010 + v000
        coef[5, c, w] = v101 - v100 - v001 + v000
        coef[6, c, w] = v011 - v010 - v001 + v000
        coef[7, c, w] = v111 - v110 - v101 - v011 + v100 + v010 + v001 - v000


@njit(inline="always")
def _poly(coef, c, w, tx, ty, tz):
    return (coef[0, c, w] + tx * (coef[1, c, w] + ty * (coef[4, c, w] + tz * coef[7, c, w])
                                  + tz * coef[5, c, w])
            + ty * (coef[2, c, w] + tz * coef[6, c, w]) + tz * coef[3, c, w])


@njit(inline="always")
def _eval(coef, lo, dx_inv, yt, k, st):
    """Stage st of every lane from its cell's polynomial (unit velocity: arc length)."""
    for w in range(W):
        tx = (yt[0, w] - lo[0, w]) * dx_inv
        ty = (yt[1, w] - lo[1, w]) * dx_inv
        tz = (yt[2, w] - lo[2, w]) * dx_inv
        u = _poly(coef, 0, w, tx, ty, tz)
        v = _poly(coef, 1, w, tx, ty, tz)
        s = _poly(coef, 2, w, tx, ty, tz)
        r = 1.0 / math.sqrt(u * u + v * v + s * s)
        k[st, 0, w] = u * r
        k[st, 1, w] = v * r
        k[st, 2, w] = s * r


@njit
def probe(seeds, c0, dx, n, vec, a, b, e, mp, rtol, atol, length, h0):
    """Trace every seed to arc length ``length``; returns (steps accepted, rejected, ends)."""
    dx_inv = 1.0 / dx
    ns, q = b.size, mp.shape[1]
    nl = seeds.shape[0]
    y, yt, y1 = np.zeros((3, W)), np.zeros((3, W)), np.zeros((3, W))
    lo, hi = np.zeros((3, W)), np.zeros((3, W))
    cell = np.zeros((3, W), np.int64)
    k = np.zeros((ns, 3, W))
    coef = np.zeros((8, 3, W))
    s, h, err, hs = np.zeros(W), np.zeros(W), np.zeros(W), np.zeros(W)
    line = np.full(W, -1, np.int64)
    qd = np.zeros((4, q))
    ends = np.full((nl, 3), np.nan)
    n_acc = n_rej = 0
    nxt = 0
    moved = np.zeros(W, np.int64)
    flat = vec.reshape(-1)
    ny, nz = vec.shape[1], vec.shape[2]
    di, dj = ny * nz * 3, nz * 3
    while True:
        n_live = 0
        for w in range(W):  # a lane whose line ended takes the next one
            if line[w] < 0 and nxt < nl:
                line[w] = nxt
                for ax in range(3):
                    y[ax, w] = seeds[nxt, ax]
                    cell[ax, w] = min(max(int((y[ax, w] - c0) * dx_inv), 0), n - 2)
                    lo[ax, w] = c0 + cell[ax, w] * dx
                    hi[ax, w] = lo[ax, w] + dx
                _gather(vec, cell[0, w], cell[1, w], cell[2, w], coef, w)
                for ax in range(3):
                    yt[ax, w] = y[ax, w]
                s[w], h[w] = 0.0, h0
                nxt += 1
            n_live += line[w] >= 0
        if n_live == 0:
            break
        _eval(coef, lo, dx_inv, y, k, 0)  # (k0 of a new line; recomputed for all: cheap)
        # a lane on a face of its cell, moving out (an edge or corner after a face crossing):
        # into the neighbour cell first (flowkit's _onto_next_cell), k0 there
        again = False
        for w in range(W):
            for ax in range(3):
                mv = k[0, ax, w]
                up = y[ax, w] >= hi[ax, w] and mv > 0.0
                if line[w] >= 0 and (up or (y[ax, w] <= lo[ax, w] and mv < 0.0)):
                    i = cell[ax, w] + (1 if up else -1)
                    if i < 0 or i > n - 2:
                        line[w] = -1
                        break
                    cell[ax, w] = i
                    lo[ax, w] = c0 + i * dx
                    hi[ax, w] = lo[ax, w] + dx
                    _gather(vec, cell[0, w], cell[1, w], cell[2, w], coef, w)
                    again = True
        if again:
            _eval(coef, lo, dx_inv, y, k, 0)
        # the step: the controller's, capped at 1.25 x the straight-line exit, clipped at the end
        for w in range(W):
            te = np.inf
            for ax in range(3):
                mv = k[0, ax, w]
                if mv > 0.0:
                    te = min(te, (hi[ax, w] - y[ax, w]) / mv)
                elif mv < 0.0:
                    te = min(te, (y[ax, w] - lo[ax, w]) / -mv)
            hs[w] = min(h[w], 1.25 * te, length - s[w])
        for st in range(1, ns):
            for ax in range(3):
                for w in range(W):
                    acc = 0.0
                    for m in range(st):
                        acc += a[st, m] * k[m, ax, w]
                    yt[ax, w] = y[ax, w] + hs[w] * acc
            _eval(coef, lo, dx_inv, yt, k, st)
        for w in range(W):  # (dopri5: stage 6 is at y1, so y1 = that stage point)
            e2 = 0.0
            for ax in range(3):
                y1[ax, w] = yt[ax, w]
                acc = 0.0
                for m in range(ns):
                    acc += e[m] * k[m, ax, w]
                sc = atol + rtol * max(abs(y[ax, w]), abs(y1[ax, w]))
                e2 += (acc / sc) ** 2
            err[w] = hs[w] * math.sqrt(e2 / 3.0)
        for w in range(W):  # one lane at a time: control, faces, moves
            if line[w] < 0:
                continue
            if err[w] > 1.0:
                n_rej += 1
                h[w] = hs[w] * max(0.2, 0.9 * err[w] ** -0.2)
                continue
            n_acc += 1
            h[w] = hs[w] * min(10.0, max(0.2, 0.9 * err[w] ** -0.2)) if err[w] > 0 else 10 * hs[w]
            th, axis, face, up = 1.0, -1, 0.0, False
            out = False
            for ax in range(3):
                out |= y1[ax, w] < lo[ax, w] or y1[ax, w] > hi[ax, w]
            if out:
                for ax in range(3):
                    for j in range(q):
                        acc = 0.0
                        for m in range(ns):
                            acc += mp[m, j] * k[m, ax, w]
                        qd[ax, j] = acc
                for ax in range(3):
                    if y1[ax, w] > hi[ax, w]:
                        t = _root(qd, ax, q, y[ax, w], hs[w], hi[ax, w], 1.0, 1.0)
                        if axis < 0 or t < th:
                            th, axis, face, up = t, ax, hi[ax, w], True
                    elif y1[ax, w] < lo[ax, w]:
                        t = _root(qd, ax, q, y[ax, w], hs[w], lo[ax, w], -1.0, 1.0)
                        if axis < 0 or t < th:
                            th, axis, face, up = t, ax, lo[ax, w], False
                for ax in range(3):
                    y[ax, w] = _dense(qd, ax, q, y[ax, w], hs[w], th)
                y[axis, w] = face
                s[w] += th * hs[w]
                i = cell[axis, w] + (1 if up else -1)
                if i < 0 or i > n - 2:
                    line[w] = -1  # left the domain
                    continue
                cell[axis, w] = i
                lo[axis, w] = c0 + i * dx
                hi[axis, w] = lo[axis, w] + dx
                moved[w] = 1
                b0 = ((cell[0, w] * ny + cell[1, w]) * nz + cell[2, w]) * 3
                for off in (0, di, dj, di + dj):  # every moved lane's cell asked for first
                    prefetch(flat, b0 + off)
                    prefetch(flat, b0 + off + 5)
            else:
                for ax in range(3):
                    y[ax, w] = y1[ax, w]
                s[w] += hs[w]
            if s[w] >= length * (1 - 1e-12):
                for ax in range(3):
                    ends[line[w], ax] = y[ax, w]
                line[w] = -1
        for w in range(W):  # then the gathers, their misses overlapping
            if moved[w]:
                moved[w] = 0
                _gather(vec, cell[0, w], cell[1, w], cell[2, w], coef, w)
    return n_acc, n_rej, ends


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nodes-per-period", type=int, default=64)
    ap.add_argument("--seeds", type=int, default=2000)
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    p = C.Problem(nodes_per_period=a.nodes_per_period, n_seeds=a.seeds)
    field = C.abc_field(p)
    seeds = C.make_seeds(p)
    m = METHODS["dopri5"]
    _c, A, B, E, _e2, P, _ints = m.kernel_arrays()
    vec = np.ascontiguousarray(field.vector)
    axis = field.grid.axes[0]
    dx = float(axis[1] - axis[0])
    numba.set_num_threads(1)
    opts = {"rtol": a.rtol, "atol": a.rtol, "max_length": p.length, "cross_faces": False}
    lines = trace(field, seeds, **opts)
    fk_steps = int(lines.line_data["n_accepted"].sum()), int(lines.line_data["n_rejected"].sum())
    args = (seeds, float(axis[0]), dx, axis.size, vec, A, B, E, P, a.rtol, a.rtol, p.length,
            0.1 * dx)
    acc, rej, ends = probe(*args)
    tf, tp = [], []
    for _ in range(a.repeat):
        t0 = time.process_time()
        trace(field, seeds, **opts)
        t1 = time.process_time()
        probe(*args)
        tp.append(time.process_time() - t1)
        tf.append(t1 - t0)
    done = np.isfinite(ends[:, 0])
    fin = lines.points[lines.offsets[1:] - 1]
    diff = np.abs(ends[done] - fin[done]).max() if done.any() else np.nan
    print(f"ABC {field.grid.shape[0]}^3, {a.seeds} seeds, arc length {p.length}, dopri5 rtol "
          f"= atol = {a.rtol:g}, every step ending on a face, one thread, best of {a.repeat} "
          f"(process time)")
    for name, t, (na, nr) in (("flowkit scalar kernel", min(tf), fk_steps),
                              (f"lock-step probe, {W} lanes", min(tp), (acc, rej))):
        print(f"  {name:26s} {t * 1e3:8.1f} ms  {na + nr:8d} steps ({nr / (na + nr):.1%} "
              f"rejected)  {t / (na + nr) * 1e9:6.0f} ns/step")
    print(f"  probe / flowkit: {min(tp) / min(tf):.2f} of the time; ends of the {done.sum()} lines "
          f"that reached the arc length agree to {diff:.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
