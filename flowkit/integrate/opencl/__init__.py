"""The OpenCL backend: the numba integrator's algorithm as a generated OpenCL kernel.

``trace(..., backend="opencl[:PLATFORM[:DEVICE]]")`` runs it; see docs/opencl.md.  pyopencl is
imported lazily, so importing this package never needs it.
"""

from .device import OpenCLUnavailable, describe_devices, parse_backend, select_device

__all__ = ["OpenCLAdvance", "OpenCLUnavailable", "describe_devices", "parse_backend", "select_device"]


def __getattr__(name):
    if name == "OpenCLAdvance":
        from .backend import OpenCLAdvance

        return OpenCLAdvance
    raise AttributeError(name)
