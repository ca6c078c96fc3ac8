"""The contact law over a batch of contacts, in SIMD lanes.

Evaluated one contact at a time inside the pair loop, a Hertz-Mindlin contact is a
chain of square roots and divisions longer than the processor's out-of-order window,
and consecutive contacts barely overlap (BENCHMARKS.md).  Here the pair loop gathers
up to CAP touching contacts into a workspace whose rows hold one quantity each (the
inputs of response.contact_response, its outputs, the pair-table row of the contact's
materials and each history value), and one compiled loop evaluates the law over them:
with the model fixed at compile time and every access a row of one array at a stride
the compiler knows, it runs several contacts per instruction (AVX2/AVX-512).
The law is the physics package's own source, recompiled: ``_law_rows`` and every
function it calls are copies (_jit.retarget) in which the model ids are constants and
``hrow`` and ``prow`` (physics/indexing.py) point into the workspace.  The results are
those of the contact-by-contact evaluation, to the bit.

One loop is compiled per model composition (on its first use, then cached on disk) as
a C callback; the time loop, compiled once, calls it through its address
(``call_law``), so changing the law never recompiles the time loop.
"""
import ast
import inspect
import textwrap

import numpy as np
from llvmlite import ir
from numba import carray, types
from numba.core.dispatcher import Dispatcher
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..._jit import callback, kernel, retarget, scalar
from ...physics.contact import contact_force
from ...physics.registry import COL
from .bundles import LawWorkspace
from .response import contact_geometry, contact_response

CAP = 64              # contacts per batch (workspace columns)
# doubles from one workspace row to the next: rows 512 bytes apart fell into 8 of the
# 64 sets of the L1 cache, 9 or 10 rows to each 12-way set; 576 bytes apart they use
# them all (280-grain bed: pair forces 14.0-14.3 -> 13.7-13.9 us, BENCHMARKS.md)
STRIDE = CAP + 8
# workspace rows: the inputs of contact_response (a wall contact stages them), the
# data a pair's geometry is computed from (a pair stages them: its separation
# r_i - r_j, radii, masses, fixed flags, w_i and w_j), the 11 outputs of
# contact_response and the pair's overlap / smaller radius (RATIO), which pair-table
# row the column holds (TABLE: a * materials + b for materials a and b, -1 for none
# yet), the pair-table columns, the history values
(OVERLAP, LEVER_I, LEVER_J, R_EFF, M_EFF, NX, NY, NZ, DVX, DVY, DVZ, WX, WY, WZ, DWX, DWY,
 DWZ, SX, SY, SZ, R_I, R_J, M_I, M_J, FIXED_I, FIXED_J) = range(26)
W_I = FIXED_J + 1                # three rows each
W_J = W_I + 3
OUTPUT = W_J + 3
RATIO = OUTPUT + 11
TABLE = RATIO + 1
PARAMS = TABLE + 1
HISTORY = PARAMS + len(COL)
MAX_HISTORY = 32       # most history values a model may keep
WORKSPACE = (HISTORY + MAX_HISTORY) * STRIDE
SIGNATURE = types.void(types.CPointer(types.float64), types.int64, types.float64, types.int64)
_LOOPS = {}


def workspace_rows(history_size):
    """Rows of a workspace for a model keeping ``history_size`` values per contact."""
    return HISTORY + history_size


@scalar
def stage_geometry(work, c, overlap, lever_i, lever_j, r_eff, m_eff, nx, ny, nz, wx, wy, wz,
                   dwx, dwy, dwz):
    """Column c of a workspace: the inputs of contact_response that follow from the
    contact's geometry (a wall contact's from contacts._stage, a pair's in _law_rows;
    w = R'_i w_i + R'_j w_j, dw = w_i - w_j)."""
    work[OVERLAP * STRIDE + c] = overlap
    work[LEVER_I * STRIDE + c] = lever_i
    work[LEVER_J * STRIDE + c] = lever_j
    work[R_EFF * STRIDE + c] = r_eff
    work[M_EFF * STRIDE + c] = m_eff
    work[NX * STRIDE + c] = nx
    work[NY * STRIDE + c] = ny
    work[NZ * STRIDE + c] = nz
    work[WX * STRIDE + c] = wx
    work[WY * STRIDE + c] = wy
    work[WZ * STRIDE + c] = wz
    work[DWX * STRIDE + c] = dwx
    work[DWY * STRIDE + c] = dwy
    work[DWZ * STRIDE + c] = dwz


@scalar
def workspace_hrow(k, c):
    """Index of history value c of contact k in the workspace."""
    return (HISTORY + c) * STRIDE + k


@scalar
def workspace_prow(k, unused, col):
    """Index of pair-table column col of contact k in the workspace."""
    return (PARAMS + col) * STRIDE + k


def _law_rows(workspace, count, dt, pairs):
    """The law for contacts 0..count-1 of the workspace (template: MODEL,
    contact_geometry, stage_geometry and contact_response are set in each compiled
    copy); with
    ``pairs``, their geometry first (response.contact_geometry), in a loop of its own
    that leaves in the rows what a wall contact stages: with the geometry under a
    branch inside the law loop, the vectorized loop computed it for the wall
    contacts too (6.8 against 5.2 ns per wall contact)."""
    w = carray(workspace, (WORKSPACE,))
    if pairs:
        for m in range(count):
            overlap, ratio, lever_i, lever_j, r_eff, m_eff, nx, ny, nz = \
                contact_geometry(w[SX * STRIDE + m], w[SY * STRIDE + m],  # noqa: F821
                                 w[SZ * STRIDE + m], w[R_I * STRIDE + m], w[R_J * STRIDE + m],
                                 w[M_I * STRIDE + m], w[M_J * STRIDE + m], w[FIXED_I * STRIDE + m],
                                 w[FIXED_J * STRIDE + m])
            w[RATIO * STRIDE + m] = ratio
            # unrolled by hand: the vectorizer takes only innermost loops
            wix = w[W_I * STRIDE + m]
            wiy = w[(W_I + 1) * STRIDE + m]
            wiz = w[(W_I + 2) * STRIDE + m]
            wjx = w[W_J * STRIDE + m]
            wjy = w[(W_J + 1) * STRIDE + m]
            wjz = w[(W_J + 2) * STRIDE + m]
            stage_geometry(w, m, overlap, lever_i, lever_j, r_eff, m_eff, nx, ny,  # noqa: F821
                           nz, lever_i * wix + lever_j * wjx, lever_i * wiy + lever_j * wjy,
                           lever_i * wiz + lever_j * wjz, wix - wjx, wiy - wjy, wiz - wjz)
    for m in range(count):
        out = contact_response(  # noqa: F821 (set by law_address)
            MODEL, w, m, 0, w[OVERLAP * STRIDE + m], w[LEVER_I * STRIDE + m],  # noqa: F821
            w[LEVER_J * STRIDE + m], w[R_EFF * STRIDE + m], w[M_EFF * STRIDE + m], w[NX * STRIDE + m],
            w[NY * STRIDE + m], w[NZ * STRIDE + m], w[DVX * STRIDE + m], w[DVY * STRIDE + m],
            w[DVZ * STRIDE + m], w[WX * STRIDE + m], w[WY * STRIDE + m], w[WZ * STRIDE + m],
            w[DWX * STRIDE + m], w[DWY * STRIDE + m], w[DWZ * STRIDE + m], w, m, dt)
        # one store per output: a tuple indexed in a loop would keep the loop scalar
        w[OUTPUT * STRIDE + m] = out[0]
        w[(OUTPUT + 1) * STRIDE + m] = out[1]
        w[(OUTPUT + 2) * STRIDE + m] = out[2]
        w[(OUTPUT + 3) * STRIDE + m] = out[3]
        w[(OUTPUT + 4) * STRIDE + m] = out[4]
        w[(OUTPUT + 5) * STRIDE + m] = out[5]
        w[(OUTPUT + 6) * STRIDE + m] = out[6]
        w[(OUTPUT + 7) * STRIDE + m] = out[7]
        w[(OUTPUT + 8) * STRIDE + m] = out[8]
        w[(OUTPUT + 9) * STRIDE + m] = out[9]
        w[(OUTPUT + 10) * STRIDE + m] = out[10]


class _Specialize(ast.NodeTransformer):
    """Model ids made constants: ``model[c]`` replaced by its value, names assigned
    from them followed, and every ``if`` whose test is then constant replaced by the
    branch it takes, so that numba never compiles the laws the model does not use."""

    def __init__(self, model, constants):
        self.model = model
        self.known = dict(constants)

    def value(self, node):
        """The value of an expression of constants and known names, or None."""
        for sub in ast.walk(node):
            if isinstance(sub, ast.Name) and sub.id not in self.known:
                return None
            if not isinstance(sub, (ast.Name, ast.Constant, ast.Compare, ast.BoolOp,
                                    ast.UnaryOp, ast.cmpop, ast.boolop, ast.unaryop,
                                    ast.Load, ast.expr_context)):
                return None
        expression = ast.fix_missing_locations(ast.Expression(node))
        return eval(compile(expression, "<model>", "eval"), {}, self.known)

    def visit_Subscript(self, node):
        self.generic_visit(node)
        if isinstance(node.value, ast.Name) and node.value.id == "model":
            index = self.value(node.slice)
            if index is not None:
                return ast.Constant(self.model[index])
        return node

    def visit_Assign(self, node):
        self.generic_visit(node)
        if len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and isinstance(node.value, ast.Constant):
            self.known[node.targets[0].id] = node.value.value
        return node

    def visit_If(self, node):
        test = self.value(self.visit(node.test))
        if test is None:
            self.generic_visit(node)
            return node
        kept = []
        for statement in node.body if test else node.orelse:
            done = self.visit(statement)
            kept.extend(done if isinstance(done, list) else [done])
        return kept or ast.Pass()


def specialized(dispatcher, model, make, memo, swap, suffix):
    """A copy of ``dispatcher`` (whose model argument is ``model``) with the model ids
    made constants and the branches they decide pruned (_Specialize), its callees
    copied as retarget does; compiled by ``make``."""
    source = dispatcher.py_func
    tree = ast.parse(textwrap.dedent(inspect.getsource(source)))
    function = tree.body[0]
    function.decorator_list = []
    names = dict(source.__globals__)
    constants = {k: v for k, v in names.items() if type(v) is int}
    _Specialize(model, constants).visit(function)
    ast.fix_missing_locations(tree)
    code = compile(tree, inspect.getsourcefile(source), "exec")
    for name in {n.id for n in ast.walk(function) if isinstance(n, ast.Name)}:
        if name in swap:
            names[name] = swap[name]
        elif isinstance(names.get(name), Dispatcher):
            names[name] = retarget(names[name], make, memo, swap, suffix)
    scope = {}
    exec(code, names, scope)
    clone = scope[source.__name__]
    clone.__qualname__ = source.__qualname__ + suffix
    return make(clone)


def law_address(model_ids):
    """Address of the compiled law loop for the model ``model_ids`` (ContactModel.ids())."""
    key = tuple(int(x) for x in model_ids)
    if key not in _LOOPS:
        suffix = "_" + "_".join(str(x) for x in key)
        make = scalar
        swap = {"hrow": workspace_hrow, "prow": workspace_prow}
        memo = {}
        memo[contact_force] = specialized(contact_force, key, make, memo, swap, suffix)
        laws = retarget(contact_response, make, memo, swap, suffix)
        loop = retarget(kernel(_law_rows), callback(SIGNATURE), {},
                        {"MODEL": key, "contact_response": laws,
                         "contact_geometry": contact_geometry,
                         "stage_geometry": stage_geometry}, suffix)
        _LOOPS[key] = loop
    return _LOOPS[key].address


# a compiled pair walk (planar.py): block lo..hi-1, dt, then the grains n, the pair
# slots P, the history columns H, the materials M and the pair-table columns C, then
# the data of the arrays that call_walk passes, in its order
WALK_ARRAYS = {"work": types.float64, "dirty": types.uint8, "params": types.float64,
               "positions": types.float64, "velocities": types.float64,
               "angular_velocities": types.float64, "radii": types.float64,
               "masses": types.float64, "materials": types.int32, "fixed": types.int8,
               "periodic_flag": types.int64, "periodic_length": types.float64,
               "start": types.int64, "partners": types.uint32, "owner": types.uint32,
               "history": types.float64, "pair_force": types.float64, "own": types.float64,
               "pair_torque_j": types.float64, "max_overlap": types.float64}
WALK_SIGNATURE = types.void(types.int64, types.int64, types.float64, types.int64, types.int64,
                            types.int64, types.int64, types.int64,
                            *[types.voidptr] * len(WALK_ARRAYS))


@intrinsic
def call_walk(typingctx, address, lo, hi, dt, work, dirty, params, positions, velocities,
              angular_velocities, radii, masses, materials, fixed, periodic_flag,
              periodic_length, start, partners, owner, history, pair_force, own, pair_torque_j,
              max_overlap):
    """Run the pair walk compiled at ``address`` (WALK_SIGNATURE) on grains lo..hi-1:
    each array (C-contiguous, of the dtype WALK_ARRAYS names) is passed as its data,
    with the sizes the walk rebuilds them from (positions: n grains; history: P slots
    and H columns; params: M materials and C columns)."""
    arrays = (work, dirty, params, positions, velocities, angular_velocities, radii, masses,
              materials, fixed, periodic_flag, periodic_length, start, partners, owner,
              history, pair_force, own, pair_torque_j, max_overlap)
    for (name, dtype), array in zip(WALK_ARRAYS.items(), arrays):
        if not isinstance(array, types.Array) or array.layout != "C" or array.dtype != dtype:
            raise TypingError(f"call_walk: {name} must be a C-contiguous array of {dtype}, "
                              f"not {array}")
    sig = types.void(address, lo, hi, dt, *arrays)

    def codegen(context, builder, signature, args):
        where, first, last, step = args[:4]
        structs = [context.make_array(kind)(context, builder, value)
                   for kind, value in zip(signature.args[4:], args[4:])]
        named = dict(zip(WALK_ARRAYS, structs))

        def extent(name, axis):
            return builder.extract_value(named[name].shape, axis)
        byte = ir.IntType(8).as_pointer()
        sizes = [extent("positions", 0), extent("history", 0), extent("history", 1),
                 extent("params", 0), extent("params", 2)]
        data = [builder.bitcast(struct.data, byte) for struct in structs]
        i64 = ir.IntType(64)
        kind = ir.FunctionType(ir.VoidType(), [i64, i64, ir.DoubleType()] + [i64] * 5
                               + [byte] * len(data))
        builder.call(builder.inttoptr(where, kind.as_pointer()),
                     [first, last, step] + sizes + data)
        return context.get_dummy_value()
    return sig, codegen


@intrinsic
def call_law(typingctx, address, workspace, count, dt, pairs):
    """Run the law loop at ``address`` on the first ``count`` contacts of
    ``workspace``: pairs (pairs = 1, whose geometry the loop computes) or wall
    contacts (0)."""
    sig = types.void(address, workspace, count, dt, pairs)

    def codegen(context, builder, signature, args):
        where, work, n, step, kind_of = args
        w = context.make_array(signature.args[1])(context, builder, work)
        pointer = ir.DoubleType().as_pointer()
        kind = ir.FunctionType(ir.VoidType(), [pointer, ir.IntType(64), ir.DoubleType(),
                                               ir.IntType(64)])
        builder.call(builder.inttoptr(where, kind.as_pointer()),
                     [builder.bitcast(w.data, pointer), n, step, kind_of])
        return context.get_dummy_value()
    return sig, codegen


def workspace(address, blocks, history_size, planar=0):
    """The law bundle (bundles.LawWorkspace) of the law loop at ``address``
    (law_address) and the 2D pair walk at ``planar`` (planar.planar_address; 0 in 3D)
    for ``blocks`` blocks of grains: workspaces (blocks, rows * STRIDE),
    the pair, first and second grain of each column (blocks, 3, CAP), the pair loop's
    dirty flags (one byte per pair slot, sized by ``prepare``), the energies each
    block dissipated (blocks, 2) and the collisions it counted (blocks, 2)."""
    if history_size > MAX_HISTORY:
        raise ValueError(f"a model keeps at most {MAX_HISTORY} history values")
    work = _aligned_zeros((blocks, workspace_rows(history_size) * STRIDE))
    work[:, TABLE * STRIDE:(TABLE + 1) * STRIDE] = -1.0
    return LawWorkspace(address=address, planar=planar, work=work,
                        slots=np.zeros((blocks, 3, CAP), np.int64),
                        dirty=np.ones(0, np.uint8), sums=np.zeros((blocks, 2)),
                        collisions=np.zeros((blocks, 2), np.int64))


def _aligned_zeros(shape):
    """Zeros whose first element sits on a 64-byte boundary, as every row of a workspace
    then does (STRIDE doubles): the law loop's AVX-512 loads and stores no longer straddle
    two cache lines (numpy gave 48 mod 64: 6.1 against 5.9 ns per pair contact)."""
    size = int(np.prod(shape))
    buffer = np.zeros(size + 8)
    first = (-buffer.ctypes.data % 64) // 8
    return buffer[first:first + size].reshape(shape)


def prepare(law, params, pair_capacity):
    """The law bundle (bundles.LawWorkspace) made ready for a chunk: with a single
    material, its pair-table row in every column of the workspaces (the pair loop then
    does not copy it for every contact; the table may have changed between runs); with
    several, no row marked as held (TABLE), so that each column copies the row it
    needs when it first needs it (contacts.stage_table); and every pair slot marked
    dirty (its force and history may be non-zero: the lists may have been rebuilt or
    the arrays replaced since the last chunk)."""
    rows = law.work.reshape(law.work.shape[0], -1, STRIDE)
    if params.shape[0] == 1:
        rows[:, PARAMS:PARAMS + params.shape[2], :] = params[0, 0, :, None]
    else:
        rows[:, TABLE, :] = -1.0
    if law.dirty.size != pair_capacity:
        law = law._replace(dirty=np.ones(pair_capacity, np.uint8))
    law.dirty[:] = 1
    return law
