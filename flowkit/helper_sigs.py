"""The helpers each kernel's compilation asks for, with their argument types, in the
order its typing asks for them (written by `python -m flowkit.write_helper_sigs`
on an empty cache; tests/test_compile_cost.py checks it against a default trace;
flowkit/parallel_compile.py says what it is for)."""

from numba.core import types as t

F, I, B = t.float64, t.int64, t.boolean
F1, F2, F3, F4 = (t.Array(F, n, "C") for n in (1, 2, 3, 4))
I1, I2, I3, I4 = (t.Array(I, n, "C") for n in (1, 2, 3, 4))
B1, B2, B3, B4 = (t.Array(B, n, "C") for n in (1, 2, 3, 4))

HELPERS = {
    "flowkit.integrate.kernel._advance_lines": (
        ("flowkit.integrate.kernel", "_dense", (F2, I, I, F, F, F,)),
        ("flowkit.integrate.kernel", "_root", (F2, I, I, F, F, F, F, F,)),
        ("flowkit.integrate.kernel", "_put", (F3, F3, I1, I, F, F, F, F, F,)),
        ("flowkit.integrate.kernel", "_emit_pending", (I, I, F2, I2, F, I, I, F, F, F3, F3, I1,
         I,)),
        ("flowkit.fields.interp", "locate_axis", (F1, F, F, F,)),
        ("flowkit.integrate.kernel", "_width", (F1, F, I,)),
        ("flowkit.integrate.kernel", "_locate_cell", (F1, F, F, F,)),
        ("flowkit.integrate.kernel", "_axis_bricks", (I, I, I,)),
        ("flowkit.integrate.kernel", "_slot", (I1, I, I, I,)),
        ("flowkit.integrate.kernel", "_brick", (I1, I, I, I,)),
        ("flowkit.integrate.kernel", "_gather", (F4, I1, I1, F2,)),
        ("flowkit.integrate.kernel", "_relocate", (F1, F1, F1, F1, F1, F4, I1, F, F, F, I1, F1,
         F2,)),
        ("flowkit.integrate.kernel", "_norm3", (F, F, F,)),
        ("flowkit.integrate.kernel", "_fc", (F, F, F, I, F1, F2, F2, I,)),
        ("flowkit.integrate.kernel", "_scaled_rms", (F1, F1, F2, I, I,)),
        ("flowkit.integrate.kernel", "_initial_guess", (F1, F1, F2,)),
        ("flowkit.integrate.kernel", "_f", (F, F, F, I, B, F1, F1, F1, F1, F1, F4, I1, I1, F1, F2,
         F2, I,)),
        ("flowkit.integrate.kernel", "_initial_step", (F1, F1, F2, F, F, I, B,)),
        ("flowkit.integrate.kernel", "_save_state", (F2, I2, I, F1, F2, F, F, F, I, I, B, I,)),
        ("flowkit.integrate.kernel", "_store", (F2, I2, I, F1, F2, F, F, F, I, I, B, F, I, I, I,
         F1, I1,)),
        ("flowkit.integrate.kernel", "_start", (I, I, F2, F1, F1, F1, F1, F1, F1, F1, F4, I1, I,
         F1, I1, F2, I2, F3, F3, I1, F2, F2, F1, I1, F1, F1, F1, F1,)),
        ("flowkit.integrate.kernel", "_load_state", (F2, I2, I, F1, F2, I, F,)),
        ("flowkit.integrate.kernel", "_copy_cell", (I1, F1, F2, I1, F1, F2,)),
        ("flowkit.integrate.kernel", "_n_cells", (F1, F,)),
        ("flowkit.integrate.kernel", "_move", (I, B, F1, F, F4, I1, I1, F1, F2,)),
        ("flowkit.integrate.kernel", "_move_axis", (I, B, F1, F1, F1, F1, F4, I1, I1, F1, F2,)),
        ("flowkit.integrate.kernel", "_through_face", (I, B, F1, I, F1, F1, F1, F1, F4, I1, I1, F1,
         F2, F2,)),
        ("flowkit.integrate.kernel", "_onto_next_cell", (F, F1, F2, I, F1, F1, F1, F1, F4, I1, I1,
         F1, F2,)),
        ("flowkit.integrate.kernel", "_exit_time", (F, F1, F2, F1,)),
        ("flowkit.fields.interp", "prefetch_corners", (F4, I, I, I, I, I, I, I,)),
        ("flowkit.fields.interp", "guess_cell", (F1, F, F, F,)),
        ("flowkit.fields.interp", "prefetch_cell", (F4, I, F1, F1, F1, F1, F1, F, F, F, I,)),
        ("flowkit.integrate.kernel", "_stage_point", (F2, F2, I, F1, F, F1,)),
        ("flowkit.integrate.kernel", "_err_rescaled", (F, F2, F1, F1, I, B, F1, F1, F1,)),
        ("flowkit.integrate.kernel", "_step_end", (F1, F2, F, F1, F1, F1, I, B, B, F1, F1,)),
        ("flowkit.integrate.kernel", "_retry", (F, F, B, F, F, F, F,)),
        ("flowkit.integrate.kernel", "_brick_across", (I1, I, B, F1, F1, F1, F1, I1,)),
        ("flowkit.integrate.kernel", "_brick_at", (I1, F1, F1, F1, F1, F1, F1,)),
        ("flowkit.integrate.kernel", "_from_anchor", (F, F, F, F, F, F, F1,)),
        ("flowkit.integrate.kernel", "_stalled", (F2, I, F1, F, F1,)),
        ("flowkit.integrate.stiffness", "hlambda", (F, F, F,)),
        ("flowkit.integrate.stiffness", "stage_hlambda", (F, F2, I, I, F1, F1,)),
        ("flowkit.integrate.stiffness", "stiff_update", (I, F,)),
        ("flowkit.integrate.kernel", "_next_step", (F, F, F, F, F, B, F, F, F, F, F,)),
        ("flowkit.integrate.kernel", "pack", (I1, F3, F3, I1, F2, F1, F1, I1,)),
    ),
    "flowkit.integrate.rosenbrock._lines": (
        ("flowkit.integrate.stiffness", "cell_jacobian", (F2, F1, F, F, F, F2,)),
        ("flowkit.integrate.rosenbrock", "_rhs_jac", (F, F, F, I, F2, F1, F2, F1, F1,)),
        ("flowkit.integrate.rosenbrock", "_inv3", (F2, F2,)),
        ("flowkit.integrate.rosenbrock", "_step", (F1, F, I, F1, F2, F2, F2, F1, F1, F1, F2, F2,
         F2, F1, F1, F2, F2, F1, F1, F1,)),
        ("flowkit.integrate.stiffness", "spectral_radius_bound", (F2,)),
        ("flowkit.integrate.rosenbrock", "_event", (F1, F1, F2, F, I, F1, F, F, F2, I,)),
    ),
    "flowkit.integrate.pathlines._lines": (
        ("flowkit.integrate.pathlines", "_axis", (F1, F, F, F,)),
        ("flowkit.fields.interp", "upper", (I, I,)),
        ("flowkit.fields.interp", "corner", (I, I, I, I, I, I, I, F, F, F,)),
        ("flowkit.fields.interp", "finite_or_nan", (F, F, F,)),
        ("flowkit.fields.interp", "trilinear_vector", (F4, I, I, I, F, F, F,)),
        ("flowkit.integrate.pathlines", "_velocity", (F, F, F, F, F1, F1, F1, F1, F1, F4, F4, F, F,
         F2, I,)),
    ),
}
