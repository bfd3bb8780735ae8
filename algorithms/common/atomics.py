"""An atomic fetch-and-add for numba kernels: threads of one parallel region take work items from a shared counter.

numba's ``prange`` deals its iterations out in fixed chunks, one per thread, before the loop starts. When items
cost very different amounts (busy layers of a volume, rows of an image that a cut-away tool crosses), or the
operating system slows one thread down, the other waits at the end. A region of one iteration per thread in which
every thread takes the next item from a counter with :func:`take` until none is left splits the work as it runs.
"""

from __future__ import annotations

from numba import types
from numba.extending import intrinsic

__all__ = ["take"]


@intrinsic
def take(typingctx, counter, amount):
    """Atomically add ``amount`` to ``counter[0]`` (a contiguous int64 array) and return its previous value: the
    next work item for the calling thread. Sequentially consistent, so no two threads get the same item."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64 and isinstance(amount, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        array = context.make_array(signature.args[0])(context, builder, args[0])
        value = context.cast(builder, args[1], signature.args[1], types.int64)
        return builder.atomic_rmw("add", array.data, value, "seq_cst")

    return types.int64(counter, amount), codegen
