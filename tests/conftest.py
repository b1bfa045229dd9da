"""Shared fixtures."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest

# the lock-step compiles in the launch that needs it (not in the background, with the scalar
# kernel tracing meanwhile): tests of the lanes must run the lanes; subprocesses inherit it
os.environ.setdefault("FLOWKIT_LOCKSTEP_WAIT", "1")


@pytest.fixture(scope="session")
def display():
    """A private X display for the session (Xvfb picks a free number: -displayfd)."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        why = "Xvfb is not installed (apt-get install xvfb): the viewer tests need a display"
        if os.environ.get("CI"):
            pytest.fail(why)
        pytest.skip(why)
    r, w = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(w), "-screen", "0", "1280x1024x24",
                             "-nolisten", "tcp"], pass_fds=(w,), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    os.close(w)
    with os.fdopen(r) as f:
        number = f.readline().strip()
    if not number:
        proc.kill()
        pytest.fail(f"Xvfb did not start: {proc.communicate()[1].decode(errors='replace')}")
    old = os.environ.get("DISPLAY")
    os.environ["DISPLAY"] = f":{number}"
    yield os.environ["DISPLAY"]
    import glfw

    glfw.terminate()
    proc.terminate()
    proc.wait(10)
    if old is None:
        os.environ.pop("DISPLAY", None)
    else:
        os.environ["DISPLAY"] = old


@pytest.fixture(scope="session")
def vtk():
    """VTK, the peer that must open flowkit's files: skipped without it on a developer's
    machine, a failure in CI (CI set), where .ci/run installs it (the "interop" extra)."""
    try:
        import vtk
    except ImportError:
        why = "vtk is not installed (pip install -e '.[interop]'): the VTK interop tests need it"
        if os.environ.get("CI"):
            pytest.fail(why)
        pytest.skip(why)
    return vtk
