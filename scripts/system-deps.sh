#!/usr/bin/env bash
# System libraries the Python wheels cannot bring: Mesa's EGL + llvmpipe for headless rendering,
# a virtual display (Xvfb + Mesa's GLX) for the viewer's tests, and Debian's PoCL: the PoCL inside
# pyopencl's wheel is built on LLVM 14 and cannot compile for CPUs newer than it (AMD Zen 5 fails
# every build with "unknown target CPU 'generic'"); Debian's picks the nearest CPU its LLVM knows.
# Installed only when missing, and only where we may (root with apt); otherwise we say what to do.
set -eu
have_lib() { ldconfig -p 2>/dev/null | grep -q "$1"; }
missing=()
have_lib libEGL.so.1 || missing+=(libegl1)
have_lib libEGL_mesa.so.0 || missing+=(libegl-mesa0)
ls /usr/lib/*/dri/swrast_dri.so >/dev/null 2>&1 || missing+=(libgl1-mesa-dri)
have_lib libGL.so.1 || missing+=(libgl1)
have_lib libGLX_mesa.so.0 || missing+=(libglx-mesa0)
command -v Xvfb >/dev/null || missing+=(xvfb xauth)
have_lib libpocl.so.2 || missing+=(pocl-opencl-icd)
[ ${#missing[@]} -eq 0 ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing system packages for headless OpenGL, the viewer's tests and OpenCL on the CPU: ${missing[*]}"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
else
    echo "warning: headless rendering, the viewer's tests and OpenCL on this CPU need these system packages: ${missing[*]} (install them with your package manager)" >&2
fi
