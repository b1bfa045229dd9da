"""How flowkit's compiled helpers are compiled: two numba decorators, chosen for compile time.

``inline``: a helper on a kernel's per-step path (field evaluation, cell moves, dense output,
events).  Compiled once, as a function of its own, and inlined by LLVM into every caller
(``forceinline``), so it costs what inline code costs.  numba's IR inlining
(``inline="always"``) gives the same machine code but types and lowers a copy of the helper at
every call site: the tracing kernel took three times as long to compile on a fresh machine
(measured with benchmarks/bench_cold_start.py; docs/integrator.md, cold start).

``helper``: compiled once and called, for work off the per-step path.

Both without NRT (they never allocate, and reference counting of the arrays they take would
cost more than their work) and with numpy's error model (a division by zero gives inf or NaN,
which the step loops test for, e.g. a zero speed in arc-length mode, instead of an exception
path per division).  Constants go to them typed (``np.int64(0)``): a literal 0 or True
argument compiles one more copy per value.

``Lean``: the compiler pipeline of both and of the step loops (``lean`` adds it to a kernel's own
options): numba's nopython pipeline less the passes for features they do not use (closures,
``with`` contexts, ``literally``, numba's IR inlining, literal propagation) and its rewrites
(array-expression fusion, semantic constants, dead-branch pruning), which have nothing to act on
in code without arrays of their own or constant branches.  The step loops are the largest
functions flowkit compiles, and these passes took about a third of their front end's time
(numba's per-pass timings); the machine code is the same, and so are the lines, bit for bit.
No cfunc wrapper either: they are called from Python or from other compiled code, never
through a C pointer.
"""

from llvmlite import ir
from numba import types
from numba.core import cgutils, compiler, typed_passes, untyped_passes
from numba.core.compiler_machinery import PassManager
from numba.core.registry import CPUDispatcher
from numba.extending import intrinsic


class Lean(compiler.CompilerBase):
    """numba's nopython pipeline with only the passes flowkit's step code needs (see above)."""

    def define_pipelines(self):
        pm = PassManager("lean")
        for p in (untyped_passes.TranslateByteCode, untyped_passes.FixupArgs,
                  untyped_passes.IRProcessing, untyped_passes.RewriteDynamicRaises,
                  untyped_passes.ReconstructSSA, typed_passes.NopythonTypeInference,
                  typed_passes.PreLowerStripPhis, typed_passes.InlineOverloads,
                  typed_passes.NoPythonSupportedFeatureValidation, typed_passes.IRLegalization,
                  typed_passes.AnnotateTypes, typed_passes.NativeLowering,
                  typed_passes.NoPythonBackend):
            pm.add_pass(p, p._name)
        pm.finalize()
        return [pm]


lean = {"pipeline_class": Lean, "no_cfunc_wrapper": True}
_OPTIONS = {"nopython": True, "boundscheck": None, "_nrt": False, "error_model": "numpy",
            "no_cpython_wrapper": True, "no_cfunc_wrapper": True}


class _Shared(CPUDispatcher):
    """A helper's dispatcher that takes its turn with a second compile process, where one runs
    (``parallel_compile.turn``): it waits for the other's copy instead of compiling its own."""

    def compile(self, sig):
        from . import parallel_compile  # (not at import: `python -m` runs that module)

        with parallel_compile.turn(self, sig):
            return super().compile(sig)


def _jit(fn, **options):
    d = _Shared(py_func=fn, locals={}, targetoptions={**_OPTIONS, **options}, pipeline_class=Lean)
    d.enable_caching()
    return d


def helper(fn):
    return _jit(fn)


def inline(fn):
    return _jit(fn, forceinline=True)


@intrinsic
def prefetch(typingctx, arr, idx):
    """Ask the cache for the element ``arr.flat[idx]`` (C-contiguous ``arr``).  A hint only:
    no value is read, results are unchanged, and an address off the array cannot fault."""
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
        builder.call(fn, [ptr, ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return types.void(arr, idx), codegen
