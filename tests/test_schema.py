"""The integrators' data contract (integrate/schema.py): layouts that tile their rows, constants the
kernels and the OpenCL source share, and no column addressed by a bare number anywhere."""

import re
from pathlib import Path

import numpy as np
import pytest

from flowkit.integrate import kernel as K
from flowkit.integrate import lanes, pathlines, rosenbrock, schema
from flowkit.integrate.methods import METHODS
from flowkit.integrate.opencl import codegen

INTEGRATE = Path(schema.__file__).parent
DERIVED = {  # layout of another integrator: (its parent, its own trailing columns)
    "PATH_FLOAT_STATE": (schema.FLOAT_STATE, 0), "PATH_INT_STATE": (schema.INT_STATE, 1),
    "PATH_FLOAT_OPTIONS": (schema.FLOAT_OPTIONS, 0), "PATH_INT_OPTIONS": (schema.INT_OPTIONS, 0),
    "ROS_INT_STATE": (schema.INT_STATE, 2),
}


def _tiles(layout):
    """Columns in offset order, each starting where the one before it ends, ending at size."""
    at = 0
    for c in sorted(layout.columns, key=lambda c: layout[c.name]):
        assert layout[c.name] == at, f"{layout.array}: {c.name} at {layout[c.name]}, not {at}"
        at += c.width
    assert at == layout.size


@pytest.mark.parametrize("layout", schema.LAYOUTS + tuple(getattr(schema, n) for n in DERIVED),
                         ids=lambda lay: f"{lay.array}-{lay.size}")
def test_layouts_tile_their_rows_without_overlap(layout):
    _tiles(layout)
    cells = np.zeros(layout.size, int)
    for c in layout.columns:
        cells[layout[c.name]:layout[c.name] + c.width] += 1
    assert np.all(cells == 1)  # every column of the row belongs to exactly one field


def test_derived_rows_keep_their_parents_columns():
    for name, (parent, own) in DERIVED.items():
        lay = getattr(schema, name)
        shared = lay.columns[:len(lay.columns) - own]
        assert shared == parent.columns[:len(shared)], name
        assert all(lay[c.name] == parent[c.name] for c in shared), name
    assert schema.PATH_FLOAT_STATE.size == schema.FLOAT_STATE["S_K0"] + 4
    assert (pathlines.NF, pathlines.NI, pathlines.I_LASTREJ) == (11, 5, 4)
    assert (rosenbrock.NI, rosenbrock.I_STIFF, rosenbrock.I_NSTIFF) == (6, 4, 5)


def test_constants_are_plain_ints_shared_by_every_kernel_module():
    names = [c.name for lay in schema.LAYOUTS for c in lay.columns]
    assert len(names) == len(set(names))  # one meaning per name across the main rows
    for name, value in schema.CONSTANTS.items():
        assert type(value) is int, name  # numba folds module-level ints into the machine code
        assert getattr(schema, name) == value
        assert getattr(K, name) == value, name  # kernel.X: the same constant, re-exported
    assert schema.FLOAT_STATE.size == schema.NF == 62 and schema.FLOAT_STATE["S_Q"] == 25
    assert schema.INT_STATE["I_CELL"] + 3 == schema.I_LASTREJ
    for mod in (lanes, pathlines, rosenbrock):
        for name in ("I_STATUS", "I_REASON", "I_NACC", "S_Y", "O_RTOL", "DONE"):
            if hasattr(mod, name):
                assert getattr(mod, name) == schema.CONSTANTS[name], (mod.__name__, name)


def test_bad_layouts_are_refused():
    with pytest.raises(ValueError, match="'A'"):
        schema.Layout("x", "N", (schema.Column("A"), schema.Column("A", 2)))
    with pytest.raises(ValueError, match="width 0"):
        schema.Layout("x", "N", (schema.Column("A", 0),))


def test_method_info_by_name():
    for m in METHODS.values():
        ints = m.kernel_arrays()[-1]
        assert ints.shape == (schema.NMI,)
        assert ints[schema.M_STAGES] == m.n_stages and ints[schema.M_NERR] == m.n_err
        assert ints[schema.M_FSAL] == m.fsal_stage and ints[schema.M_KEXP] == m.error_exponent_k
        assert ints[schema.M_ADAPTIVE] == m.adaptive
        assert ints[schema.M_HASE2] == (m.name == "dop853")


def _defines(src):
    return {m[1]: int(m[2]) for m in re.finditer(r"^#define (\w+) (-?\d+)$", src, re.MULTILINE)}


@pytest.mark.parametrize("method", ["dopri5", "rk4"])
def test_opencl_defines_are_the_schema(method):
    arrays = METHODS[method].kernel_arrays()
    for kw in ({}, {"aware": False, "real": "float"}):
        src = codegen.render(codegen.Flags(method, codegen.tableau_key(arrays), **kw), arrays)
        got = _defines(src)
        for lay in (schema.FLOAT_STATE, schema.INT_STATE, schema.FLOAT_OPTIONS):
            for name, value in lay.constants().items():
                assert got.pop(name) == value, name
        for name in ("QMAX", "NEW", "RUNNING", "DONE", "EMIT_SPACING", "EV_FACE", "EV_DEPLIM"):
            assert got.pop(name) == schema.CONSTANTS[name], name
        # what else is defined is not a column (stage count, dense degree, reason codes)
        assert not any(re.match(r"[SIOPM]_", n) for n in got), got


# a state/option/method array indexed by a literal: sf[3], si[l, 1], io[0], mi[2], fo[:, 5]
BARE = re.compile(r"\b(sf|si|ssi|sub|fo|io|mi|ints|sf_all|si_all)\[([^\[\]]*,\s*)?-?\d+\s*\]")


def test_no_column_is_addressed_by_a_bare_number():
    files = list(INTEGRATE.rglob("*.py")) + list((INTEGRATE / "opencl" / "templates").glob("*.j2"))
    hits = [f"{p.name}:{i}: {line.strip()}" for p in files
            for i, line in enumerate(p.read_text().splitlines(), 1) if BARE.search(line)]
    assert not hits, "\n".join(hits)
    # and the pattern does catch what it is meant to
    assert BARE.search("si[l, 1] = reason") and BARE.search("max_steps = io[0]")
    assert not BARE.search("sf[l, S_Y + 2]") and not BARE.search("mi[M_STAGES]")
    arrays = METHODS["dopri5"].kernel_arrays()
    src = codegen.render(codegen.Flags("dopri5", codegen.tableau_key(arrays)), arrays)
    assert not BARE.search(src)


def test_a_backend_gets_one_launch_with_the_callers_arrays():
    """trace hands a backend one ``Launch``; its arrays() are those objects themselves (no copy:
    the kernel writes the state and outputs in place), in the order the kernel takes them."""
    import inspect

    import flowkit
    from flowkit.fields.analytic import SolidBodyRotation
    from flowkit.integrate.launch import FieldArrays, Launch, MethodArrays

    f = SolidBodyRotation().to_field(9)
    seen = []

    def backend(launch):
        assert isinstance(launch, Launch)
        assert isinstance(launch.field, FieldArrays) and isinstance(launch.method, MethodArrays)
        arrays = launch.arrays()
        assert arrays[0] is launch.active and arrays[-1] is launch.out_n
        assert arrays[5] is launch.field.gx and arrays[10] is launch.field.vec
        assert arrays[11] is launch.field.bk and launch.field.bk.size == 0  # in memory
        assert arrays[12] is launch.method.c and arrays[18] is launch.method.info
        assert arrays[21] is launch.sf and arrays[22] is launch.si
        assert launch.sf.shape[1] == schema.NF and launch.si.shape[1] == schema.NI
        assert launch.fo.shape == (schema.NFO,) and launch.io.shape == (schema.NIO,)
        seen.append(len(arrays))
        K.advance(launch)

    lines = flowkit.trace(f, np.full((4, 3), 0.3), backend=backend, max_length=1.0)
    assert len(lines) == 4 and seen
    params = list(inspect.signature(K._advance_lines.py_func).parameters)
    kernel_params = params[2:params.index("k")]  # (then the scratch arrays of one line)
    assert seen[0] == len(kernel_params) and kernel_params[0] == "active"
