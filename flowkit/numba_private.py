"""Every use flowkit makes of numba's private API, and what stands in for it without.

numba documents ``njit``, its options ``cache``, ``nogil``, ``error_model`` and ``boundscheck``,
``numba.extending``, the event API and ``numba.core.types``; nothing else here is a promise.
The pieces below cut compile time on a fresh machine or a call's overhead, and change no
result: the step loops compile to the same arithmetic with or without them, and the lines are
bit for bit the same (tests/test_jit.py).  ``AVAILABLE`` is False where one of them cannot be
imported or checked (a numba release that renamed a pass class or an attribute), or where
``FLOWKIT_NUMBA_ACCELERATORS=0``: then ``flowkit`` still imports and runs on public numba
alone (``cache=True``, numba's standard pipeline), only its first compile is slower.

- ``Lean``: numba's nopython pipeline less the passes for features the step code does not use
  (closures, ``with`` contexts, ``literally``, IR inlining, literal propagation) and its array
  rewrites; the step loops are the largest functions flowkit compiles, and those passes took
  about a third of their front end's time (numba's per-pass timings).  It keeps numba's dead
  branch pruning: a step loop's ``if arg is None`` branches vanish where the argument is None,
  so that one loop compiles to one variant per stepper and field evaluator.
- ``HELPER_OPTIONS``: no NRT (helpers never allocate; reference counting their arrays cost more
  than their work), no CPython or cfunc wrapper (they are called from compiled code only), and
  ``forceinline`` for the helpers on a kernel's per-step path (compiled once, inlined by LLVM:
  numba's IR inlining types a copy at every call site, three times the compile time).
- ``shared_dispatcher``: a helper's dispatcher that takes its turn with a second compile
  process (``compile_turn``, which parallel_compile sets while one runs).
- ``prefetch``: LLVM's prefetch intrinsic, a cache hint (a no-op function without).
- ``cache_index``, ``cache_path``, ``user_cache_dir``: what numba's disk cache holds and where.
"""

from __future__ import annotations

import contextlib
import os

from numba import njit

AVAILABLE = False
WHY = "switched off (FLOWKIT_NUMBA_ACCELERATORS=0)"
Lean = None
KERNEL_OPTIONS: dict = {}  # added to a step loop's njit options
HELPER_OPTIONS: dict = {}  # a helper's target options beside nopython and numpy's error model


def _alone(dispatcher, sig):
    return contextlib.nullcontext()


# around each helper's compilation: parallel_compile.turn while a second process compiles the
# helpers too (set there: that module builds on this one, so this one does not import it)
compile_turn = _alone

if os.environ.get("FLOWKIT_NUMBA_ACCELERATORS", "1") != "0":
    try:
        from llvmlite import ir
        from numba import types
        from numba.core import cgutils, compiler, typed_passes, untyped_passes
        from numba.core.compiler_machinery import PassManager
        from numba.core.registry import CPUDispatcher
        from numba.extending import intrinsic

        _PASSES = (untyped_passes.TranslateByteCode, untyped_passes.FixupArgs,
                   untyped_passes.IRProcessing, untyped_passes.DeadBranchPrune,
                   untyped_passes.RewriteDynamicRaises,
                   untyped_passes.ReconstructSSA, typed_passes.NopythonTypeInference,
                   typed_passes.PreLowerStripPhis, typed_passes.InlineOverloads,
                   typed_passes.NoPythonSupportedFeatureValidation, typed_passes.IRLegalization,
                   typed_passes.AnnotateTypes, typed_passes.NativeLowering,
                   typed_passes.NoPythonBackend)
        _NAMES = tuple(p._name for p in _PASSES)
        for _attr in ("get_or_insert_function",):
            getattr(cgutils, _attr)
        for _attr in ("enable_caching", "compile"):
            getattr(CPUDispatcher, _attr)
    except (ImportError, AttributeError) as e:
        WHY = f"numba {__import__('numba').__version__} lacks what they use ({e})"
    else:
        AVAILABLE, WHY = True, ""

if AVAILABLE:
    class Lean(compiler.CompilerBase):
        """numba's nopython pipeline with only the passes flowkit's step code needs."""

        def define_pipelines(self):
            pm = PassManager("lean")
            for p, name in zip(_PASSES, _NAMES):
                pm.add_pass(p, name)
            pm.finalize()
            return [pm]

    KERNEL_OPTIONS = {"_nrt": False, "pipeline_class": Lean, "no_cfunc_wrapper": True}
    HELPER_OPTIONS = {"boundscheck": None, "_nrt": False, "no_cpython_wrapper": True,
                      "no_cfunc_wrapper": True}

    class _Shared(CPUDispatcher):
        """Takes its turn with a second compile process, where one runs: waits for the other's
        copy of a helper instead of compiling its own."""

        def compile(self, sig):
            with compile_turn(self, sig):
                return super().compile(sig)

    def shared_dispatcher(fn, options: dict):
        d = _Shared(py_func=fn, locals={},
                    targetoptions={"nopython": True, "error_model": "numpy", **HELPER_OPTIONS,
                                   **options},
                    pipeline_class=Lean)
        d.enable_caching()
        return d

    @intrinsic
    def prefetch(typingctx, arr, idx):
        """Ask the cache for the element ``arr.flat[idx]`` (C-contiguous ``arr``).  A hint
        only: no value is read, results are unchanged, and an address off the array cannot
        fault."""
        if not isinstance(arr, types.Array) or not isinstance(idx, types.Integer):
            return None

        def codegen(context, builder, sig, args):
            ary = context.make_array(sig.args[0])(context, builder, args[0])
            item = context.get_abi_sizeof(context.get_data_type(sig.args[0].dtype))
            off = builder.mul(context.cast(builder, args[1], sig.args[1], types.intp),
                              context.get_constant(types.intp, item))
            ptr = builder.gep(builder.bitcast(ary.data, ir.IntType(8).as_pointer()), [off])
            i32 = ir.IntType(32)
            fnty = ir.FunctionType(ir.VoidType(), [ptr.type, i32, i32, i32])
            fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0")
            # read, keep in all cache levels, data cache
            builder.call(fn, [ptr, ir.Constant(i32, 0), ir.Constant(i32, 3),
                              ir.Constant(i32, 1)])
            return context.get_dummy_value()

        return types.void(arr, idx), codegen
else:
    def shared_dispatcher(fn, options: dict):
        return njit(cache=True, error_model="numpy")(fn)

    @njit(cache=True)
    def prefetch(arr, idx):
        """A cache hint where numba's internals allow one (see above); here it does nothing."""


def cache_index(dispatcher, sig=None):
    """(the key ``sig`` has in numba's disk cache index, the index as a dict) of a cached
    dispatcher, read as numba's ``Cache.load_overload`` reads it; None where it cannot be read."""
    try:
        cache = dispatcher._cache
        key = cache._index_key(sig, dispatcher.targetctx.codegen())
        return key, cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 (numba internals: the caller then compiles as usual)
        return None


def cache_path(dispatcher) -> str | None:
    """The folder numba's disk cache keeps ``dispatcher`` in (None where it cannot say)."""
    cache = getattr(dispatcher, "_cache", None)
    return getattr(cache, "cache_path", None) or getattr(cache, "_cache_path", None)


def user_cache_dir() -> str | None:
    """numba's per-user cache folder (``~/.cache/numba`` on Linux), None where unknown."""
    try:
        from numba.misc.appdirs import AppDirs

        return AppDirs(appname="numba", appauthor=False).user_cache_dir
    except Exception:  # noqa: BLE001
        return None
