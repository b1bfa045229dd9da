"""The OpenCL backend on PoCL against the numba kernel: same lines, same reasons, same step counts.

float64: vertex for vertex within 1e-9 of the domain extent (measured: bit-identical except where
glibc's pow, which numba calls, rounds an ulp away from the correctly rounded value the OpenCL
kernel computes; then a step size differs by an ulp).  float32: the bound stated in
docs/opencl.md and tested in ``test_float32_within_bound``.  Programs are compiled once per process
(PoCL compiles take ~1 s each), so the cases share flags where they can.
"""

import importlib
import re

import numpy as np
import pytest

import flowkit
from flowkit import Field, Grid, datasets
from flowkit.fields import analytic
from flowkit.integrate.methods import METHODS
from flowkit.integrate.reasons import Reason

pytest.importorskip("pyopencl")  # the `opencl` extra; CI installs it (pocl-binary-distribution)
from flowkit.integrate.opencl import codegen, device
from flowkit.integrate.opencl.backend import OpenCLAdvance

REL = 1e-9
EPS32 = float(np.finfo(np.float32).eps)


@pytest.fixture(scope="module")
def ocl64():
    return OpenCLAdvance("opencl", dtype="float64")


@pytest.fixture(scope="module")
def ocl32():
    return OpenCLAdvance("opencl", dtype="float32")


@pytest.fixture(scope="module")
def fields():
    rot = analytic.SolidBodyRotation().to_field(shape=17)
    x = np.concatenate([np.linspace(-1, 0, 9), np.linspace(0, 1, 14)[1:] ** 1.3])  # rectilinear
    rot_rect = analytic.SolidBodyRotation().to_field(grid=Grid.from_axes(x, x, np.linspace(-1, 1, 7)))
    abc = analytic.ABCFlow().to_field(shape=24)
    room = datasets.hotroom()
    return {"rotation": rot, "rotation_rect": rot_rect, "abc": abc, "hotroom": room}


def _seeds(field, n, seed=0):
    b = field.grid.bounds
    lo = b[:, 0] + 0.1 * (b[:, 1] - b[:, 0])
    hi = b[:, 1] - 0.1 * (b[:, 1] - b[:, 0])
    return np.random.default_rng(seed).uniform(lo, hi, (n, 3))


def _limits(name):
    return {"rotation": {"max_length": 6.0}, "rotation_rect": {"max_length": 6.0},
            "abc": {"max_length": 4.0}, "hotroom": {"max_length": 6.0}}[name]


def assert_same(ref, got, extent, rel=REL):
    """Same line structure, reasons, step counts; vertices and attributes within rel."""
    np.testing.assert_array_equal(got.offsets, ref.offsets)
    for k in ref.line_data:
        np.testing.assert_array_equal(got.line_data[k], ref.line_data[k], err_msg=k)
    err = np.abs(got.points - ref.points).max(initial=0.0) / extent
    assert err <= rel, f"vertices differ by {err:.3g} of the extent"
    assert set(got.point_data) == set(ref.point_data)
    for k, v in ref.point_data.items():
        nan = np.isnan(v)
        np.testing.assert_array_equal(np.isnan(got.point_data[k]), nan, err_msg=k)
        scale = max(np.abs(v[~nan]).max(initial=0.0), 1e-300)
        d = np.abs(got.point_data[k][~nan] - v[~nan]).max(initial=0.0) / scale
        assert d <= rel, f"attribute {k} differs by {d:.3g} relative"
    return err


def _both(field, seeds, adv, **kw):
    ref = flowkit.trace(field, seeds, backend="numba", **kw)
    got = flowkit.trace(field, seeds, backend=adv, **kw)
    return ref, got


def _extent(field):
    b = field.grid.bounds
    return float(np.max(b[:, 1] - b[:, 0]))


MEASURED = {}


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("name", ["rotation", "abc", "hotroom"])
def test_float64_matches_numba(fields, ocl64, method, name):
    f = fields[name]
    attrs = ("time", "arc_length", "speed") + (("T",) if name == "hotroom" else ())
    rtol = 1e-4 if method in ("bs23",) else 1e-7
    ref, got = _both(f, _seeds(f, 6), ocl64, method=method, rtol=rtol, attributes=attrs,
                     **_limits(name))
    assert ref.n_points > 6 * 5  # real lines, not seeds only
    MEASURED[(method, name)] = assert_same(ref, got, _extent(f))


@pytest.mark.parametrize("name", ["rotation", "rotation_rect", "abc", "hotroom"])
@pytest.mark.parametrize("aware", [True, False])
def test_cell_aware_and_plain_rectilinear(fields, ocl64, name, aware):
    f = fields[name]
    ref, got = _both(f, _seeds(f, 8, 1), ocl64, cell_aware=aware, rtol=1e-6,
                     attributes=("velocity",), **_limits(name))
    assert_same(ref, got, _extent(f))


@pytest.mark.parametrize("opts", [
    {"direction": "both"},
    {"direction": "backward", "parameter": "arc_length"},
    {"spacing": 0.05},
    {"count": 40, "direction": "both"},
    {"budget": 3},  # every line suspends and continues many times
    {"budget": 2, "spacing": 0.02},  # continuation with a pending resampled step
    {"max_time": 0.7, "max_length": np.inf},
    {"max_steps": 9},
], ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()))
def test_options_match(fields, ocl64, opts):
    f = fields["abc"]
    kw = {"max_length": 3.0, "rtol": 1e-6, "attributes": ("time", "arc_length")} | opts
    ref, got = _both(f, _seeds(f, 5, 2), ocl64, **kw)
    assert_same(ref, got, _extent(f))


def test_reason_codes_match(ocl64):
    """Every reason a purpose-built case produces, identically on both backends."""
    g = Grid.regular((0, 0, 0), (0.1, 0.1, 0.1), (11, 11, 11))
    x = g.node_points()
    v = np.zeros(g.shape + (3,))
    v[..., 0] = 1.0 + 0.3 * x[..., 1]
    v[..., 1] = 0.2 * np.sin(3 * x[..., 0])
    v[7:9, 0:3, :, :] = np.nan  # a NaN block in the way of the low lines
    v[:, 8:, :, :] *= np.where(x[:, 8:, :, 0:1] > 0.5, 0.0, 1.0)  # stagnant region
    f = Field(g, v, scalars={"T": x[..., 2] * 2.0}, source="reasons test")
    seeds = np.array([[0.05, 0.1, 0.5], [0.05, 0.5, 0.5], [0.05, 0.9, 0.5], [2.0, 0.5, 0.5],
                      [0.75, 0.05, 0.5], [0.05, 0.6, 0.4], [0.1, 0.45, 0.5]])
    cases = [{}, {"max_length": 0.5}, {"max_time": 0.3, "max_length": np.inf}, {"max_steps": 3},
             {"min_step": 10.0, "rtol": 1e-12}]
    seen = set()
    for kw in cases:
        ref, got = _both(f, seeds, ocl64, attributes=("T", "speed"), **kw)
        assert_same(ref, got, 1.0)
        seen |= set(ref.line_data["reason"].tolist())
    want = {Reason.OUT_OF_DOMAIN, Reason.MAX_LENGTH, Reason.MAX_TIME, Reason.MAX_STEPS,
            Reason.STAGNATION, Reason.NAN_FIELD, Reason.SEED_OUTSIDE, Reason.STEP_UNDERFLOW}
    assert {int(r) for r in want} <= seen, sorted(seen)


def test_float32_within_bound(fields, ocl32):
    """float32 against float64 numba at equal arc lengths (resampled vertices).

    Bound (docs/opencl.md): |x32 - x64| <= C * (rtol + n_steps * eps32) * X * exp(lam * L), where
    X is the largest coordinate magnitude, n_steps the line's accepted steps, L its length and
    lam a Lipschitz constant of the field; C = 1 (measured: at most 0.2 of the bound with C = 1;
    the step sequences may differ a little, the error estimate carrying float32 noise of
    eps32 / rtol relative).  Rotation preserves distances (lam = 0); the room flow is slow and
    smooth (lam ~ max |grad u| ~ 0.3 / m).
    """
    rtol = 1e-5
    for name, lam in (("rotation", 0.0), ("hotroom", 0.3)):
        f = fields[name]
        kw = {"rtol": rtol, "spacing": 0.1, "attributes": ("time",)} | _limits(name)
        ref = flowkit.trace(f, _seeds(f, 8, 3), backend="numba", **kw)
        got = flowkit.trace(f, _seeds(f, 8, 3), backend=ocl32, **kw)
        np.testing.assert_array_equal(got.line_data["reason"], ref.line_data["reason"])
        np.testing.assert_array_equal(got.offsets, ref.offsets)
        X = np.abs(f.grid.bounds).max()
        for i in range(len(ref)):
            a, b = ref.offsets[i], ref.offsets[i + 1]
            n = ref.line_data["n_accepted"][i]
            L = kw["max_length"]
            bound = (rtol + n * EPS32) * X * np.exp(lam * L)
            err = np.abs(got.points[a:b] - ref.points[a:b]).max()
            assert err <= bound, (name, i, err, bound)
            # and float32 is not secretly float64: the difference is above float64 rounding
        assert np.abs(got.points - ref.points).max() > 1e-12


def test_image3d_path(fields):
    """The field as an image3d with hardware linear filtering (float32 texels).

    On a linear field (rotation: the filter reproduces it exactly) the lines meet the float32
    bound above.  On the room the filter cannot extend a cell's polynomial past its faces as the
    cell-aware buffer path does, so stages beyond a face see the neighbour cell: the step
    sequence changes and lines differ at the tolerance level, not the rounding level (measured
    6.9e-4 of the extent at rtol 1e-5; asserted < 2e-3).  docs/opencl.md has the filter's weight
    precision (PoCL: exact float32; NVIDIA: 8 fractional bits, emulated error 1e-3 of max |v|).
    """
    adv = OpenCLAdvance(dtype="float32", image=True)
    assert "read_imagef" in _src(image=True) and "read_imagef" not in _src()
    f = fields["rotation"]
    # (the image path never steps across faces: its kink bound needs the cell's polynomial)
    kw = {"rtol": 1e-5, "spacing": 0.1, "max_length": 6.0, "cross_faces": False}
    ref = flowkit.trace(f, _seeds(f, 8, 3), **kw)
    got = flowkit.trace(f, _seeds(f, 8, 3), backend=adv, **kw)
    np.testing.assert_array_equal(got.offsets, ref.offsets)
    for i in range(len(ref)):
        a, b = ref.offsets[i], ref.offsets[i + 1]
        bound = (1e-5 + ref.line_data["n_accepted"][i] * EPS32) * 1.0
        assert np.abs(got.points[a:b] - ref.points[a:b]).max() <= bound
    room = fields["hotroom"]
    ref = flowkit.trace(room, _seeds(room, 8, 3), **kw)
    got = flowkit.trace(room, _seeds(room, 8, 3), backend=adv, **kw)
    np.testing.assert_array_equal(got.line_data["reason"], ref.line_data["reason"])
    for i in range(len(ref)):
        a = ref.points[ref.offsets[i]:ref.offsets[i + 1]]
        b = got.points[got.offsets[i]:got.offsets[i + 1]]
        m = min(len(a), len(b))
        assert abs(len(a) - len(b)) <= 1 and m > 10
        assert np.abs(a[:m] - b[:m]).max() <= 2e-3 * _extent(room)


def test_seed_outside_and_nan_seeds(fields, ocl64):
    f = fields["rotation"]
    seeds = np.array([[5.0, 0, 0], [np.nan, 0, 0], [0.5, 0, 0]])
    ref, got = _both(f, seeds, ocl64, max_length=1.0)
    assert_same(ref, got, 2.0)
    assert list(got.line_data["reason"][:2]) == [Reason.SEED_OUTSIDE] * 2


# -- source generation ---------------------------------------------------------------------------
def _src(method="dopri5", **kw):
    m = METHODS[method]
    arrays = m.kernel_arrays()
    return codegen.render(codegen.Flags(method, codegen.tableau_key(arrays), **kw), arrays)


def test_source_contains_only_what_the_run_needs():
    plain = _src(aware=False, periodic=False, uniform=True)
    aware = _src(aware=True, periodic=True, uniform=False, real="float")
    assert "pymod" not in plain and "pymod(" in aware  # periodic wrap only when periodic
    assert "through_face(G, ev_axis" not in plain and "through_face(G, ev_axis" in aware
    assert "searchsorted" not in plain and "searchsorted" in aware  # rectilinear lookup
    assert "typedef double real" in plain and "cl_khr_fp64" in plain
    assert "typedef float real" in aware and "cl_khr_fp64" not in aware
    assert "xpow(double" in plain and "xpow(double" not in aware
    assert "image3d_t" not in plain
    assert "FP_CONTRACT OFF" in plain
    fixed = _src("rk4")
    assert "err > R(1.0)" not in fixed and "err > R(1.0)" in plain  # no error control for rk4
    assert "e3 += " in _src("dop853") and "e3 += " not in plain  # DOP853's second estimate only


def test_the_stiffness_test_takes_its_constants_from_python(monkeypatch):
    from flowkit.integrate import stiffness

    src = _src(stiff_stage=5)
    assert "hlam > 3.25)" in src and f">= {stiffness.STIFF_STEPS})" in src
    monkeypatch.setattr(stiffness, "HLAMBDA_STIFF", 2.875)
    assert "hlam > 2.875)" in _src(stiff_stage=5)


# the step loop's tuning constants, each with flags whose source uses it (DOP853: the second
# error estimate; dopri5 with its stiffness stage; cell-aware with crossing steps)
LOOP_CONSTANTS = [(n, "kernel", kw) for n, kw in [
    ("NORM_TINY", {}), ("NORM_HUGE", {}), ("ERR_TINY", {}), ("ERR_HUGE", {}),
    ("E3_WEIGHT", {"method": "dop853"}), ("NAN_SHRINK", {}), ("ERRP_MIN", {}), ("EXPO1_BETA", {}),
    ("HINIT_TINY", {}), ("HINIT_H", {}), ("HINIT_FRAC", {}), ("HINIT_FLAT", {}),
    ("HINIT_SHRINK", {}), ("HINIT_GROW", {}), ("H_AT_REST", {}), ("ROOT_ITERS", {}),
    ("ROOT_TOL", {}), ("END_DUP", {}), ("KINK_CELLS", {"cross": True}),
    ("KINK_GROW", {"cross": True}), ("KINK_SHRINK_MIN", {"cross": True}),
    ("KINK_FAIL_MAX", {"cross": True}), ("KINK_BACKOFF_BITS", {"cross": True})]] + [
    (n, "stiffness", {"stiff_stage": 5}) for n in (
        "HLAMBDA_STIFF", "STIFF_STEPS", "NONSTIFF_RESET", "STIFF_COUNT_BITS", "STIFF_COUNT_MAX",
        "STIFF_BIT")]


@pytest.mark.parametrize("real", ["double", "float"])
@pytest.mark.parametrize("name,module,kw", LOOP_CONSTANTS, ids=[c[0] for c in LOOP_CONSTANTS])
def test_the_loop_takes_its_constants_from_python(monkeypatch, name, module, kw, real):
    """A constant changed where the numba code reads it (float32's norm ranges: where codegen
    keeps them) changes the source, and each line it changes holds the new value."""
    mod = importlib.import_module(f"flowkit.integrate.{module}")
    if real == "float" and name in codegen.FLOAT32_RANGES:  # float32's own, from codegen
        new = codegen.FLOAT32_RANGES[name] * 1.0625
        mod, target, value = codegen, "FLOAT32_RANGES", codegen.FLOAT32_RANGES | {name: new}
    else:
        old = getattr(mod, name)
        new = old + 7 if isinstance(old, int) else old * 1.0625
        target, value = name, new
    lit = codegen.literal(new, real) if isinstance(new, float) else str(new)
    before = _src(real=real, **kw).splitlines()
    monkeypatch.setattr(mod, target, value)
    changed = [line for line in _src(real=real, **kw).splitlines() if line not in before]
    assert changed and all(lit in line for line in changed), (lit, changed)


def test_the_loop_has_no_numbers_of_its_own():
    """Numbers in the templates' C, outside what codegen renders: only 0, 1, 1/2 (a midpoint, a
    texel centre), 3 (the RMS over the position's components) and small indices; xpow.cl.j2's
    are its series'."""
    num = re.compile(r"(?<![\w.])(?:\d+\.\d*(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+|0[xX][0-9a-fA-F]+"
                     r"|\d+)[fFlL]?(?![\w.])")
    allowed = {"0.0", "1.0", "0.5", "3.0", "0.0f", "0.5f", "0L", "1L"} | {str(i) for i in range(10)}
    for path in sorted(codegen.TEMPLATES.glob("*.cl.j2")):
        if path.name == "xpow.cl.j2":
            continue
        text = re.sub(r"\{#.*?#\}|\{\{.*?\}\}|\{%.*?%\}|/\*.*?\*/|//[^\n]*", " ",
                      path.read_text(), flags=re.DOTALL)
        assert set(num.findall(text)) <= allowed, (path.name, set(num.findall(text)) - allowed)


def test_stages_are_the_tableau_literals():
    m = METHODS["dopri5"]
    src = _src()
    for st in range(1, m.n_stages):
        for j in range(st):
            if m.a[st, j] != 0:
                lit = codegen.literal(m.a[st, j], "double")
                assert f"{lit} * k[{j}][a]" in src
                assert float(lit.strip("()")) == m.a[st, j]  # parses back exactly
    # float32 literals are the float32-rounded values, exactly
    for x in (0.1, 1 / 3, -3.7333333333333334, 1e-30):
        lit = codegen.literal(x, "float")
        assert lit.strip("()").endswith("f")
        assert np.float32(float(lit.strip("()f"))) == np.float32(x)
    with pytest.raises(ValueError, match="non-finite"):
        codegen.literal(np.inf, "double")


def test_programs_cached_per_flags_and_device(fields, ocl64, monkeypatch):
    monkeypatch.setattr(codegen, "_programs", {})
    f = fields["rotation"]
    flowkit.trace(f, _seeds(f, 2), backend=ocl64, max_length=1.0)
    n = codegen.cached_programs()
    assert n == 1
    flowkit.trace(f, _seeds(f, 3, 5), backend=ocl64, max_length=2.0, direction="both")
    assert codegen.cached_programs() == n  # runtime options do not recompile
    flowkit.trace(f, _seeds(f, 2), backend=ocl64, max_length=1.0, method="euler")
    assert codegen.cached_programs() == n + 1


def test_chunks_and_overlap_give_the_same_lines(fields):
    """Several chunks per launch (the copy/compute pipeline) change nothing."""
    f = fields["abc"]
    seeds = _seeds(f, 40, 7)
    one = flowkit.trace(f, seeds, backend=OpenCLAdvance(), max_length=1.0)
    adv = OpenCLAdvance(chunk=7)
    many = flowkit.trace(f, seeds, backend=adv, max_length=1.0, budget=4)
    assert adv.launches > 6
    assert_same(one, many, _extent(f), rel=0.0)


# -- devices --------------------------------------------------------------------------------------
def test_device_selection_and_listing():
    infos = device.device_infos()
    assert infos and all(i.spec.startswith("opencl:") for i in infos)
    d0 = device.select_device(infos[0].spec)
    assert d0.name.strip() == infos[0].name
    assert device.select_device(f"opencl:{infos[0].platform[:4].lower()}").name.strip() == infos[0].name
    text = device.describe_devices()
    assert infos[0].name in text and "fp64" in text
    with pytest.raises(ValueError, match="index 99 out of range"):
        device.select_device("opencl:99")
    with pytest.raises(ValueError, match="no OpenCL device matches 'nosuchgpu'"):
        device.select_device("opencl:0:nosuchgpu")
    with pytest.raises(ValueError, match="expected 'opencl'"):
        device.parse_backend("cuda:0")


def test_clear_error_without_pyopencl_or_platform(monkeypatch):
    import builtins

    import pyopencl as cl

    monkeypatch.setattr(cl, "get_platforms", list)
    with pytest.raises(device.OpenCLUnavailable, match=r"pip install 'flowkit\[opencl\]'"):
        device.select_device("opencl")
    assert "flowkit[opencl]" in device.describe_devices()
    monkeypatch.undo()
    real_import = builtins.__import__

    def no_pyopencl(name, *a, **k):
        if name == "pyopencl":
            raise ImportError("No module named 'pyopencl'")
        return real_import(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_pyopencl)
    with pytest.raises(device.OpenCLUnavailable, match="needs pyopencl.*flowkit\\[opencl\\]"):
        device.select_device("opencl")


class _FakeDevice:
    def __init__(self, name, ptr):
        self.name, self.int_ptr, self.type = name, ptr, 2  # CL_DEVICE_TYPE_CPU


class _FakePlatform:
    def __init__(self, name, devs):
        self.name, self._devs = name, devs

    def get_devices(self):
        return self._devs


def test_default_device_skips_one_that_cannot_compile(monkeypatch):
    # The wheel's PoCL (LLVM 14) on a CPU its LLVM does not know: listed, but every build fails.
    old = _FakeDevice("pthread-AMD EPYC", 1)
    good = _FakeDevice("pthread-skylake-avx512-AMD EPYC", 2)
    monkeypatch.setattr(device, "platforms", lambda: [_FakePlatform("PoCL 3.0", [old]),
                                                      _FakePlatform("PoCL 3.1", [good])])
    monkeypatch.setattr(device, "_build_errors",
                        {1: "error: unknown target CPU 'generic'", 2: None})
    assert device.select_device("opencl") is good
    assert device.select_device("opencl:0:0") is old  # named explicitly: taken as asked
    device._build_errors[2] = "error: unknown target CPU 'generic'"
    with pytest.raises(device.OpenCLUnavailable,
                       match=r"can compile a kernel: error: unknown target CPU 'generic'.*"
                             r"apt install pocl-opencl-icd"):
        device.select_device("opencl")


def test_probe_reads_the_build_error(monkeypatch):
    import pyopencl as cl

    class FailingProgram:
        def __init__(self, ctx, src):
            pass

        def build(self, **kw):
            raise cl.RuntimeError("clBuildProgram failed: BUILD_PROGRAM_FAILURE\n\n"
                                  "Build on <dev>:\n\nerror: unknown target CPU 'generic'\n")

    dev = device.select_device("opencl")
    monkeypatch.setattr(device, "_build_errors", {})
    monkeypatch.setattr(cl, "Program", FailingProgram)
    assert not device.compiles(dev)
    assert device._build_errors[dev.int_ptr] == "error: unknown target CPU 'generic'"
    # a kernel build failing the same way names the cure, not just PoCL's log
    monkeypatch.setattr(codegen, "_programs", {})
    arrays = METHODS["dopri5"].kernel_arrays()
    flags = codegen.Flags(method="dopri5", tableau=codegen.tableau_key(arrays))
    with pytest.raises(device.OpenCLUnavailable, match="cannot compile kernels.*pocl-opencl-icd"):
        codegen.kernel(cl.Context([dev]), dev, flags, arrays)


def test_float64_refused_where_unsupported(monkeypatch):
    monkeypatch.setattr("flowkit.integrate.opencl.backend.supports_fp64", lambda d: False)
    assert OpenCLAdvance().dtype == np.float32  # default falls back to float32
    with pytest.raises(ValueError, match="no float64 support"):
        OpenCLAdvance(dtype="float64")


def test_cli_info_devices_and_trace_backend(tmp_path, capsys, fields):
    from flowkit.cli import main
    from flowkit.io import read_lines

    assert main(["info", "--devices"]) == 0
    out = capsys.readouterr().out
    assert "opencl:0:0" in out and device.device_infos()[0].name in out
    assert main(["info"]) == 2
    assert "give a FILE (or --devices)" in capsys.readouterr().err
    # flowkit trace --backend opencl:0:0 on the built-in room gives the numba lines
    src = str(datasets.hotroom_path())
    args = ["trace", src, "--seeds", "points:0.5,0.5,0.5:4,1,5:8,2,3", "--max-length", "3",
            "--float64", "--quiet", "--attributes", "T,speed"]
    assert main([*args, "-o", str(tmp_path / "n.h5")]) == 0
    assert main([*args, "-o", str(tmp_path / "o.h5"), "--backend", "opencl:0:0"]) == 0
    a, b = read_lines(tmp_path / "n.h5"), read_lines(tmp_path / "o.h5")
    assert a.n_points > 3
    assert_same(a, b, 10.0)
