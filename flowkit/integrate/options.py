"""TraceOptions: everything a trace needs besides the field and the seeds, validated up front."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from .methods import METHODS, catalogue, get_method, is_registered, names

DIRECTIONS = ("forward", "backward", "both")
PARAMETERS = ("time", "arc_length")


class OptionsError(ValueError):
    """An option value that cannot be used; the message names the option and the value."""


@dataclass(frozen=True)
class TraceOptions:
    """Options of :func:`flowkit.trace`.  ``None`` means "derived from the field" (see below).

    method       a registered method's name (default dopri5) or a method object
                 (flowkit.integrate.methods: Method, e.g. Method.from_butcher(...),
                 RosenbrockMethod, StiffSwitch), validated by its check().  Registered:
{methods}
    rtol, atol   relative/absolute tolerance, a number or one per component (x, y, z); the error
                 of a step is the RMS over components of err_i / (atol_i + rtol_i * |y_i|).
                 atol None: rtol times the largest extent of the grid.
    step         initial step (adaptive; None: Hairer's automatic choice) or the fixed step
                 (fixed-step methods; None: half the smallest cell, in time at the typical speed);
                 in units of the parameter (time, or arc length).
    min_step     a step the controller wants below this ends the line (step_underflow);
                 None: 1e-10 of the smallest cell crossing
    max_step     upper bound on any step (None: none)
    max_steps    attempted steps (accepted + rejected) per line and direction
    max_length, max_time   met exactly (per direction)
    direction    forward, backward or both (one line through the seed)
    parameter    time (dx/dt = v) or arc_length (dx/ds = v / |v|)
    cell_aware   steps end on the faces of the cell they start in (see docs/integrator.md)
    cross_faces  cell-aware adaptive steps may cross faces where their error estimate allows,
                 so that a looser tolerance costs less; False: every step ends on a face
    stagnation   absolute speed below which a line stops: the field's at the line's point, or
                 (adaptive methods) the line's own progress over its tolerance, which stops
                 lines hovering at no-slip walls; None: stagnation_rel * typical speed
    spacing      resample vertices every `spacing` of arc length (dense output)
    count        resample each line to `count` vertices evenly spaced in arc length
    attributes   per-vertex attributes to compute (see flowkit.integrate.attributes)
    budget       vertices per line kept in one kernel pass (None: from a 32 MiB buffer);
                 longer lines continue in later passes, never truncated
    progress     a progress bar on stderr: True always, False never, None (default) where
                 stderr is a terminal and the work is long (trace: 20 000 seeds or more;
                 evenly spaced seeding: a count of the lines once a run passes one second)
    memory       memory budget of a trace, in bytes or as text ("4GB"); None: what the machine
                 has free.  A vector read from a file that does not fit is read brick by brick,
                 only where lines go, into a pool of bricks of the budget (the same lines)
    """

    method: str = "dopri5"
    rtol: float | tuple = 1e-6
    atol: float | tuple | None = None
    step: float | None = None
    min_step: float | None = None
    max_step: float | None = None
    max_steps: int = 100_000
    max_length: float = math.inf
    max_time: float = math.inf
    direction: str = "forward"
    parameter: str = "time"
    cell_aware: bool = True
    cross_faces: bool = True
    stagnation: float | None = None
    stagnation_rel: float = 1e-4
    spacing: float | None = None
    count: int | None = None
    attributes: tuple = ()
    safety: float = 0.9
    min_factor: float = 0.2
    max_factor: float = 10.0
    beta: float = 0.04
    budget: int | None = None
    progress: bool | None = None
    memory: int | str | None = None

    def __post_init__(self):
        m = get_method(self.method)
        if is_registered(m):  # by its name: options read, print and hash as before
            object.__setattr__(self, "method", m.name)
        else:
            if m.name in names():
                raise OptionsError(f"option method: the name {m.name!r} is a registered method's; "
                                   "give your method another name")
            m.check()
        if not m.resamples and (self.spacing is not None or self.count is not None):
            raise OptionsError(f"method {m.name}: options spacing and count (resampling) are "
                               f"offered by the methods with dense output "
                               f"({', '.join(names(lambda e: e.resamples))}); {m.name} emits "
                               "its steps")
        object.__setattr__(self, "rtol", _tol("rtol", self.rtol, positive=True))
        if self.atol is not None:
            object.__setattr__(self, "atol", _tol("atol", self.atol, positive=False))
        for name in ("step", "min_step", "max_step", "stagnation", "spacing"):
            v = getattr(self, name)
            if v is not None and not (_num(v) and v > 0 and math.isfinite(v)):
                raise OptionsError(f"option {name} must be a positive finite number, got {v!r}")
        if self.stagnation == 0:
            raise OptionsError("option stagnation must be positive")
        for name in ("max_length", "max_time"):
            v = getattr(self, name)
            if not (_num(v) and v > 0):
                raise OptionsError(f"option {name} must be positive (inf for no limit), got {v!r}")
        if not (isinstance(self.max_steps, (int, np.integer)) and self.max_steps >= 1):
            raise OptionsError(f"option max_steps must be an integer >= 1, got {self.max_steps!r}")
        if self.direction not in DIRECTIONS:
            raise OptionsError(f"option direction must be one of {DIRECTIONS}, got {self.direction!r}")
        par = {"arc": "arc_length", "length": "arc_length"}.get(self.parameter, self.parameter)
        if par not in PARAMETERS:
            raise OptionsError(f"option parameter must be one of {PARAMETERS}, got {self.parameter!r}")
        object.__setattr__(self, "parameter", par)
        if self.spacing is not None and self.count is not None:
            raise OptionsError("options spacing and count exclude each other; give one")
        if self.count is not None and not (isinstance(self.count, (int, np.integer)) and self.count >= 2):
            raise OptionsError(f"option count must be an integer >= 2, got {self.count!r}")
        if self.budget is not None and not (isinstance(self.budget, (int, np.integer)) and self.budget >= 2):
            raise OptionsError(f"option budget must be an integer >= 2, got {self.budget!r}")
        attrs = self.attributes
        if isinstance(attrs, str):
            attrs = [a for a in attrs.split(",") if a.strip()]
        object.__setattr__(self, "attributes", tuple(a.strip() for a in attrs))
        if not (0 < self.safety <= 1):
            raise OptionsError(f"option safety must be in (0, 1], got {self.safety!r}")
        if not (0 < self.min_factor < 1 < self.max_factor):
            raise OptionsError(
                f"options min_factor < 1 < max_factor required, got {self.min_factor!r}, {self.max_factor!r}")
        if not (0 <= self.beta < 0.2):
            raise OptionsError(f"option beta must be in [0, 0.2), got {self.beta!r}")
        if self.memory is not None:
            from ..fields.stored import parse_bytes

            try:
                object.__setattr__(self, "memory", parse_bytes(self.memory))
            except ValueError as e:
                raise OptionsError(f"option memory: {e}") from None
        if not (0 < self.stagnation_rel < 1):
            raise OptionsError(f"option stagnation_rel must be in (0, 1), got {self.stagnation_rel!r}")

    def __repr__(self) -> str:
        """The method and tolerance, then only the options that differ from their defaults
        (as keywords that rebuild them), a few to a line."""
        m = self.entry
        head = f"<TraceOptions: method {m.name}" + ("" if is_registered(m) else " (unregistered)")
        head += f", rtol {_show(self.rtol)}"
        changed = [f"{f.name}={_show(getattr(self, f.name), f.name)}" for f in fields(self)
                   if f.name not in ("method", "rtol") and getattr(self, f.name) != f.default]
        if not changed:
            return head + "; the other options at their defaults>"
        rows = [""]
        for item in changed:
            if rows[-1] and len(rows[-1]) + len(item) > 84:
                rows.append("")
            rows[-1] += (", " if rows[-1] else "") + item
        return head + "".join(f"\n  {r}" for r in rows) + ">"

    def _repr_html_(self) -> str:
        import html

        return f"<pre>{html.escape(repr(self))}</pre>"

    def replace(self, **kw) -> TraceOptions:
        """These options with some changed (validated again); an unknown name is refused."""
        unknown = set(kw) - {f.name for f in fields(self)}
        if unknown:
            raise OptionsError(f"unknown trace option(s): {', '.join(sorted(unknown))}")
        return replace(self, **kw)

    @property
    def entry(self):
        """The method's registry entry (or the unregistered method object given)."""
        return get_method(self.method)

    @property
    def method_name(self) -> str:
        """The method's name (a registered one's canonical name, not an alias)."""
        return self.entry.name

    @property
    def method_obj(self):
        """The explicit method's tableau; methods of another kind have none (only
        ``flowkit.trace`` and ``trace_to_file`` run them), so a caller that needs one gets a
        clear error."""
        m = self.entry
        if m.kind != "explicit":
            raise OptionsError(f"method {m.name} is offered by flowkit.trace/trace_to_file only; "
                               f"choose an explicit method ({', '.join(METHODS)})")
        return m


TraceOptions.__doc__ = TraceOptions.__doc__.replace("{methods}", catalogue(" " * 17))


def _show(v, name: str = "") -> str:
    """An option's value as the keyword that sets it takes it: numbers as Python writes them
    (numpy's own scalars too), the memory budget as text ("4.29 GB", which option memory takes)."""
    if name == "memory" and v is not None:
        from ..fields.stored import fmt_bytes

        return repr(fmt_bytes(v))
    if isinstance(v, tuple):
        return "(" + ", ".join(_show(x) for x in v) + ("," if len(v) == 1 else "") + ")"
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, np.integer):
        return repr(int(v))
    return repr(v)


def _num(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _tol(name, v, positive):
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        a = None
    if a is None or not (a.ndim == 0 or a.shape == (3,)):
        raise OptionsError(f"option {name} must be a number or 3 numbers (x, y, z), got {v!r}")
    a = np.broadcast_to(a, (3,))
    ok = np.all(np.isfinite(a)) and (np.all(a > 0) if positive else np.all(a >= 0))
    if not ok:
        raise OptionsError(f"option {name} must be {'positive' if positive else 'non-negative'} and finite, got {v!r}")
    return float(a[0]) if np.all(a == a[0]) else tuple(float(x) for x in a)
