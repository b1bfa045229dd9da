"""Say so when a kernel is being compiled: on a fresh machine the first trace waits for numba.

numba reports a compilation (not a load from its cache) as the event "numba:compile".  When
one of flowkit's functions starts compiling at the outermost level and is still compiling
after ``DELAY`` seconds, the logger ``flowkit.compile`` says so once per kernel and process:
"compiling the tracing kernel for this CPU, once: ~N s", N from ``TYPICAL`` (cold compile
times measured on a 2-core machine by benchmarks/bench_cold_start.py).  A kernel compiled in
variants (one per type of some arguments) names them in ``VARIANTS``: each is told once.  The CLI prints that
logger's messages on stderr; Python users see them through logging.
"""

from __future__ import annotations

import logging
import threading

from numba.core import event

LOG = logging.getLogger("flowkit.compile")
DELAY = 2.0
# qualified name of a kernel -> (what it is, typical cold compile seconds)
TYPICAL = {
    "flowkit.integrate.kernel._advance_lines": ("the tracing kernel", 9),
    "flowkit.integrate.kernel._advance_lines:pathlines": ("the tracing kernel for pathlines", 6),
    "flowkit.integrate.kernel._advance_lines:rosenbrock": (
        "the tracing kernel with the Rosenbrock stepper", 7),
    "flowkit.integrate.lanes.lockstep": ("the lock-step kernel", 18),
    "flowkit.fields.interp._sample_range": ("the attribute sampler", 1),
    "flowkit.seeding.even._pick": ("the evenly spaced seeding's candidate pick", 3),
    "flowkit.seeding.even._walk": ("the evenly spaced seeding's walk", 1),
}


# qualified name of a kernel -> its variant's suffix (":name", "" the first) from the argument
# types of a compilation; set by the kernel's module (this one sits below it)
VARIANTS: dict = {}


def _name(dispatcher, args=None) -> str:
    f = getattr(dispatcher, "py_func", None)
    if f is None:
        return ""
    name = f"{f.__module__}.{f.__qualname__}"
    variant = VARIANTS.get(name)
    return name + (variant(args) if variant is not None and args is not None else "")


class _Listener(event.Listener):
    def __init__(self):
        self.depth = 0
        self.told: set[str] = set()
        self.timer: threading.Timer | None = None

    def on_start(self, ev):
        self.depth += 1
        if self.depth != 1:
            return
        name = _name(ev.data.get("dispatcher"), ev.data.get("args"))
        if not name.startswith("flowkit.") or name in self.told:
            return
        what, secs = TYPICAL.get(name, ("a flowkit kernel", None))
        self.timer = threading.Timer(DELAY, self._tell, (name, what, secs))
        self.timer.daemon = True
        self.timer.start()

    def on_end(self, ev):
        self.depth -= 1
        if self.depth == 0 and self.timer is not None:
            self.timer.cancel()
            self.timer = None

    def _tell(self, name, what, secs):
        self.told.add(name)
        about = f": ~{secs} s" if secs else ""
        LOG.info("compiling %s for this CPU, once%s (cached for later runs)", what, about)


def install() -> None:
    """Listen for numba compilations (idempotent; flowkit's import calls it)."""
    global _installed
    if not _installed:
        event.register("numba:compile", _Listener())
        _installed = True


_installed = False
