"""The OpenCL backend: a drop-in for ``kernel.advance`` that runs the generated kernel on a device.

``OpenCLAdvance(spec)(launch)`` takes the ``launch.Launch`` the numba ``kernel.advance`` takes and
has the same effect on ``sf``, ``si``, ``out_p``, ``out_par`` and ``out_n``: the host driver in
trace.py (vertex budget per line per pass, relaunch of unfinished lines, never truncating) is
shared by both backends.  The active lines are processed in chunks; each chunk's state is packed,
uploaded on one queue, advanced on a second and read back on a third, so that on a device with
copy engines the transfers of one chunk overlap the kernel of the next.  The vertices are read
back once the counts have arrived, on a fourth queue, and only the first max(out_n) slots of each
line (a rectangle of the (lines, budget) buffers), not the whole budget.  The field and the grid
are uploaded once per field.

Per-vertex attributes: ``trace`` asks the backend to ``bind_attributes(field, names)`` and gets a
callable whose kernel also computes them for the vertices it wrote (``vertex.py``), into one
output buffer per attribute that is read back with the positions, into the columns of ``out_par``
after (t, s); the host then only reorders them with the vertices.  Field data an attribute needs
(scalar fields; the stencil table from which the device computes the node curl once per field)
is uploaded only when one asks for it.
"""

from __future__ import annotations

import numpy as np

from .. import schema
from . import codegen, vertex
from .device import select_device, supports_fp64

DEFAULT_CHUNK = 65536  # lines per launch
MIN_SPLIT = 2048  # at or above this many lines, at least two chunks so that copies overlap
# a fixed work-group size: PoCL compiles a kernel per work-group size (a size that followed the
# number of lines would recompile on every pass) and vectorises across the items of a group
LOCAL_SIZE = 64


class OpenCLAdvance:
    """Callable with the signature of ``flowkit.integrate.kernel.advance`` (one ``Launch``).

    spec    "opencl[:PLATFORM[:DEVICE]]"
    dtype   "float64" (default where the device has fp64, else float32) or "float32"
    image   sample the field from an image3d with hardware linear filtering (float32 texels);
            see docs/opencl.md for the error this adds
    kernel_attributes
            compute the per-vertex attributes in the kernel (default); False leaves them to the
            host code of trace (numba/numpy on the read-back vertices), for comparison
    profile record the profiling events of every copy and launch in ``timeline`` as
            (kind "up"/"run"/"down", chunk number, event), to see what overlaps
    """

    n_columns = 0  # attribute columns this callable adds to out_par (see bind_attributes)

    def __init__(self, spec: str = "opencl", dtype: str | None = None, image: bool = False,
                 chunk: int = DEFAULT_CHUNK, local_size: int = LOCAL_SIZE,
                 kernel_attributes: bool = True, profile: bool = False):
        import pyopencl as cl

        self.cl = cl
        self.device = select_device(spec)
        fp64 = supports_fp64(self.device)
        if dtype is None:
            dtype = "float64" if fp64 else "float32"
        if dtype not in ("float64", "float32"):
            raise ValueError(f"OpenCL dtype must be float64 or float32, got {dtype!r}")
        if dtype == "float64" and not fp64:
            raise ValueError(f"OpenCL device {self.device.name.strip()} has no float64 support; "
                             "use dtype='float32'")
        if image and not self.device.image_support:
            raise ValueError(f"OpenCL device {self.device.name.strip()} has no image support")
        self.dtype = np.dtype(dtype)
        self.real = "double" if self.dtype == np.float64 else "float"
        self.image = bool(image)
        self.chunk = int(chunk)
        self.local = int(local_size)
        self.ctx = _context(self.device)
        props = cl.command_queue_properties.PROFILING_ENABLE if profile else 0
        # uploads, runs, downloads of the counts and state, downloads of the vertices
        self.q_up, self.q_run, self.q_down, self.q_back = (
            cl.CommandQueue(self.ctx, self.device, properties=props) for _ in range(4))
        self.timeline = [] if profile else None
        self.kernel_attributes = bool(kernel_attributes)
        self._field = None  # (key arrays, device buffers)
        self._extra = {}  # device data of what attributes need: (kind, id(source)) -> (source, data)
        self.launches = 0

    def describe(self) -> str:
        return (f"{self.device.name.strip()} [{self.device.platform.name.strip()}], {self.dtype.name}"
                + (", image3d" if self.image else ""))

    # -- field ------------------------------------------------------------------------------
    def _field_buffers(self, gx, gy, gz, period, vec):
        cl = self.cl
        if self._field is not None and all(a is b for a, b in zip(self._field[0], (gx, gy, gz, vec))):
            return self._field[1]
        mf = cl.mem_flags
        bufs = [cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                          hostbuf=np.ascontiguousarray(c, self.dtype)) for c in (gx, gy, gz)]
        # with an image the field lives only there (the buffer argument gets a placeholder)
        data = np.zeros(1, self.dtype) if self.image else np.ascontiguousarray(vec, self.dtype)
        bufs.append(cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=data))
        if self.image:
            bufs.append(field_image(self.ctx, vec, period))
        self._field = ((gx, gy, gz, vec), bufs)
        return bufs

    def _cached(self, field, kind, src, make):
        """``make()`` (device data derived from ``src``, part of ``field``), made once per ``src``
        object; the cache holds ``src`` so that its id stays its own, and one field at a time."""
        if self._extra.get("field") is not field.vector:
            self._extra = {"field": field.vector}
        hit = self._extra.get((kind, id(src)))
        if hit is None:
            hit = self._extra[(kind, id(src))] = (src, make())
        return hit[1]

    def _buffer(self, arr, dtype):
        mf = self.cl.mem_flags
        return self.cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                              hostbuf=np.ascontiguousarray(arr, dtype))

    # -- attributes -----------------------------------------------------------------------
    def bind_attributes(self, field, names):
        """The callable ``trace`` runs when attributes ``names`` of ``field`` are requested: this
        backend with the attributes computed in the kernel (or itself, leaving them to the host,
        when ``kernel_attributes`` is off)."""
        if not self.kernel_attributes or not names:
            return self
        return _WithAttributes(self, field, vertex.Plan.of(field, names))

    def _attribute_args(self, field, plan, flags, arrays, vec_buf):
        """Kernel arguments after ``B`` for ``plan``: per scalar field its buffer (and a None for
        its output, per chunk), the vector buffer with an image3d field, the node curl grid."""
        args = []
        for name in plan.scalars:
            arr = field.scalars[name]
            args += [self._cached(field, "scalar", arr, lambda a=arr: self._buffer(a, self.dtype)),
                     None]
        if self.image and plan.needs_vector:  # the image has no exact values: a buffer too
            vec_buf = self._cached(field, "vector", field.vector,
                                   lambda: self._buffer(field.vector, self.dtype))
            if plan.needs_velocity:
                args.append(vec_buf)
        if plan.needs_stencils:
            args.append(self._cached(field, "curl", field.grid,
                                     lambda: self._curl_grid(field, flags, arrays, vec_buf)))
        return args

    def _curl_grid(self, field, flags, arrays, vec_buf):
        """fields.curl.curl at the nodes, computed on the device from the field buffer already
        there (only the stencil table, kilobytes, is uploaded); kept while the field is."""
        cl = self.cl
        nodes, weights, k = vertex.stencils(field.grid)
        fb_nodes, fb_weights = vertex.fallbacks(field.grid)
        shape = field.grid.shape
        curl = cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE,
                         int(np.prod(shape)) * 3 * self.dtype.itemsize)
        knl = codegen.kernel(self.ctx, self.device, flags, arrays, "curl_nodes")
        n = int(np.prod(shape))
        glob = -(-n // self.local) * self.local
        knl(self.q_run, (glob,), (self.local,), *(np.int32(s) for s in shape), vec_buf,
            self._buffer(nodes, np.int32), self._buffer(weights, self.dtype), np.int32(k),
            self._buffer(fb_nodes, np.int32), self._buffer(fb_weights, self.dtype), curl).wait()
        return curl

    # -- one pass ----------------------------------------------------------------------------
    def __call__(self, launch):
        self._run(launch, None)

    def _run(self, work, bound):
        (active, seeds, dirs, spacings, phases, gx, gy, gz, period, inv, vec, _bk,
         mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_par, out_n) = work.arrays()
        cl = self.cl
        plan = bound.plan if bound is not None else vertex.Plan((), (), ())
        arrays = (mc, ma, mb, me, me2, mp, mi)
        flags = codegen.Flags(
            method=_method_name(arrays), tableau=codegen.tableau_key(arrays), real=self.real,
            aware=bool(io[schema.P_AWARE]), periodic=bool(np.any(np.asarray(period) > 0)),
            # crossing bounds the kinks with the start cell's polynomial, which an image lacks
            cross=bool(io[schema.P_AWARE] and io[schema.P_CROSS] and mi[schema.M_ADAPTIVE]
                       and not self.image),
            uniform=bool(np.all(np.asarray(inv) > 0)), image=self.image,
            attrs=plan.attrs, scalars=len(plan.scalars), stiff_stage=int(io[schema.P_STIFF]))
        knl = codegen.kernel(self.ctx, self.device, flags, arrays)
        fbufs = self._field_buffers(gx, gy, gz, period, vec)
        extra = [] if bound is None else self._attribute_args(bound.field, plan, flags, arrays,
                                                              fbufs[3])
        outs = plan.outputs()
        local = min(self.local, knl.get_work_group_info(
            cl.kernel_work_group_info.WORK_GROUP_SIZE, self.device))
        n = active.size
        B = out_p.shape[1]
        dt = self.dtype
        fo_buf = cl.Buffer(self.ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                           hostbuf=np.ascontiguousarray(fo, dt))
        size = self.chunk if n < MIN_SPLIT else min(self.chunk, -(-n // 2))
        bounds = [(lo, min(n, lo + size)) for lo in range(0, n, size)]
        pending = []
        for lo, hi in bounds:
            idx = active[lo:hi]
            m = hi - lo
            host_in = [np.ascontiguousarray(seeds[idx], dt), np.ascontiguousarray(dirs[idx], dt),
                       np.ascontiguousarray(spacings[idx], dt), np.ascontiguousarray(phases[idx], dt),
                       np.ascontiguousarray(sf[idx], dt), np.ascontiguousarray(si[idx], np.int64)]
            dev_in = [cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, h.nbytes) for h in host_in]
            ev_up = [cl.enqueue_copy(self.q_up, d, h, is_blocking=False) for d, h in zip(dev_in, host_in)]
            host_attr = [np.empty((m, B) if c == 1 else (m, B, c), dt) for _, c in outs]
            host_out = [np.empty((m, B, 3), dt), np.empty((m, B, 2), dt), np.empty(m, np.int64),
                        *host_attr, host_in[4], host_in[5]]
            dev_out = [cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, h.nbytes)
                       for h in host_out[:-2]]
            scal = [np.float64(x) if self.real == "double" else np.float32(x)
                    for x in (*period, *inv)]
            args = [np.int32(m), *dev_in[:4], *fbufs[:3],
                    *(np.int32(c.size) for c in (gx, gy, gz)), *scal, fbufs[3]]
            if self.image:
                args.append(fbufs[4])
            args += [fo_buf, np.int64(io[schema.P_MAXSTEPS]), np.int32(io[schema.P_PARAM]),
                     np.int32(io[schema.P_EMIT]), dev_in[4], dev_in[5], *dev_out[:3], np.int32(B)]
            # attribute outputs (built-ins in plan order), then per scalar (field, output), ...
            a_out = iter(dev_out[3:])
            args += [next(a_out) for _ in plan.attrs]
            args += [next(a_out) if x is None else x for x in extra]
            glob = -(-m // local) * local
            ev_run = knl(self.q_run, (glob,), (local,), *args, wait_for=ev_up)
            self.launches += 1
            # the counts and the state now; the vertices once the counts say how many
            ev_down = [cl.enqueue_copy(self.q_down, h, d, is_blocking=False, wait_for=[ev_run])
                       for h, d in zip(host_out[2:3] + host_out[-2:], dev_out[2:3] + dev_in[4:])]
            pending.append((lo, hi, idx, host_in, host_out, dev_out, ev_down, self.launches))
            if self.timeline is not None:
                self.timeline += ([("up", self.launches, e) for e in ev_up] + [("run", self.launches, ev_run)]
                                  + [("down", self.launches, e) for e in ev_down])
            for q in (self.q_up, self.q_run, self.q_down):
                q.flush()
        for lo, hi, idx, _host_in, host_out, dev_out, ev_down, launch in pending:
            op, opar, on, *attr, sfc, sic = host_out
            cl.wait_for_events(ev_down)
            # only the first max(out_n) slots of each line hold vertices: read those (a
            # rectangle of the (lines, B) buffers), not the whole budget
            w = int(on.max(initial=0))
            if w:
                ev_back = [self._read_prefix(h, d, w)
                           for h, d in zip([op, opar, *attr], dev_out[:2] + dev_out[3:])]
                if self.timeline is not None:
                    self.timeline += [("down", launch, e) for e in ev_back]
                cl.wait_for_events(ev_back)
            with np.errstate(invalid="ignore"):  # float32 slots past out_n hold garbage
                out_p[lo:hi, :w] = op[:, :w]
                out_par[lo:hi, :w, :2] = opar[:, :w]
                col = 2
                for a in attr:
                    c = 1 if a.ndim == 2 else a.shape[2]
                    out_par[lo:hi, :w, col:col + c] = a.reshape(a.shape[0], B, c)[:, :w]
                    col += c
            out_n[lo:hi] = on
            sf[idx] = sfc
            si[idx] = sic

    def _read_prefix(self, host, dev, w):
        """Start reading the first w slots of every line of a (lines, B[, c]) output buffer
        into the same places of ``host``; returns the event."""
        row = host.strides[0]  # bytes per line, on the device as on the host
        slot = host.itemsize * (1 if host.ndim == 2 else host.shape[2])
        return self.cl.enqueue_copy(self.q_back, host, dev, buffer_origin=(0, 0, 0),
                                    host_origin=(0, 0, 0), region=(w * slot, host.shape[0], 1),
                                    buffer_pitches=(row,), host_pitches=(row,),
                                    is_blocking=False)


class _WithAttributes:
    """An OpenCLAdvance whose kernel also computes the attributes of ``plan`` (what
    ``bind_attributes`` returns to trace): ``n_columns`` extra columns of out_par, decoded by
    ``point_data``."""

    def __init__(self, base: OpenCLAdvance, field, plan: vertex.Plan):
        self.base = base
        self.field = field
        self.plan = plan
        self.n_columns = plan.n_columns

    def __call__(self, launch):
        self.base._run(launch, self)

    def point_data(self, t, s, columns):
        return self.plan.point_data(t, s, columns)


def field_image(ctx, vec, period):
    """The vector field as a float32 RGBA image3d (w = 0); on periodic axes the first node layer
    is repeated at the end so that the wrap cell's upper corners exist."""
    import pyopencl as cl

    v = np.asarray(vec, np.float32)
    for a in range(3):
        if period[a] > 0:
            v = np.concatenate([v, np.take(v, [0], axis=a)], axis=a)
    rgba = np.zeros(v.shape[:3] + (4,), np.float32)
    rgba[..., :3] = v
    # OpenCL images are indexed (x fastest): the array must be (nz, ny, nx, 4)
    data = np.ascontiguousarray(rgba.transpose(2, 1, 0, 3))
    fmt = cl.ImageFormat(cl.channel_order.RGBA, cl.channel_type.FLOAT)
    return cl.create_image(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, fmt,
                    shape=v.shape[:3], hostbuf=data)


def _method_name(arrays) -> str:
    from ..methods import METHODS

    key = codegen.tableau_key(arrays)
    for name, m in METHODS.items():
        if codegen.tableau_key(m.kernel_arrays()) == key:
            return name
    return "custom"


_contexts: dict = {}


def _context(device):
    import pyopencl as cl

    ctx = _contexts.get(device.int_ptr)
    if ctx is None:
        ctx = _contexts[device.int_ptr] = cl.Context([device])
    return ctx
