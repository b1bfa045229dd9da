"""The integrators' data contract (integrate/schema.py): each column means, in every backend,
what its declaration says; no row is addressed past its end; the OpenCL source defines the same
columns; and no column is addressed by a bare number anywhere.

The checks read the columns back independently of the code that wrote them: the state a kernel
leaves in ``sf``/``si`` against the vertices it emitted and the exact field there, and a state
written here by name against a Runge–Kutta step computed here from the method's tableau."""

import ast
import re
from pathlib import Path

import numpy as np
import pytest

from flowkit import trace
from flowkit.fields.analytic import LinearField
from flowkit.integrate import kernel as K
from flowkit.integrate import lanes, schema
from flowkit.integrate.methods import METHODS
from flowkit.integrate.opencl import codegen

INTEGRATE = Path(schema.__file__).parent
# a linear field: trilinear interpolation reproduces it, so the exact velocity is the kernel's
SPIRAL = LinearField.spiral(omega=1.0, rate=-0.2, axial=0.3)
BOUNDS = [[-2.0, 2.0], [-2.5, 2.5], [-1.0, 3.0]]
FIELD = SPIRAL.to_field(shape=(9, 11, 7), bounds=BOUNDS)


def _f(y, param):
    """The right-hand side the state columns are documented to hold: (v, |v|) with time as the
    parameter, (v / |v|, 1 / |v|) with arc length."""
    v = SPIRAL.velocity(np.asarray(y[:3])[None])[0]
    sp = np.linalg.norm(v)
    return np.r_[v, sp] if param == "time" else np.r_[v / sp, 1.0 / sp]


def _ocl_advance():
    pytest.importorskip("pyopencl")
    from flowkit.integrate.opencl.backend import OpenCLAdvance
    from flowkit.integrate.opencl.device import OpenCLUnavailable

    try:
        return OpenCLAdvance()
    except OpenCLUnavailable as e:
        pytest.skip(str(e))


@pytest.mark.parametrize("param", ["time", "arc_length"])
@pytest.mark.parametrize("backend,method,aware", [
    ("numba", "dopri5", True),    # the scalar kernel
    ("numba", "rk4", False),      # the lock-step, fixed steps
    ("numba", "dopri5", False),   # the lock-step, adaptive
    ("opencl", "dopri5", True),
])
def test_a_suspended_state_means_what_its_columns_say(backend, method, aware, param):
    """Lines suspended every 3 vertices: in the state they leave, S_Y is the last vertex, S_TAU
    and S_DEP its parameter and the other one, S_K0 the field there, S_H a step in the line's
    direction, I_NACC the steps that emitted, and (cell-aware) I_CELL, S_LO and S_HI its cell.
    A kernel writing a column under the wrong name, or past a column's declared width, fails."""
    advance = lanes.advance if backend == "numba" else _ocl_advance()
    rng = np.random.default_rng(3)
    seeds = rng.uniform([-1.5, -1.5, -0.5], [1.5, 1.5, 1.0], (6, 3))
    emitted, checked = {}, [0]
    gx, gy, gz = FIELD.grid.kernel_args()[:3]

    def checking(launch):
        ran = advance(launch)
        sf, si = launch.sf, launch.si
        for n, line in enumerate(launch.active):
            m = int(launch.out_n[n])
            emitted[line] = emitted.get(line, 0) + m
            if si[line, schema.I_STATUS] != schema.RUNNING or m == 0:
                continue
            y = sf[line, schema.S_Y:schema.S_Y + 3]
            assert np.array_equal(y, launch.out_p[n, m - 1])
            t, s = launch.out_par[n, m - 1, :2]
            pair = (t, s) if param == "time" else (s, t)
            assert (sf[line, schema.S_TAU], sf[line, schema.S_DEP]) == pair
            want = _f(y, param)
            k0 = sf[line, schema.S_K0:schema.S_K0 + 4]
            assert np.allclose(k0, want, rtol=1e-12, atol=1e-12 * np.abs(want).max()), (k0, want)
            assert np.sign(sf[line, schema.S_H]) == launch.dirs[line] != 0
            assert si[line, schema.I_NACC] == emitted[line] - 1  # the seed, then one per step
            assert si[line, schema.I_NREJ] >= 0 and si[line, schema.I_REASON] == 0
            if aware:
                ci = si[line, schema.I_CELL:schema.I_CELL + 3]
                lo = sf[line, schema.S_LO:schema.S_LO + 3]
                hi = sf[line, schema.S_HI:schema.S_HI + 3]
                nodes = [g[[c, c + 1]] for g, c in zip((gx, gy, gz), ci)]
                assert [g[0] for g in nodes] == lo.tolist() and [g[1] for g in nodes] == hi.tolist()
                assert np.all((lo <= y) & (y <= hi))
            checked[0] += 1
        return ran

    lines = trace(FIELD, seeds, backend=checking, method=method, cell_aware=aware, parameter=param,
                  direction="both", max_length=4.0, rtol=1e-5, budget=3)
    assert checked[0] >= 20 and len(lines) == len(seeds)


@pytest.mark.parametrize("method", ["rk4", "dopri5", "dop853"])
def test_a_state_written_by_name_resumes_as_documented(method):
    """A line written here as suspended mid-way (position, parameter, dependent, step, f there,
    step counts: each by its column name) takes from the kernel the Runge–Kutta steps computed
    here from the method's tableau; then its state holds the new point and f there (the f(y1)
    stage, M_FSAL)."""
    m = METHODS[method]
    h, tau0, dep0, nacc0 = 0.05, 0.7, 1.3, 11
    y0 = np.array([0.9, -0.4, 0.2, dep0])
    got = {}

    def resume(launch):
        sf, si, active = launch.sf, launch.si, launch.active
        for line in active:  # every line: the same state
            sf[line] = 0.0
            si[line] = 0
            sf[line, schema.S_Y:schema.S_Y + 3] = y0[:3]
            sf[line, schema.S_DEP] = dep0
            sf[line, schema.S_TAU] = tau0
            sf[line, schema.S_H] = h
            sf[line, schema.S_ERRP] = 1e-4
            sf[line, schema.S_K0:schema.S_K0 + 4] = _f(y0, "time")
            sf[line, schema.S_ANCHOR:schema.S_ANCHOR + 3] = y0[:3]
            sf[line, schema.S_ANCHOR + 3] = tau0
            sf[line, schema.S_LAST_S] = -np.inf
            si[line, schema.I_STATUS] = schema.RUNNING
            si[line, schema.I_NACC] = nacc0
            si[line, schema.I_CELL:schema.I_CELL + 3] = -1
        K.advance(launch)  # the scalar kernel (plain stepping: no cell carried over)
        n = launch.out_n[0]
        got.update(p=launch.out_p[0, :n].copy(), par=launch.out_par[0, :n, :2].copy(),
                   sf=sf[active[0]].copy(), si=si[active[0]].copy())
        si[active, schema.I_STATUS] = schema.DONE  # and the trace ends here

    trace(FIELD, np.zeros((1, 3)), backend=resume, method=method, direction="forward", step=h,
          cell_aware=False, max_step=h, rtol=1e3, max_length=50.0, budget=2, empty="warn")
    # the same two steps here, from the tableau (the field is linear: the kernel's is exact)
    y, t, ref = y0.copy(), tau0, []
    for _ in range(2):
        k = np.zeros((m.n_stages, 4))
        for i in range(m.n_err):
            k[i] = _f(y + h * (m.a[i, :i] @ k[:i]), "time")
        y = y + h * (m.b[:m.n_err] @ k[:m.n_err])
        t += h
        ref.append((y.copy(), t))
    scale = np.abs(y0).max()
    assert got["p"].shape == (2, 3)
    for (yr, tr), p, (tk, sk) in zip(ref, got["p"], got["par"]):
        assert np.allclose(p, yr[:3], rtol=0, atol=1e-13 * scale), (p, yr)
        assert tk == pytest.approx(tr, abs=1e-14) and sk == pytest.approx(yr[3], abs=1e-13 * scale)
    sf, si = got["sf"], got["si"]
    assert np.array_equal(sf[schema.S_Y:schema.S_Y + 3], got["p"][-1])
    assert np.allclose(sf[schema.S_K0:schema.S_K0 + 4], _f(ref[-1][0], "time"), atol=1e-13 * scale)
    assert si[schema.I_NACC] == nacc0 + 2 and si[schema.I_STATUS] == schema.RUNNING


COLUMN = re.compile(r"[SI]_[A-Z0-9]+")


def _columns(mod, tree, rows):
    """Where ``tree`` (code of module ``mod``) names a column of one of ``rows`` (array -> its
    row), the offset it compiles with: (what, value, row, name) for each ``arr[.., NAME`` (or
    ``arr[.., K.NAME``) and for each other bare NAME of a column of those rows (the column
    argument of a shared helper, ``_load_state(.., I_LASTREJ, ..)``)."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) \
                and node.value.id in rows:
            for sub in ast.walk(node.slice):
                if isinstance(sub, ast.Attribute) and COLUMN.fullmatch(sub.attr):
                    value = getattr(getattr(mod, sub.value.id), sub.attr)
                    out.append((f"{node.value.id}[.., {sub.attr}]", value, rows[node.value.id],
                                sub.attr))
                elif isinstance(sub, ast.Name) and COLUMN.fullmatch(sub.id):
                    out.append((f"{node.value.id}[.., {sub.id}]", getattr(mod, sub.id),
                                rows[node.value.id], sub.id))
        elif isinstance(node, ast.Name) and COLUMN.fullmatch(node.id):
            for row in rows.values():
                if node.id in row.offsets:
                    out.append((node.id, getattr(mod, node.id), row, node.id))
    return out


def _functions(path, *names):
    tree = ast.parse(path.read_text())
    return ast.Module([n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)
                      and n.name in names], [])


def test_published_names_are_the_declared_offsets():
    """The names the kernels compile with (``schema.S_Y``, ``kernel.S_Y``, ...) are the
    declaration's offsets and row sizes, as plain ints (numba folds them into the machine code):
    this guards constants written out by hand."""
    for lay in schema.LAYOUTS:
        for name, value in {**lay.offsets, lay.size_name: lay.size}.items():
            for mod in (schema, K):
                got = getattr(mod, name)
                assert type(got) is int and got == value, (mod.__name__, name, got)


def test_bad_layouts_are_refused():
    with pytest.raises(ValueError, match="'A'"):
        schema.Layout("x", "N", (schema.Column("A"), schema.Column("A", 2)))
    with pytest.raises(ValueError, match="width 0"):
        schema.Layout("x", "N", (schema.Column("A", 0),))


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
            assert got.pop(name) == getattr(schema, name), name
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
    # (then the evaluator's and stepper's choices, and the scratch arrays of one line)
    kernel_params = params[2:params.index("vb")]
    assert seen[0] == len(kernel_params) and kernel_params[0] == "active"
