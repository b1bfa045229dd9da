#!/usr/bin/env bash
# System libraries the Python wheels cannot bring: Mesa's EGL + llvmpipe for headless rendering.
# Installed only when missing, and only where we may (root with apt); otherwise we say what to do.
set -eu
have_lib() { ldconfig -p 2>/dev/null | grep -q "$1"; }
missing=()
have_lib libEGL.so.1 || missing+=(libegl1)
have_lib libEGL_mesa.so.0 || missing+=(libegl-mesa0)
ls /usr/lib/*/dri/swrast_dri.so >/dev/null 2>&1 || missing+=(libgl1-mesa-dri)
have_lib libGL.so.1 || missing+=(libgl1)
[ ${#missing[@]} -eq 0 ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing system packages for headless OpenGL: ${missing[*]}"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
else
    echo "warning: headless rendering needs these system packages: ${missing[*]} (install them with your package manager)" >&2
fi
