"""How much faster lines in lock-step could be: a bare RK4 that advances W lines side by side
(one stage of all of them at a time, so that LLVM vectorizes the lane loop with gathers and the
corner loads of different lines overlap) next to flowkit's rk4 on the ABC benchmark problem.

The probe does only what an interior step needs (no cell cache, no boundary or NaN handling, a
fixed number of steps, no vertex output), so its times are a bound for a lock-step kernel, not a
kernel; its end points are compared with flowkit's to show it does the same arithmetic.
Its figures are in benchmarks/results/integrator_run_history.md ("lines in lock-step for
fixed-step methods"); flowkit's own lock-step (lanes.py) is now vector code too.

    .venv/bin/python benchmarks/lockstep_probe.py [--nodes-per-period 128] [--step 0.1]
"""

from __future__ import annotations

import argparse
import time

import common as C  # run as a script: benchmarks/ is on sys.path
import numpy as np
from numba import njit, prange

from flowkit import trace
from flowkit.integrate.kernel import _prefetch


@njit(inline="always")
def _cell(c0, inv, nm2, x):
    return min(max(int((x - c0) * inv), 0), nm2)


@njit(inline="always")
def _velocity(flat, ny, nz, c0, inv, nm2, x, y, z):
    """Unit velocity (arc-length parameter) of the trilinear field at (x, y, z)."""
    fx, fy, fz = (x - c0) * inv, (y - c0) * inv, (z - c0) * inv
    i, j, k = _cell(c0, inv, nm2, x), _cell(c0, inv, nm2, y), _cell(c0, inv, nm2, z)
    tx, ty, tz = fx - i, fy - j, fz - k
    b = ((i * ny + j) * nz + k) * 3
    di, dj = ny * nz * 3, nz * 3
    ux, uy, uz = 1.0 - tx, 1.0 - ty, 1.0 - tz
    w0, w1, w2, w3 = ux * uy * uz, tx * uy * uz, ux * ty * uz, tx * ty * uz
    w4, w5, w6, w7 = ux * uy * tz, tx * uy * tz, ux * ty * tz, tx * ty * tz
    u = (w0 * flat[b] + w1 * flat[b + di] + w2 * flat[b + dj] + w3 * flat[b + di + dj]
         + w4 * flat[b + 3] + w5 * flat[b + di + 3] + w6 * flat[b + dj + 3]
         + w7 * flat[b + di + dj + 3])
    v = (w0 * flat[b + 1] + w1 * flat[b + di + 1] + w2 * flat[b + dj + 1]
         + w3 * flat[b + di + dj + 1] + w4 * flat[b + 4] + w5 * flat[b + di + 4]
         + w6 * flat[b + dj + 4] + w7 * flat[b + di + dj + 4])
    s = (w0 * flat[b + 2] + w1 * flat[b + di + 2] + w2 * flat[b + dj + 2]
         + w3 * flat[b + di + dj + 2] + w4 * flat[b + 5] + w5 * flat[b + di + 5]
         + w6 * flat[b + dj + 5] + w7 * flat[b + di + dj + 5])
    r = 1.0 / np.sqrt(u * u + v * v + s * s)
    return u * r, v * r, s * r


@njit(parallel=True)
def lockstep_rk4(flat, ny, nz, c0, inv, nm2, seeds, h, n_steps, lanes, prefetch, out):
    n = seeds.shape[0]
    for g in prange((n + lanes - 1) // lanes):
        P = np.empty((3, lanes))
        K = np.empty((4, 3, lanes))
        for w in range(lanes):
            for a in range(3):
                P[a, w] = seeds[min(g * lanes + w, n - 1), a]
        for _ in range(n_steps):
            for st in range(4):
                cc = 0.0 if st == 0 else (0.5 if st < 3 else 1.0)
                if prefetch:  # request every lane's cell before any lane needs it
                    for w in range(lanes):
                        x = P[0, w] + cc * h * K[st - 1, 0, w] if st else P[0, w]
                        y = P[1, w] + cc * h * K[st - 1, 1, w] if st else P[1, w]
                        z = P[2, w] + cc * h * K[st - 1, 2, w] if st else P[2, w]
                        b = ((_cell(c0, inv, nm2, x) * ny + _cell(c0, inv, nm2, y)) * nz
                             + _cell(c0, inv, nm2, z)) * 3
                        for off in (0, ny * nz * 3, nz * 3, ny * nz * 3 + nz * 3):
                            _prefetch(flat, b + off)
                            _prefetch(flat, b + off + 5)
                for w in range(lanes):
                    x = P[0, w] + cc * h * K[st - 1, 0, w] if st else P[0, w]
                    y = P[1, w] + cc * h * K[st - 1, 1, w] if st else P[1, w]
                    z = P[2, w] + cc * h * K[st - 1, 2, w] if st else P[2, w]
                    K[st, 0, w], K[st, 1, w], K[st, 2, w] = _velocity(flat, ny, nz, c0, inv, nm2,
                                                                      x, y, z)
            for a in range(3):
                for w in range(lanes):
                    P[a, w] += h / 6.0 * (K[0, a, w] + 2.0 * K[1, a, w] + 2.0 * K[2, a, w]
                                          + K[3, a, w])
        for w in range(lanes):
            if g * lanes + w < n:
                for a in range(3):
                    out[g * lanes + w, a] = P[a, w]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nodes-per-period", type=int, default=128)
    ap.add_argument("--step", type=float, default=0.1)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    pb = C.Problem(nodes_per_period=a.nodes_per_period)
    f = C.abc_field(pb)
    seeds = C.make_seeds(pb)
    n = f.vector.shape[0]
    flat = f.vector.reshape(-1)
    steps = round(pb.length / a.step)
    out = np.empty((len(seeds), 3))
    print(f"machine: {C.machine()}")
    print(f"ABC {n}^3 nodes, {len(seeds)} seeds, rk4 arc-length step {a.step}, {steps} steps")

    def best(fn):
        fn()  # compile / warm
        ts = []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return min(ts)

    lines = []

    def flowkit_rk4():
        lines[:] = [trace(f, seeds, method="rk4", step=a.step, cell_aware=False,
                          parameter="arc_length", max_length=pb.length)]

    t_fk = best(flowkit_rk4)
    L = lines[0]
    end = L.points[L.offsets[1:] - 1]
    print(f"flowkit rk4 (trace, all host work)  {t_fk:.4f} s")
    for lanes, pf in ((1, False), (8, False), (32, False), (32, True)):
        t = best(lambda lanes=lanes, pf=pf: lockstep_rk4(flat, n, n, 0.0, 1.0 / pb.spacing,
                                                         n - 2, seeds, a.step, steps, lanes, pf,
                                                         out))
        diff = np.abs(out - end).max()
        print(f"probe, {lanes:2d} lanes{', prefetch' if pf else '          '}  {t:.4f} s  "
              f"{t * 2e9 / (len(seeds) * steps):6.1f} ns per step per core  flowkit / probe "
              f"{t_fk / t:.2f}  max end-point difference {diff:.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
