"""numba against OpenCL (here: PoCL on the CPU) on identical work, in one process.

    .venv/bin/python benchmarks/bench_opencl.py [--seeds 2000] [--nodes 32] [--quick]

Work: ABC flow on a bounded grid of 3 periods (``--nodes`` cells per period), seeds from
benchmarks/common.py (lines that stay inside), dopri5 at rtol 1e-6, arc length 10; then the heated
room (built-in data), 2000 random seeds, length 20.  For each backend: wall time (after a warm-up
that compiles), vertices/s and steps/s (accepted + rejected), the ratio to numba, and the largest
vertex difference to the numba lines (float64 must be ~0).  Then the per-vertex attributes
(speed, vorticity, T on the room): numba (host attributes), OpenCL with the attributes computed
on the host from the read-back vertices (``kernel_attributes=False``, the path before they moved
into the kernel) and OpenCL computing them in the kernel; each against the same backend without
attributes, so the attribute cost is a difference of walls measured in this run.  Then what
overlaps on this device: the copies of each chunk against the kernels of the others, from
OpenCL profiling events.  Also the image3d path's field error:
hardware-filtered samples against exact trilinear interpolation, and what 8-bit filter weights
(NVIDIA's texture units) would add, emulated.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common as C

import flowkit
from flowkit import datasets
from flowkit.integrate.opencl.backend import OpenCLAdvance, field_image
from flowkit.integrate.seeds import random_in


def run(field, seeds, backend, **kw):
    flowkit.trace(field, seeds[:8], backend=backend, **kw)  # warm-up: compiles
    t0 = time.perf_counter()
    lines = flowkit.trace(field, seeds, backend=backend, **kw)
    return lines, time.perf_counter() - t0


def compare(name, field, seeds, backends, **kw):
    print(f"\n## {name}: {len(seeds)} seeds, {field.grid.shape} nodes, "
          + ", ".join(f"{k}={v}" for k, v in kw.items()))
    print("| backend | wall s | vertices | steps | vertices/s | steps/s | x numba | max |dx| to numba |")
    print("|---|---|---|---|---|---|---|---|")
    base = ref = None
    for label, be in backends:
        lines, dt = run(field, seeds, be, **kw)
        steps = int(lines.line_data["n_accepted"].sum() + lines.line_data["n_rejected"].sum())
        if ref is None:
            ref, base = lines, dt
        same = np.array_equal(lines.offsets, ref.offsets)
        dx = f"{np.abs(lines.points - ref.points).max():.2e}" if same else "(other vertex counts)"
        print(f"| {label} | {dt:.2f} | {lines.n_points} | {steps} | {lines.n_points / dt:.3g} | "
              f"{steps / dt:.3g} | {base / dt:.2f} | {dx} |")


def attribute_cost(field, seeds, attrs, repeat=3, **kw):
    """Wall with and without ``attrs`` for numba, OpenCL with host attributes, OpenCL with kernel
    attributes (same vertices), best of ``repeat``: the attribute cost of each path, measured here."""
    print(f"\n## attributes {', '.join(attrs)}: {len(seeds)} seeds, {field.grid.shape} nodes, "
          + ", ".join(f"{k}={v}" for k, v in kw.items()))
    print("| backend | attributes computed | wall s, no attributes | wall s, with | attribute cost s "
          "| cost per vertex | vertices/s with | max rel. attribute diff to numba |")
    print("|---|---|---|---|---|---|---|---|")
    ref = None
    for label, where, be in (("numba (all cores)", "host (numba)", "numba"),
                             ("OpenCL float64", "host (numba)", OpenCLAdvance(kernel_attributes=False)),
                             ("OpenCL float64", "in the kernel", OpenCLAdvance())):
        # best of `repeat` interleaved pairs: the machine is shared, the cost is a difference
        t0 = t1 = np.inf
        for _ in range(repeat):
            t0 = min(t0, run(field, seeds, be, **kw)[1])
            lines, dt = run(field, seeds, be, attributes=attrs, **kw)
            t1 = min(t1, dt)
        if ref is None:
            ref = lines
        diff = max(np.nanmax(np.abs(lines.point_data[a] - ref.point_data[a]))
                   / np.nanmax(np.abs(ref.point_data[a])) for a in attrs)
        print(f"| {label} | {where} | {t0:.2f} | {t1:.2f} | {t1 - t0:.2f} | "
              f"{1e9 * (t1 - t0) / lines.n_points:.0f} ns | {lines.n_points / t1:.3g} | {diff:.1e} |")


def overlap(field, seeds, **kw):
    """From profiling events: how much of the copy time runs while another chunk's kernel runs,
    and how long read-backs start after their kernel ended."""
    adv = OpenCLAdvance(profile=True, chunk=max(1, len(seeds) // 4))
    flowkit.trace(field, seeds[:8], backend=adv, **kw)
    adv.timeline.clear()
    flowkit.trace(field, seeds, backend=adv, **kw)
    ev = [(k, c, e.profile.start * 1e-9, e.profile.end * 1e-9) for k, c, e in adv.timeline]
    runs = {c: (a, b) for k, c, a, b in ev if k == "run"}
    copy = over = 0.0
    delays = []
    for k, c, a, b in ev:
        if k == "run":
            continue
        copy += b - a
        over += sum(max(0.0, min(b, rb) - max(a, ra)) for cc, (ra, rb) in runs.items() if cc != c)
        if k == "down":
            delays.append(a - runs[c][1])
    kern = sum(b - a for a, b in runs.values())
    print(f"\n## overlap on this device ({len(runs)} launches, chunks of {adv.chunk} lines): "
          f"kernels {kern:.3f} s, copies {copy:.3f} s, of which {over:.3f} s "
          f"({100 * over / max(copy, 1e-12):.0f} %) ran while another chunk's kernel ran; "
          f"read-backs started {1e3 * np.median(delays):.1f} ms (median) after their kernel ended")


def image_field_error(field, n=200000, seed=0):
    """Max |image sample - trilinear| / max |v| at random points, and the 8-bit-weight emulation."""
    import pyopencl as cl

    adv = OpenCLAdvance(dtype="float32", image=True)
    ctx, q = adv.ctx, adv.q_run
    prg = cl.Program(ctx, """
    __kernel void s(__read_only image3d_t img, __global const float *c, __global float *o) {
      const sampler_t lin = CLK_NORMALIZED_COORDS_FALSE | CLK_ADDRESS_CLAMP_TO_EDGE | CLK_FILTER_LINEAR;
      int i = get_global_id(0);
      float4 v = read_imagef(img, lin, (float4)(c[3*i] + 0.5f, c[3*i+1] + 0.5f, c[3*i+2] + 0.5f, 0.0f));
      o[3*i] = v.x; o[3*i+1] = v.y; o[3*i+2] = v.z;
    }""").build()
    g = field.grid
    shape = np.array(g.shape)
    rng = np.random.default_rng(seed)
    idx = (rng.random((n, 3)) * (shape - 1)).astype(np.float32)  # texel-index coordinates
    i0 = np.minimum(np.floor(idx).astype(int), shape - 2)
    t = idx.astype(np.float64) - i0
    pts = np.stack([g.axes[a][i0[:, a]] + t[:, a] * (g.axes[a][i0[:, a] + 1] - g.axes[a][i0[:, a]])
                    for a in range(3)], axis=1)
    exact = field.sample(pts)[0]
    img = field_image(ctx, field.vector, g.period)
    cb = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=idx)
    ob = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, idx.nbytes)
    prg.s(q, (n,), None, img, cb, ob)
    got = np.empty_like(idx)
    cl.enqueue_copy(q, got, ob)
    vmax = np.abs(field.vector).max()
    # 8-bit fractional weights: the same trilinear formula with t rounded to 1/256
    t8 = np.round(t * 256) / 256
    pts8 = np.stack([g.axes[a][i0[:, a]] + t8[:, a] * (g.axes[a][i0[:, a] + 1] - g.axes[a][i0[:, a]])
                     for a in range(3)], axis=1)
    emu8 = field.sample(pts8)[0]
    ok = np.all(np.isfinite(exact), axis=1)
    return (np.abs(got - exact)[ok].max() / vmax, np.abs(emu8 - exact)[ok].max() / vmax)


def weights_bits():
    """Precision of this device's linear-filter weights: a 0 -> 1 ramp across one texel sampled at
    random float32 positions t; 8-bit weights would give errors up to 2^-9 and 257 values."""
    import pyopencl as cl

    adv = OpenCLAdvance(dtype="float32", image=True)
    ctx, q = adv.ctx, adv.q_run
    prg = cl.Program(ctx, """
    __kernel void s(__read_only image3d_t img, __global const float *t, __global float *o) {
      const sampler_t lin = CLK_NORMALIZED_COORDS_FALSE | CLK_ADDRESS_CLAMP_TO_EDGE | CLK_FILTER_LINEAR;
      int i = get_global_id(0);
      o[i] = read_imagef(img, lin, (float4)(0.5f + t[i], 0.5f, 0.5f, 0.0f)).x;
    }""").build()
    data = np.zeros((2, 2, 2, 4), np.float32)
    data[:, :, 1, 0] = 1.0
    img = cl.create_image(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                   cl.ImageFormat(cl.channel_order.RGBA, cl.channel_type.FLOAT), shape=(2, 2, 2),
                   hostbuf=data)
    t = np.random.default_rng(0).random(100000).astype(np.float32)
    tb = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=t)
    ob = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, t.nbytes)
    prg.s(q, t.shape, None, img, tb, ob)
    o = np.empty_like(t)
    cl.enqueue_copy(q, o, ob)
    err = np.abs(o.astype(float) - t.astype(float)).max()
    return err, len(np.unique(o)), len(np.unique(t))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2000)
    ap.add_argument("--nodes", type=int, default=32, help="ABC cells per period")
    ap.add_argument("--quick", action="store_true", help="200 seeds, 16 cells per period")
    a = ap.parse_args(argv)
    if a.quick:
        a.seeds, a.nodes = 200, 16
    print(f"# OpenCL backend benchmark — {C.machine()}, load average {os.getloadavg()[0]:.2f}")
    print("(no GPU in this environment: every OpenCL figure below is PoCL on the CPU)")
    ocl = OpenCLAdvance()
    print(f"OpenCL device: {ocl.describe()}")
    print("No GPU was lent to this run: the 1M seeds x 1000 steps GPU goal is not measured here.")
    backends = [("numba (all cores)", "numba"), ("OpenCL float64", ocl),
                ("OpenCL float32", OpenCLAdvance(dtype="float32")),
                ("OpenCL float32 image3d", OpenCLAdvance(dtype="float32", image=True))]
    prob = C.Problem(nodes_per_period=a.nodes, n_seeds=a.seeds)
    abc = C.abc_field(prob)
    seeds = C.make_seeds(prob)
    compare("ABC, 3 periods", abc, seeds, backends, rtol=1e-6, max_length=prob.length,
            parameter="arc_length")
    room = datasets.hotroom()
    rs = random_in(room, a.seeds, seed=1)
    compare("heated room", room, rs, backends, rtol=1e-6, max_length=20.0)
    attribute_cost(room, rs, ("speed", "vorticity", "T"), rtol=1e-6, max_length=20.0)
    overlap(room, rs, rtol=1e-6, max_length=20.0, attributes=("speed", "vorticity", "T"))
    err, levels, npos = weights_bits()
    print(f"\n## image3d linear filtering on this device: max |filtered - t| = {err:.2e} "
          f"({-np.log2(max(err, 2.0 ** -60)):.1f} bits), {levels} distinct values at {npos} positions")
    for name, f in (("ABC", abc), ("heated room", room)):
        e_dev, e8 = image_field_error(f)
        print(f"{name}: max |image - trilinear| / max|v| = {e_dev:.2e} on this device; "
              f"8-bit weights (emulated) would give {e8:.2e}")
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
