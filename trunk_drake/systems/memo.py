"""Value-keyed memo cache entries: a result kept in the Drake Context, recomputed only when its key changes.

Drake invalidates every cache entry of a diagram when any continuous state is set, but an
implicit integrator's finite-difference Jacobian perturbs one state at a time: most of those
evaluations leave the plant state, and so the muscle paths, unchanged. A memo entry keeps the
last key (an array compared by value, or an object compared by identity) and result in the
Context, so a cloned Context carries its own and systems hold no state of their own.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import ValueProducer

from trunk_drake.systems.weak import weak


class Memo:
    """The last key and the result computed for it."""

    __slots__ = ("key", "value")

    def __init__(self):
        self.key, self.value = None, None


def _comparable(key):
    """Arrays compare by value (their bytes), anything else by identity (the object itself is kept)."""
    return key.tobytes() if isinstance(key, np.ndarray) else key


def declare_memo(system, description: str, key, compute, prerequisites):
    """Declare a cache entry of `system` whose ``Eval(context)`` returns ``compute(context, key(context))``,
    recomputed only when ``key(context)`` differs from the key of the last computation; `key` and
    `compute` are methods of `system` (held weakly: `weak`)."""
    key, compute = weak(key), weak(compute)

    def calc(context, value):
        memo = value.get_mutable_value()
        k = key(context)
        comparable = _comparable(k)
        same = memo.key == comparable if isinstance(comparable, bytes) else memo.key is comparable
        if not same or memo.value is None:
            memo.value = compute(context, k)
            memo.key = comparable

    entry = system.DeclareCacheEntry(description, ValueProducer(allocate=lambda: AbstractValue.Make(Memo()), calc=calc),
                                     prerequisites)
    return _MemoEntry(entry)


class _MemoEntry:
    """A memo cache entry: ``Eval(context)`` gives the result, ``ticket()`` its dependency ticket."""

    def __init__(self, entry):
        self._entry = entry

    def Eval(self, context):  # noqa: N802 (Drake naming)
        return self._entry.Eval(context).value

    def ticket(self):
        return self._entry.ticket()
