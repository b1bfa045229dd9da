"""``python -m flowkit.write_helper_sigs``: writes helper_sigs.py, the helpers each kernel's
compilation asks for, which parallel_compile's second process compiles; from a default trace and
the traces of ``parallel_compile.NEXT`` on an empty cache.  Tooling, which flowkit itself never
imports: it traces through the whole package, and parallel_compile sits below all of that."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path


def _type_src(ty) -> str:
    from numba.core import types

    if isinstance(ty, types.Array) and ty.layout == "C" and ty.mutable and ty.ndim <= 4:
        return f"{_type_src(ty.dtype)}{ty.ndim}"  # F2: a C-contiguous 2-d float64 array
    names = {types.float64: "F", types.int64: "I", types.boolean: "B", types.none: "N"}
    if ty in names:
        return names[ty]
    raise ValueError(f"helper_sigs: no source form for the type {ty!r}")


def compile_order(run, kernel: str) -> list[tuple[str, str, tuple]]:
    """(module, name, argument types) of every flowkit function compiled while ``run()``
    compiles ``kernel`` (a qualified name), in the order the compilations end (the kernel's
    typing asks for a helper's callees first), the kernel itself left out."""
    from numba.core import event

    seen = {}  # (module, name) -> argument types, in the order they were compiled

    class Listener(event.Listener):
        def on_start(self, ev):
            pass

        def on_end(self, ev):
            d = ev.data["dispatcher"]
            name = (d.py_func.__module__, d.py_func.__qualname__)
            if name[0].startswith("flowkit.") and ".".join(name) != kernel.split(":")[0]:
                seen.setdefault(name, tuple(ev.data["args"]))

    with event.install_listener("numba:compile", Listener()):
        run()
    return [(m, n, sig) for (m, n), sig in seen.items()]


def write_table(path: Path | None = None) -> Path:
    """Write helper_sigs.py from a default trace and the traces of ``parallel_compile.NEXT``
    (run on an empty cache: a helper loaded from the cache is not seen compiling)."""
    # this process compiles every helper itself: one a second process stored would be loaded
    os.environ["FLOWKIT_PARALLEL_COMPILE"] = "0"
    import flowkit
    from flowkit import warmup
    from flowkit.integrate.pathlines import pathlines

    field = warmup.stand_in()
    # in this order, each after the one before (a helper already compiled is not listed again)
    kernels = {"flowkit.integrate.kernel._advance_lines":
               lambda: flowkit.trace(field, warmup.SEEDS, max_length=4.0),
               "flowkit.integrate.kernel._advance_lines:rosenbrock":
               lambda: flowkit.trace(field, warmup.SEEDS, max_length=4.0, method="ros34pw2"),
               "flowkit.integrate.kernel._advance_lines:pathlines":
               lambda: pathlines([(0.0, field), (1.0, warmup.stand_in(t=1.0))], warmup.SEEDS,
                                 max_time=1.0)}
    lines = ['"""The helpers each kernel\'s compilation asks for, with their argument types, in the',
             "order its typing asks for them (written by `python -m flowkit.write_helper_sigs`",
             "on an empty cache; tests/test_compile_cost.py checks it against a default trace;",
             'flowkit/parallel_compile.py says what it is for)."""',
             "", "from numba.core import types as t", "",
             "F, I, B, N = t.float64, t.int64, t.boolean, t.none",
             "F1, F2, F3, F4 = (t.Array(F, n, \"C\") for n in (1, 2, 3, 4))",
             "I1, I2, I3, I4 = (t.Array(I, n, \"C\") for n in (1, 2, 3, 4))",
             "B1, B2, B3, B4 = (t.Array(B, n, \"C\") for n in (1, 2, 3, 4))",
             "", "HELPERS = {"]
    for kernel, run in kernels.items():
        lines.append(f'    "{kernel}": (')
        for m, n, sig in compile_order(run, kernel):
            args = ", ".join(_type_src(a) for a in sig) + ","
            lines += textwrap.wrap(f'("{m}", "{n}", ({args})),', 99, initial_indent=" " * 8,
                                   subsequent_indent=" " * 9, break_long_words=False)
        lines.append("    ),")
    lines.append("}")
    path = path or Path(__file__).with_name("helper_sigs.py")
    path.write_text("\n".join(lines) + "\n")
    return path


def main() -> int:
    # in a process of its own on an empty cache (see write_table)
    with tempfile.TemporaryDirectory() as cache:
        code = "from flowkit.write_helper_sigs import write_table; print(write_table())"
        return subprocess.run([sys.executable, "-c", code], check=False,
                              env=dict(os.environ, NUMBA_CACHE_DIR=cache)).returncode


if __name__ == "__main__":
    sys.exit(main())
