"""Numba helpers shared by the kernel modules."""

from __future__ import annotations

import types

from numba import njit


def serial_twin(kernel):
    """A thread-free copy of the ``parallel=True`` kernel ``kernel``, cached apart from it.

    Numba's on-disk cache names a function by its module, qualified name and first line, not by
    its target options (numba issue #6845). ``njit(cache=True)(kernel.py_func)`` therefore shares
    the parallel kernel's cache files, and whichever of the two compiled first is loaded for
    both: a "serial" twin that wakes the thread pool, or a parallel kernel that runs on one
    thread. The twin is a new function object over the same code with its own qualified name
    (``<name>_serial``), so it has cache files of its own and computes the same values.
    """
    f = kernel.py_func
    twin = types.FunctionType(
        f.__code__, f.__globals__, f.__name__ + "_serial", f.__defaults__, f.__closure__
    )
    twin.__qualname__ = f.__qualname__ + "_serial"
    twin.__module__ = f.__module__
    twin.__doc__ = f"Serial twin of :func:`{f.__name__}` (no threads; the same values)."
    return njit(cache=True)(twin)
