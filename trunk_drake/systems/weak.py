"""Callbacks that do not keep their system alive.

pydrake stores a port's or cache entry's callback in C++; a callback that references its Python
system (a bound method, a lambda using `self`) closes a cycle Python's garbage collector cannot see,
so every diagram built would stay in memory (about 12 MB a simulation; RobotLocomotion/drake#22515,
#24162). Every callback our systems declare goes through `weak`: the diagram keeps its systems
alive while it lives, and nothing else does.
"""

from __future__ import annotations

import weakref


def weak(method):
    """`method` (bound to a system) called through a weak reference to the system."""
    ref = weakref.WeakMethod(method)

    def call(*args):
        return ref()(*args)

    return call
