"""The integrators' data contract: the columns of the per-line state and option arrays, declared once.

A backend advances lines whose whole state lives in two arrays, ``sf`` (float64, one row per
line) and ``si`` (int64), and reads its options from ``fo`` (float64) and ``io`` (int64) and the
method's integers from ``mi`` (``Method.kernel_arrays``).  Each array is a ``Layout``: named
columns with widths, laid end to end.  The layout generates the column constants (``S_Y``,
``I_STATUS``, ``O_RTOL``, ``P_AWARE``, ``M_STAGES``, ...) and the row sizes (``NF``, ``NI``,
``NFO``, ``NIO``, ``NMI``) as plain module-level ints, which numba compiles as constants (no
lookup at run time), and the OpenCL code generator emits the same names as ``#define`` lines
(``c_defines``), so neither the numba kernels nor the C source address a column by number.

A column ``w`` wide holds components ``C .. C + w - 1`` (``sf[l, S_Y + 2]`` is the position's z).
Pathlines and Rosenbrock lines keep shorter rows: the streamline kernel's leading columns, read
and written by the kernel's own state helpers, then columns of their own (``Layout.head``).
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

    def head(self, last: str, *more: Column) -> Layout:
        """This layout's columns up to ``last`` (same offsets), then ``more`` (a row of its own:
        its constants are not exported, and a name in ``more`` may sit elsewhere than here)."""
        keep = self.columns[:[c.name for c in self.columns].index(last) + 1]
        return Layout(self.array, self.size_name, keep + more)

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

# rows of the other integrators: the kernel's leading columns (kernel._load_state/_save_state)
# and their own
PATH_FLOAT_STATE = FLOAT_STATE.head("S_K0")
PATH_INT_STATE = INT_STATE.head("I_NREJ", Column("I_LASTREJ", 1, "1 when the last step was rejected"))
PATH_FLOAT_OPTIONS = FLOAT_OPTIONS.head("O_STAG")
PATH_INT_OPTIONS = INT_OPTIONS.head("P_MAXSTEPS")
ROS_INT_STATE = INT_STATE.head("I_NREJ", Column("I_STIFF", 1, "stiffness.stiff_update state"),
                               Column("I_NSTIFF", 1, "accepted steps with h ρ(J) > HLAMBDA_STIFF"))


def _constants() -> dict[str, int]:
    out = {"QMAX": QMAX}
    for layout in LAYOUTS:
        out.update(layout.constants())
    for names in CODES.values():
        out.update({n: v for v, n in enumerate(names)})
    return out


CONSTANTS = _constants()
globals().update(CONSTANTS)  # S_Y, ..., NF, NEW, ...: plain ints, constants to numba


def c_defines(layouts=LAYOUTS, codes=tuple(CODES)) -> str:
    """``layouts`` and ``codes`` (keys of CODES) as OpenCL C ``#define`` lines, with QMAX."""
    lines = [f"#define QMAX {QMAX}"]
    for layout in layouts:
        lines.append(f"/* {layout.array}: {layout.size_name} columns */")
        lines.append(f"#define {layout.size_name} {layout.size}")
        lines += [f"#define {c.name} {layout[c.name]}" for c in layout.columns]
    for of in codes:
        lines.append(f"/* values of {of} */")
        lines += [f"#define {n} {v}" for v, n in enumerate(CODES[of])]
    return "\n".join(lines)
