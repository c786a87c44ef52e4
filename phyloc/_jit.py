"""Numba helpers shared by the kernel modules.

* :func:`serial_twin`: a thread-free copy of a ``parallel=True`` kernel, cached apart from it;
* :func:`by_threads`: one name for a ``parallel=True`` kernel and its serial twin, calling the
  twin when Numba runs on one thread (a Dask worker on a 2-core machine), so that a run
  compiles only the variant it uses: lowering a parallel loop costs about 3× compiling the
  same loop serially, and on one thread it buys nothing;
* :func:`jit_seconds`: the time this process has spent compiling kernels or loading them from
  the cache, so that measured run times can leave it out;
* :func:`kernel_cache_empty`: whether no kernel of phyloc is in Numba's on-disk cache yet (the
  first run after an install compiles them, which a progress bar alone does not say).

References
----------
Numba issue #6845 (https://github.com/numba/numba/issues/6845: the on-disk cache does not
tell a function's target options apart); Numba's event API, ``numba.core.event``.
"""

from __future__ import annotations

import functools
import inspect
import threading
import time
import types

import numba
import numpy as np
from numba import njit
from numba.core import event as _event


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


def numba_threads() -> int:
    """The number of threads Numba's parallel kernels would use in this thread, without
    starting the thread pool when nothing has started it yet (then it is the configured
    ``NUMBA_NUM_THREADS``)."""
    from numba.np.ufunc import parallel

    if not getattr(parallel, "_is_initialized", True):
        return int(numba.config.NUMBA_NUM_THREADS)
    return int(numba.get_num_threads())


class ByThreads:
    """A ``parallel=True`` kernel (:attr:`parallel`) and its :func:`serial_twin`
    (:attr:`serial`) behind one name: a call runs the twin when Numba has one thread
    (:func:`numba_threads`), the parallel kernel otherwise.

    Both compute the same values (the kernels write disjoint rows; none reduces across the
    iterations of its parallel loop in an order-dependent way), and each is compiled, and
    cached, only when first called. A run on one thread per task therefore never lowers the
    parallel loop, which is most of a parallel kernel's compile time; only when the parallel
    kernel is compiled or cached already and the twin is not does a one-thread run load the
    parallel kernel instead (:meth:`_choose_one_thread`).

    A call passes every argument (:func:`call_arguments`), so that one compiled signature
    serves callers that leave out optional arguments and callers that pass them.
    """

    def __init__(self, kernel):
        if not kernel.targetoptions.get("parallel"):
            raise TypeError(f"{kernel.py_func.__name__} is not a parallel=True kernel")
        self.parallel = kernel
        self.serial = serial_twin(kernel)
        self.parameters = _parameters(kernel.py_func)
        self._one_thread = None  # the variant this process runs on one thread, once chosen
        functools.update_wrapper(self, kernel.py_func)

    def __call__(self, *args, **kwargs):
        """Run the serial twin on one thread, the parallel kernel otherwise."""
        if numba_threads() == 1:
            kernel = self._one_thread or self._choose_one_thread()
        else:
            kernel = self.parallel
        return kernel(*call_arguments(self.parameters, args, kwargs))

    def _choose_one_thread(self):
        """The serial twin, unless only the parallel kernel is compiled already (in this
        process or in the on-disk cache, e.g. by an in-process run whose Dask workers now run
        on one thread each): loading it is cheaper than compiling the twin, and it computes the
        same values."""
        chosen = self.serial
        if not self.serial.overloads and not _in_disk_cache(self.serial):
            if self.parallel.overloads or _in_disk_cache(self.parallel):
                chosen = self.parallel
        self._one_thread = chosen
        return chosen

    def serial_only(self):
        """The serial twin behind the same argument handling (for callers that choose it
        for small inputs whatever the thread count)."""
        return _Serial(self)

    @property
    def py_func(self):
        """The Python function both variants compile."""
        return self.parallel.py_func

    def __repr__(self) -> str:
        return f"<ByThreads {self.parallel.py_func.__qualname__}>"

    def __reduce__(self):
        # pickled by reference (a Dask payload that holds a kernel finds it by name)
        return _module_attribute, (self.__module__, self.__qualname__)


def _in_disk_cache(dispatcher) -> bool:
    """Whether Numba's on-disk cache holds a compiled signature of ``dispatcher`` (False
    when that cannot be read)."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # a private Numba interface: any failure means "not known to be cached"
        return False


def _module_attribute(module: str, name: str):
    """``module.name``, importing ``module``."""
    import importlib

    return getattr(importlib.import_module(module), name)


class _Serial:
    """The serial twin of a :class:`ByThreads` kernel, called with every argument."""

    def __init__(self, kernel: ByThreads):
        self.kernel = kernel
        functools.update_wrapper(self, kernel.serial.py_func)

    def __call__(self, *args, **kwargs):
        """Run the serial twin."""
        k = self.kernel
        return k.serial(*call_arguments(k.parameters, args, kwargs))

    @property
    def py_func(self):
        """The Python function of the twin."""
        return self.kernel.serial.py_func


def _parameters(fn) -> tuple[tuple[str, object], ...]:
    """``(name, default)`` of each parameter of ``fn`` (``inspect.Parameter.empty``: none)."""
    return tuple((p.name, p.default) for p in inspect.signature(fn).parameters.values())


def call_arguments(parameters, args: tuple, kwargs: dict) -> tuple:
    """The positional arguments of a kernel call, normalized so that one compiled signature
    serves every caller:

    * optional arguments a caller leaves out are passed with their defaults (Numba compiles
      a left-out argument as its own type, ``omitted``, so a kernel called with and without
      it was compiled twice);
    * read-only integer arrays (the index arrays of a frozen table or of a stored dataset)
      are passed as writeable copies: a read-only array is a type of its own, and the same
      kernel was compiled once for a fresh table's index and once for a stored one. Index
      arrays are small next to the data they index, and no kernel writes them.
    """
    if kwargs or len(args) < len(parameters):
        args = list(args)
        for name, default in parameters[len(args) :]:
            if name in kwargs:
                args.append(kwargs.pop(name))
            elif default is inspect.Parameter.empty:
                raise TypeError(f"missing argument {name!r}")
            else:
                args.append(default)
        if kwargs:
            raise TypeError(f"unexpected arguments {sorted(kwargs)}")
    return tuple(_writeable_index(a) for a in args)


def _writeable_index(a):
    if type(a) is np.ndarray and not a.flags.writeable and a.dtype.kind in "iu":
        return a.copy()
    return a


def by_threads(kernel) -> ByThreads:
    """Decorator over ``@njit(cache=True, parallel=True)``: the kernel and its serial twin
    under one name (:class:`ByThreads`)."""
    return ByThreads(kernel)


# -- time spent in the JIT ---------------------------------------------------------------------
class _JitClock(_event.Listener):
    """Sums the outermost holds of Numba's compiler lock: every compilation and every load of
    a compiled kernel from the on-disk cache takes it (``numba:compiler_lock`` events)."""

    def __init__(self):
        self.total = 0.0
        self._local = threading.local()

    def on_start(self, event):
        depth = getattr(self._local, "depth", 0)
        if depth == 0:
            self._local.t0 = time.perf_counter()
        self._local.depth = depth + 1

    def on_end(self, event):
        depth = getattr(self._local, "depth", 1) - 1
        self._local.depth = depth
        if depth == 0:
            self.total += time.perf_counter() - self._local.t0


_CLOCK = _JitClock()
_event.register("numba:compiler_lock", _CLOCK)


def jit_seconds() -> float:
    """Seconds this process has spent compiling Numba kernels or loading them from the cache
    (summed over threads). The difference of two readings is the JIT time between them, which
    a timed section subtracts from its wall time to report the cost of the work alone."""
    return _CLOCK.total


def kernel_cache_empty() -> bool:
    """True when Numba's on-disk cache holds no kernel of phyloc yet: no index file (``.nbi``)
    under ``NUMBA_CACHE_DIR`` when it is set, else in the package's ``__pycache__`` folders.
    Then the first run compiles every kernel it calls (about a minute on 2 cores)."""
    from pathlib import Path

    root = Path(numba.config.CACHE_DIR) if numba.config.CACHE_DIR else Path(__file__).parent
    try:
        return not any(root.rglob("*.nbi"))
    except OSError:
        return False
