"""Integration: methods as data, numba and OpenCL backends, attributes, seeding."""
