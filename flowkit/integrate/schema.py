"""The integrators' data contract: the columns of the per-line state and option arrays, declared once.

A backend advances lines whose whole state lives in two arrays, ``sf`` (float64, one row per
line) and ``si`` (int64), and reads its options from ``fo`` (float64) and ``io`` (int64) and the
method's integers from ``mi`` (``Method.kernel_arrays``).  Each array is a ``Layout``: named
columns with widths, laid end to end.  The layout gives the column constants (``S_Y``,
``I_STATUS``, ``O_RTOL``, ``P_AWARE``, ``M_STAGES``, ...) and the row sizes (``NF``, ``NI``,
``NFO``, ``NIO``, ``NMI``), assigned below as plain module-level ints (written by
``constants_source``, checked against the layouts by tests/test_schema_constants.py), which
numba compiles as constants (no lookup at run time), and the OpenCL code generator emits the
same names as ``#define`` lines (``c_defines``), so neither the numba kernels nor the C source
address a column by number.

A column ``w`` wide holds components ``C .. C + w - 1`` (``sf[l, S_Y + 2]`` is the position's z).
Codes name the values some columns hold (a line's status, a launch's pass, the emit mode).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Column:
    name: str
    width: int = 1
    doc: str = ""


class Layout:
    """Columns laid end to end in one row of ``array``; ``size_name`` names the row length."""

    def __init__(self, array: str, size_name: str, columns: tuple[Column, ...]):
        self.array, self.size_name, self.columns = array, size_name, tuple(columns)
        self.offsets: dict[str, int] = {}
        at = 0
        for c in self.columns:
            if c.width < 1 or c.name in self.offsets:
                raise ValueError(f"{array}: column {c.name!r} repeated or of width {c.width}")
            self.offsets[c.name] = at
            at += c.width
        self.size = at

    def __getitem__(self, name: str) -> int:
        return self.offsets[name]

    def constants(self) -> dict[str, int]:
        return {**self.offsets, self.size_name: self.size}


QMAX = 8  # highest dense-output degree a method may have

FLOAT_STATE = Layout("sf", "NF", (
    Column("S_Y", 3, "position"),
    Column("S_TAU", 1, "independent parameter: time, or arc length when P_PARAM == 1"),
    Column("S_DEP", 1, "dependent parameter, integrated as a 4th component"),
    Column("S_H", 1, "the controller's next step (signed: negative for backward lines)"),
    Column("S_ERRP", 1, "previous accepted error (PI controller)"),
    Column("S_K0", 4, "first stage of the next step (u, v, w, rate of the dependent parameter)"),
    Column("S_LO", 3, "lower faces of the current cell (cell-aware)"),
    Column("S_HI", 3, "upper faces of the current cell"),
    Column("S_Y0", 4, "pending step (resampled output): its start, position and dependent"),
    Column("S_TAU0", 1, "pending step: its start's independent parameter"),
    Column("S_HS", 1, "pending step: its size"),
    Column("S_TH", 1, "pending step: θ where it ends"),
    Column("S_LAST_S", 1, "arc length of the last emitted vertex"),
    Column("S_Q", 4 * QMAX, "pending step's dense coefficients, 4 components x QMAX"),
    Column("S_HK", 1, "the longest step across faces that the kink error allowed (P_CROSS)"),
    Column("S_ANCHOR", 4, "position and time the line's progress is measured from (kernel._stalled)"),
))
INT_STATE = Layout("si", "NI", (
    Column("I_STATUS", 1, "NEW, RUNNING or DONE"),
    Column("I_REASON", 1, "why the line stopped (reasons.Reason)"),
    Column("I_NACC", 1, "accepted steps"),
    Column("I_NREJ", 1, "rejected steps"),
    Column("I_CELL", 3, "index of the current cell (cell-aware)"),
    Column("I_LASTREJ", 1, "1 when the last step was rejected"),
    Column("I_PEND", 1, "1 while a pending step has vertices left to emit"),
    Column("I_M", 1, "index of the next resampled vertex"),
    Column("I_FINAL", 1, "1 while the line's last vertex is still to be emitted"),
    Column("I_STIFF", 1, "stiffness detection state (stiffness.stiff_update)"),
    Column("I_NCROSS", 1, "accepted steps that crossed faces (P_CROSS)"),
    Column("I_KFAIL", 1, "failed crossing tries in a row"),
    Column("I_KWAIT", 1, "faces to wait before the next crossing try"),
    Column("I_WAIT", 1, "bricked field: 1 + the brick the line waits for, 0 none"),
    Column("I_ROS", 1, "1 while the line steps with the Rosenbrock stepper (kernel's ros)"),
    Column("I_NSTIFF", 1, "Rosenbrock steps with h ρ(J) > stiffness.HLAMBDA_STIFF"),
))
FLOAT_OPTIONS = Layout("fo", "NFO", (
    Column("O_RTOL", 3, "relative tolerance per axis"),
    Column("O_ATOL", 3, "absolute tolerance per axis"),
    Column("O_SAFETY", 1, "controller safety factor"),
    Column("O_FACMIN", 1, "smallest step-size factor"),
    Column("O_FACMAX", 1, "largest step-size factor"),
    Column("O_BETA", 1, "PI controller's beta"),
    Column("O_H0", 1, "first step (0: estimated)"),
    Column("O_HMIN", 1, "smallest step"),
    Column("O_HMAX", 1, "largest step"),
    Column("O_MAXLEN", 1, "arc length limit"),
    Column("O_MAXTIME", 1, "time limit"),
    Column("O_STAG", 1, "stagnation speed"),
    Column("O_CELLFAC", 1, "step cap: this times the straight-line time to the exit face"),
))
INT_OPTIONS = Layout("io", "NIO", (
    Column("P_MAXSTEPS", 1, "steps (accepted and rejected) per line"),
    Column("P_PARAM", 1, "independent parameter: 0 time, 1 arc length"),
    Column("P_AWARE", 1, "1: cell-aware stepping"),
    Column("P_EMIT", 1, "EMIT_STEPS, EMIT_SPACING or EMIT_FINAL"),
    Column("P_STIFF", 1, "stage index of the stiffness pair (dopri5: 5, c = 1 like f(y1)); -1 none"),
    # a flag in io, not an argument, so that the kernel's line function is compiled once
    Column("P_PASS", 1, "what a launch does: PASS_FULL, PASS_SETUP or PASS_FINISH (lanes.py)"),
    Column("P_CROSS", 1, "1: adaptive cell-aware steps may cross faces"),
    Column("P_ROS", 1, "with the Rosenbrock stepper: 1 lines start with it; 0 they switch to it "
                       "at the step the stiffness test flags them"),
))
METHOD_INFO = Layout("mi", "NMI", (
    Column("M_STAGES", 1, "stages, the f(y1) stage and the dense-output ones included"),
    Column("M_NERR", 1, "stages computed before the error test"),
    Column("M_FSAL", 1, "the stage that evaluates f(y1)"),
    Column("M_ADAPTIVE", 1, "1 when the method has an error estimate"),
    Column("M_KEXP", 1, "q + 1 of the step-size rule h_new = h (1 / err)^(1 / (q + 1))"),
    Column("M_HASE2", 1, "1 when it has DOP853's second error estimate"),
))
LAYOUTS = (FLOAT_STATE, INT_STATE, FLOAT_OPTIONS, INT_OPTIONS, METHOD_INFO)

# the values of coded columns, and the event kinds of a step (shared by both backends' loops)
CODES = {
    "I_STATUS": ("NEW", "RUNNING", "DONE"),
    "P_PASS": ("PASS_FULL", "PASS_SETUP", "PASS_FINISH"),
    "P_EMIT": ("EMIT_STEPS", "EMIT_SPACING", "EMIT_FINAL"),
    "step event": ("EV_NONE", "EV_FACE", "EV_BOUNDARY", "EV_DEPLIM"),
}

def _constants() -> dict[str, int]:
    out = {"QMAX": QMAX}
    for layout in LAYOUTS:
        out.update(layout.constants())
    for names in CODES.values():
        out.update({n: v for v, n in enumerate(names)})
    return out


CONSTANTS = _constants()

# The constants by name, as the kernels import them (plain ints: numba compiles them as
# constants), written by constants_source() from the layouts and codes above.
# -- generated by constants_source() --
# sf: NF columns
NF = 62
S_Y = 0
S_TAU = 3
S_DEP = 4
S_H = 5
S_ERRP = 6
S_K0 = 7
S_LO = 11
S_HI = 14
S_Y0 = 17
S_TAU0 = 21
S_HS = 22
S_TH = 23
S_LAST_S = 24
S_Q = 25
S_HK = 57
S_ANCHOR = 58
# si: NI columns
NI = 18
I_STATUS = 0
I_REASON = 1
I_NACC = 2
I_NREJ = 3
I_CELL = 4
I_LASTREJ = 7
I_PEND = 8
I_M = 9
I_FINAL = 10
I_STIFF = 11
I_NCROSS = 12
I_KFAIL = 13
I_KWAIT = 14
I_WAIT = 15
I_ROS = 16
I_NSTIFF = 17
# fo: NFO columns
NFO = 17
O_RTOL = 0
O_ATOL = 3
O_SAFETY = 6
O_FACMIN = 7
O_FACMAX = 8
O_BETA = 9
O_H0 = 10
O_HMIN = 11
O_HMAX = 12
O_MAXLEN = 13
O_MAXTIME = 14
O_STAG = 15
O_CELLFAC = 16
# io: NIO columns
NIO = 8
P_MAXSTEPS = 0
P_PARAM = 1
P_AWARE = 2
P_EMIT = 3
P_STIFF = 4
P_PASS = 5
P_CROSS = 6
P_ROS = 7
# mi: NMI columns
NMI = 6
M_STAGES = 0
M_NERR = 1
M_FSAL = 2
M_ADAPTIVE = 3
M_KEXP = 4
M_HASE2 = 5
# values of I_STATUS
NEW = 0
RUNNING = 1
DONE = 2
# values of P_PASS
PASS_FULL = 0
PASS_SETUP = 1
PASS_FINISH = 2
# values of P_EMIT
EMIT_STEPS = 0
EMIT_SPACING = 1
EMIT_FINAL = 2
# values of step event
EV_NONE = 0
EV_FACE = 1
EV_BOUNDARY = 2
EV_DEPLIM = 3
# -- end of generated --


def _groups(layouts, codes):
    """(heading, [(name, value), ...]) for each layout (its size, then its columns) and code."""
    for layout in layouts:
        yield (f"{layout.array}: {layout.size_name} columns",
               [(layout.size_name, layout.size)] + [(c.name, layout[c.name]) for c in layout.columns])
    for of in codes:
        yield f"values of {of}", [(n, v) for v, n in enumerate(CODES[of])]


def constants_source() -> str:
    """The block of assignments above, as LAYOUTS and CODES give it (QMAX is declared)."""
    lines = []
    for heading, pairs in _groups(LAYOUTS, CODES):
        lines += [f"# {heading}"] + [f"{n} = {v}" for n, v in pairs]
    return "\n".join(lines)


def c_defines(layouts=LAYOUTS, codes=tuple(CODES)) -> str:
    """``layouts`` and ``codes`` (keys of CODES) as OpenCL C ``#define`` lines, with QMAX."""
    lines = [f"#define QMAX {QMAX}"]
    for heading, pairs in _groups(layouts, codes):
        lines += [f"/* {heading} */"] + [f"#define {n} {v}" for n, v in pairs]
    return "\n".join(lines)
