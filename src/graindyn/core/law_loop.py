"""The contact law over a batch of contacts, in SIMD lanes (issue 2).

Evaluated one contact at a time inside the pair loop, a Hertz-Mindlin contact is a
chain of square roots and divisions longer than the processor's out-of-order window,
and consecutive contacts barely overlap (BENCHMARKS.md).  Here the pair loop gathers
up to CAP touching contacts into a workspace whose rows hold one quantity each (the
inputs of contacts.contact_response, its outputs, and each history value), and one
compiled loop evaluates the law over them: with the model fixed at compile time and a
row stride the compiler knows, it runs several contacts per instruction (AVX2/AVX-512).
The law is the physics package's own source, recompiled: ``_law_rows`` and every
function it calls are copies (_jit.retarget) in which the model ids are constants and
``hrow`` (physics/history.py) points into the workspace.  The results are those of the
contact-by-contact evaluation, to the bit.

One loop is compiled per model composition (on its first use, then cached on disk) as
a C callback; the time loop, compiled once, calls it through its address
(``call_law``), so changing the law never recompiles the time loop.
"""
import numba
import numpy as np
from llvmlite import ir
from numba import carray, types
from numba.core import cgutils
from numba.extending import intrinsic

from .._jit import retarget, scalar

CAP = 128              # contacts per batch (workspace columns)
# workspace rows: the inputs of contact_response, its 11 outputs, the history values
(OVERLAP, LEVER_I, LEVER_J, R_EFF, M_EFF, NX, NY, NZ, DVX, DVY, DVZ, WX, WY, WZ, DWX, DWY,
 DWZ, MATERIAL_I, MATERIAL_J) = range(19)
OUTPUT = 19
HISTORY = OUTPUT + 11
MAX_HISTORY = 32       # most history values a model may keep
WORKSPACE = (HISTORY + MAX_HISTORY) * CAP
SIGNATURE = types.void(types.CPointer(types.float64), types.int64, types.CPointer(types.float64),
                       types.int64, types.int64, types.float64)
_LOOPS = {}


def workspace_rows(history_size):
    """Rows of a workspace for a model keeping ``history_size`` values per contact."""
    return HISTORY + history_size


@scalar
def workspace_hrow(k, c):
    """Index of history value c of contact k in the workspace."""
    return (HISTORY + c) * CAP + k


@intrinsic
def _local_workspace(typingctx):
    """A workspace on the stack of the law loop: the compiler then knows that nothing
    else points into it, which vectorizing the loop needs."""
    sig = types.CPointer(types.float64)()

    def codegen(context, builder, signature, args):
        with builder.goto_entry_block():
            return builder.alloca(ir.DoubleType(), size=WORKSPACE)
    return sig, codegen


def _law_rows(workspace, count, table, materials, columns, dt):
    """The law for contacts 0..count-1 of the workspace (template: MODEL and
    contact_response are set in each compiled copy).  The rows are copied to a
    workspace on the stack and back."""
    shared = carray(workspace, (WORKSPACE,))
    w = carray(_local_workspace(), (WORKSPACE,))
    params = carray(table, (materials, materials, columns))
    for q in range(WORKSPACE):
        w[q] = shared[q]
    for m in range(count):
        out = contact_response(  # noqa: F821 (set by law_address)
            MODEL, params, int(w[MATERIAL_I * CAP + m]),  # noqa: F821
            int(w[MATERIAL_J * CAP + m]), w[OVERLAP * CAP + m], w[LEVER_I * CAP + m],
            w[LEVER_J * CAP + m], w[R_EFF * CAP + m], w[M_EFF * CAP + m], w[NX * CAP + m],
            w[NY * CAP + m], w[NZ * CAP + m], w[DVX * CAP + m], w[DVY * CAP + m],
            w[DVZ * CAP + m], w[WX * CAP + m], w[WY * CAP + m], w[WZ * CAP + m],
            w[DWX * CAP + m], w[DWY * CAP + m], w[DWZ * CAP + m], w, m, dt)
        for q in range(11):
            w[(OUTPUT + q) * CAP + m] = out[q]
    for q in range(OUTPUT * CAP, WORKSPACE):
        shared[q] = w[q]


def law_address(model_ids):
    """Address of the compiled law loop for the model ``model_ids`` (ContactModel.ids())."""
    key = tuple(int(x) for x in model_ids)
    if key not in _LOOPS:
        from .contacts import contact_response

        suffix = "_" + "_".join(str(x) for x in key)
        laws = retarget(contact_response,
                        numba.njit(error_model="numpy", inline="always"), {},
                        {"hrow": workspace_hrow}, suffix)
        memo = {}
        template = numba.njit(_law_rows)
        loop = retarget(template, numba.cfunc(SIGNATURE, cache=True, error_model="numpy"),
                        memo, {"MODEL": key, "contact_response": laws}, suffix)
        _LOOPS[key] = loop
    return _LOOPS[key].address


@intrinsic
def call_law(typingctx, address, workspace, count, params, dt):
    """Run the law loop at ``address`` on the first ``count`` contacts of
    ``workspace`` with the pair table ``params``."""
    sig = types.void(address, workspace, count, params, dt)

    def codegen(context, builder, signature, args):
        where, work, n, table, step = args
        w = context.make_array(signature.args[1])(context, builder, work)
        p = context.make_array(signature.args[3])(context, builder, table)
        shape = cgutils.unpack_tuple(builder, p.shape, 3)
        double = ir.DoubleType()
        pointer = double.as_pointer()
        i64 = ir.IntType(64)
        kind = ir.FunctionType(ir.VoidType(), [pointer, i64, pointer, i64, i64, double])
        builder.call(builder.inttoptr(where, kind.as_pointer()),
                     [builder.bitcast(w.data, pointer), n, builder.bitcast(p.data, pointer),
                      shape[0], shape[2], step])
        return context.get_dummy_value()
    return sig, codegen


def workspace(blocks, history_size):
    """Scratch of the law loop for ``blocks`` blocks of grains: workspaces (blocks,
    rows * CAP) and the pair and grain of each column (blocks, 2, CAP)."""
    if history_size > MAX_HISTORY:
        raise ValueError(f"a model keeps at most {MAX_HISTORY} history values")
    return (np.zeros((blocks, workspace_rows(history_size) * CAP)),
            np.zeros((blocks, 2, CAP), np.int64))

