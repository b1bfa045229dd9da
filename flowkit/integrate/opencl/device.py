"""OpenCL platform/device discovery and selection from ``"opencl[:PLATFORM[:DEVICE]]"``.

PLATFORM and DEVICE are indices (as listed by ``flowkit info --devices``) or case-insensitive
substrings of the platform / device name.  Without them the first GPU is taken, else the first
device of any kind, among the devices that can compile a kernel: the PoCL that pyopencl's wheel
bundles is built on LLVM 14, which does not know CPUs newer than it (AMD Zen 5, say) and then
fails every build with "unknown target CPU 'generic'", while Debian's PoCL
(``scripts/system-deps.sh`` installs it) targets the nearest CPU it knows.  PoCL
(``pip install 'flowkit[opencl]'``, which brings pocl-binary-distribution) gives every machine a
CPU device.
"""

from __future__ import annotations

from dataclasses import dataclass

INSTALL_HINT = "install the opencl extra: pip install 'flowkit[opencl]' (brings pyopencl and PoCL)"
CPU_HINT = ("this PoCL's LLVM does not know the CPU; install a PoCL that does (Debian/Ubuntu: "
            "apt install pocl-opencl-icd, as scripts/system-deps.sh does) or pick another device "
            "with --backend opencl:PLATFORM:DEVICE (flowkit info --devices lists them)")


class OpenCLUnavailable(RuntimeError):
    """pyopencl or an OpenCL platform/device is missing; the message names the extra."""


def _cl():
    try:
        import pyopencl as cl
    except ImportError as exc:  # pragma: no cover - exercised by monkeypatching in tests
        raise OpenCLUnavailable(f"the OpenCL backend needs pyopencl: {INSTALL_HINT}") from exc
    return cl


def platforms():
    cl = _cl()
    try:
        plats = cl.get_platforms()
    except cl.Error as exc:  # PLATFORM_NOT_FOUND_KHR from the ICD loader
        raise OpenCLUnavailable(f"no OpenCL platform found ({exc}); {INSTALL_HINT}") from None
    if not plats:
        raise OpenCLUnavailable(f"no OpenCL platform found; {INSTALL_HINT}")
    return plats


def parse_backend(spec: str) -> tuple[str | None, str | None]:
    """``"opencl[:P[:D]]"`` -> (P, D), each None when absent."""
    parts = str(spec).split(":")
    if parts[0].strip().lower() != "opencl" or len(parts) > 3:
        raise ValueError(f"backend {spec!r}: expected 'opencl', 'opencl:PLATFORM' or "
                         "'opencl:PLATFORM:DEVICE'")
    parts = [p.strip() or None for p in parts[1:]] + [None, None]
    return parts[0], parts[1]


def _pick(items, key, what, names):
    if key is None:
        return None
    if key.isdigit():
        i = int(key)
        if i >= len(items):
            raise ValueError(f"OpenCL {what} index {i} out of range; have: {names}")
        return items[i]
    hits = [it for it in items if key.lower() in it.name.lower()]
    if not hits:
        raise ValueError(f"no OpenCL {what} matches {key!r}; have: {names}")
    return hits[0]


def _listing(items):
    return ", ".join(f"{i}: {it.name.strip()}" for i, it in enumerate(items))


def select_device(spec: str = "opencl"):
    """The pyopencl Device named by a backend string."""
    cl = _cl()
    pkey, dkey = parse_backend(spec)
    plats = platforms()
    plat = _pick(plats, pkey, "platform", _listing(plats))
    cands = [plat] if plat is not None else plats
    devs = [d for p in cands for d in _devices(p)]
    if not devs:
        raise OpenCLUnavailable(f"no OpenCL device on {_listing(cands)}; {INSTALL_HINT}")
    if dkey is not None:
        return _pick(devs, dkey, "device", _listing(devs))
    working = [d for d in devs if compiles(d)]
    if not working:
        raise OpenCLUnavailable(f"no OpenCL device on {_listing(cands)} can compile a kernel: "
                                f"{_build_errors[devs[0].int_ptr]}; {CPU_HINT}")
    gpus = [d for d in working if d.type & cl.device_type.GPU]
    return (gpus or working)[0]


_build_errors: dict[int, str | None] = {}


def compiles(dev) -> bool:
    """Whether ``dev`` builds a one-line kernel (checked once per device and process)."""
    if dev.int_ptr not in _build_errors:
        cl = _cl()
        try:
            cl.Program(cl.Context([dev]), "__kernel void probe(__global int *a) { a[0] = 1; }"
                       ).build(devices=[dev])
            _build_errors[dev.int_ptr] = None
        except cl.Error as exc:
            _build_errors[dev.int_ptr] = _first_error(str(exc))
    return _build_errors[dev.int_ptr] is None


def _first_error(log: str) -> str:
    lines = [ln.strip() for ln in log.splitlines() if ln.strip()]
    return next((ln for ln in lines if ln.startswith("error")), lines[0] if lines else "")[:200]


def _devices(plat):
    cl = _cl()
    try:
        return plat.get_devices()
    except cl.Error:  # DEVICE_NOT_FOUND on an empty platform
        return []


@dataclass(frozen=True)
class DeviceInfo:
    spec: str  # the backend string that selects it
    platform: str
    name: str
    kind: str
    compute_units: int
    global_mem_mib: int
    fp64: bool
    images: bool

    def line(self) -> str:
        return (f"{self.spec:<12} {self.kind:<4} {self.name} [{self.platform}] "
                f"{self.compute_units} CU, {self.global_mem_mib} MiB, "
                f"fp64 {'yes' if self.fp64 else 'no'}, image3d {'yes' if self.images else 'no'}")


def supports_fp64(dev) -> bool:
    return "cl_khr_fp64" in dev.extensions or bool(getattr(dev, "double_fp_config", 0))


def device_infos() -> list[DeviceInfo]:
    cl = _cl()
    out = []
    for pi, p in enumerate(platforms()):
        for di, d in enumerate(_devices(p)):
            kind = "GPU" if d.type & cl.device_type.GPU else (
                "CPU" if d.type & cl.device_type.CPU else "ACC")
            out.append(DeviceInfo(f"opencl:{pi}:{di}", p.name.strip(), d.name.strip(), kind,
                                  int(d.max_compute_units), int(d.global_mem_size >> 20),
                                  supports_fp64(d), bool(d.image_support)))
    return out


def describe_devices() -> str:
    """Text for ``flowkit info --devices``: one line per device, or why there is none."""
    try:
        infos = device_infos()
    except OpenCLUnavailable as exc:
        return f"OpenCL: {exc}"
    if not infos:
        return f"OpenCL: platforms found but no device; {INSTALL_HINT}"
    return "\n".join(["OpenCL devices (use --backend SPEC):"] + ["  " + i.line() for i in infos])
