"""The one FFT seam of phyloc: length padding, normalization, pyFFTW plans and wisdom.

Nothing else in phyloc imports :mod:`pyfftw`. Conventions (those of NumPy):

.. math:: \\mathrm{fft}(a)_k = \\sum_m a_m e^{-j2π mk/L}, \\qquad
          \\mathrm{ifft}(A)_m = \\frac1L \\sum_k A_k e^{+j2π mk/L}.

Backends
    ``pyfftw`` (planned FFTW transforms, threads, wisdom cached on disk) when importable, else
    ``scipy.fft`` (pocketfft) with ``workers`` threads. :func:`set_backend` forces one.

Planning and reproducibility
    Plans are made with ``FFTW_ESTIMATE`` by default: FFTW picks the algorithm by its
    heuristics, the same in every process, so every Dask worker computes the same bits as the
    main process. Timed plans (``FFTW_MEASURE``, ``FFTW_PATIENT``, :func:`set_backend`) can
    differ between processes and change the last bits of a result, which a particle filter's
    resampling then carries on; measured, the estimated plan of the padded length of the
    DiPNet system (L = 20480) costs the same as the measured one (60 against 63 µs per FFT,
    ``phyloc bench phy``).

Wisdom
    Timed plans are remembered in ``$PHYLOC_CACHE_DIR/fftw_wisdom.json`` (default
    ``~/.cache/phyloc``), so a second process plans in milliseconds. Writes are atomic; an
    unreadable wisdom file is ignored (and replaced on the next save). Estimated plans neither
    read nor write wisdom (FFTW would otherwise reuse a timed plan found there).

References
----------
M. Frigo and S. G. Johnson, "The design and implementation of FFTW3," Proc. IEEE 93(2),
pp. 216–231, 2005.

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import functools
import json
import math
import os
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np
import scipy.fft

from phyloc.errors import ValidationError

try:  # pragma: no cover - exercised implicitly by which backend is active
    import pyfftw

    _HAVE_PYFFTW = True
except ImportError:  # pragma: no cover
    pyfftw = None
    _HAVE_PYFFTW = False

_state = {
    "backend": "pyfftw" if _HAVE_PYFFTW else "scipy",
    "threads": None,
    "planner_effort": "FFTW_ESTIMATE",
    "wisdom_loaded": False,
}
_plans: dict = {}
_lock = threading.Lock()


def default_threads() -> int:
    """Threads for FFTs: ``PHYLOC_FFT_THREADS`` or the CPUs this process may use."""
    env = os.environ.get("PHYLOC_FFT_THREADS")
    if env:
        return max(1, int(env))
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def backend() -> str:
    """The active backend, ``"pyfftw"`` or ``"scipy"``."""
    return _state["backend"]


def set_backend(name: str, *, threads: int | None = None, planner_effort: str | None = None):
    """Choose the FFT backend (``"pyfftw"`` or ``"scipy"``), thread count and FFTW effort.

    ``planner_effort`` is one of ``FFTW_ESTIMATE``, ``FFTW_MEASURE``, ``FFTW_PATIENT``.
    """
    allowed = {"pyfftw", "scipy"}
    if name not in allowed:
        raise ValidationError("fft.backend", name, f"one of {sorted(allowed)}")
    if name == "pyfftw" and not _HAVE_PYFFTW:
        raise ValidationError("fft.backend", name, "pyfftw is not installed; use 'scipy'")
    efforts = ("FFTW_ESTIMATE", "FFTW_MEASURE", "FFTW_PATIENT")
    if planner_effort is not None and planner_effort not in efforts:
        raise ValidationError("fft.planner_effort", planner_effort, f"one of {efforts}")
    with _lock:
        _state["backend"] = name
        if threads is not None:
            _state["threads"] = max(1, int(threads))
        if planner_effort is not None:
            _state["planner_effort"] = planner_effort
        _plans.clear()


def threads() -> int:
    """Threads the FFTs use."""
    return _state["threads"] or default_threads()


# -- lengths ---------------------------------------------------------------------------------
def next_fast_len(n: int) -> int:
    """Smallest length >= n that FFTs fast (factors 2, 3, 5 only)."""
    return _smooth_len(int(n))


@functools.lru_cache(maxsize=256)
def prev_fast_len(n: int) -> int:
    """Largest 5-smooth length <= n (n >= 1); cached (a table of one link asks every time)."""
    m = int(n)
    while m > 1 and not _is_smooth(m):
        m -= 1
    return max(m, 1)


def _is_smooth(m: int) -> bool:
    for p in (2, 3, 5):
        while m % p == 0:
            m //= p
    return m == 1


def _smooth_len(n: int) -> int:
    # 5-smooth lengths suit FFTW and pocketfft alike; scipy's helper finds the next one.
    return int(scipy.fft.next_fast_len(n, real=True))


# -- wisdom ----------------------------------------------------------------------------------
def wisdom_path() -> Path:
    """Where FFTW wisdom is kept: ``$PHYLOC_CACHE_DIR/fftw_wisdom.json``."""
    root = os.environ.get("PHYLOC_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "phyloc"
    )
    return Path(root) / "fftw_wisdom.json"


def _load_wisdom() -> None:
    if _state["wisdom_loaded"] or not _HAVE_PYFFTW:
        return
    _state["wisdom_loaded"] = True
    try:
        data = json.loads(wisdom_path().read_text())
        pyfftw.import_wisdom(tuple(s.encode("ascii") for s in data["wisdom"]))
    except (OSError, ValueError, KeyError, TypeError):
        pass  # no or unreadable wisdom: plan afresh


def save_wisdom() -> Path | None:
    """Write the current FFTW wisdom to :func:`wisdom_path` atomically (None if not pyfftw)."""
    if not _HAVE_PYFFTW:
        return None
    path = wisdom_path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        text = json.dumps({"wisdom": [w.decode("ascii") for w in pyfftw.export_wisdom()]})
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".wisdom-", suffix=".tmp")
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except OSError:
        return None  # a read-only cache is not an error; plans are just slower next time
    return path


# -- planned batched transforms ----------------------------------------------------------------
class BatchFFT:
    """A planned forward FFT of a ``[batch, length]`` complex128 array along its last axis.

    Holds aligned input/output buffers. :meth:`execute` transforms ``self.input`` into
    ``self.output`` (or into a caller's aligned, C-contiguous ``out`` of the same shape).
    """

    def __init__(self, batch: int, length: int, *, n_threads: int | None = None):
        self.shape = (int(batch), int(length))
        self.backend = backend()
        self.band = None  # half-width of the spectrum last scattered by `centered`
        self.lock = threading.Lock()  # one transform at a time through the shared buffers
        self.n_threads = n_threads or threads()
        timed = _state["planner_effort"] != "FFTW_ESTIMATE"
        if self.backend == "pyfftw":
            if timed:
                _load_wisdom()
            self.input = pyfftw.zeros_aligned(self.shape, dtype=np.complex128)
            self.output = pyfftw.empty_aligned(self.shape, dtype=np.complex128)
            self._plan = pyfftw.FFTW(
                self.input,
                self.output,
                axes=(-1,),
                direction="FFTW_FORWARD",
                flags=(_state["planner_effort"],),
                threads=self.n_threads,
            )
            self.input[...] = 0  # FFTW_MEASURE scribbles on the buffers while planning
            if timed:
                save_wisdom()
        else:
            self.input = np.zeros(self.shape, dtype=np.complex128)
            self.output = np.empty(self.shape, dtype=np.complex128)
            self._plan = None

    def execute(self, out: np.ndarray | None = None) -> np.ndarray:
        """Run the transform of :attr:`input`; returns the output array."""
        if self._plan is None:
            res = scipy.fft.fft(self.input, axis=-1, workers=self.n_threads)
            if out is None:
                self.output[...] = res
                return self.output
            out[...] = res
            return out
        target = self.output if out is None else out
        if self._plan.output_array is not target:  # a previous call may have redirected it
            try:
                self._plan.update_arrays(self.input, target)
            except ValueError:  # misaligned caller array: transform, then copy
                self._plan.update_arrays(self.input, self.output)
                self._plan.execute()
                target[...] = self.output
                return target
        self._plan.execute()
        if out is not None:  # the plan must not keep the caller's array (and its memory) alive
            self._plan.update_arrays(self.input, self.output)
        return target

    def centered(self, spectrum: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Forward FFT of zero-padded centred spectra (thread-safe).

        ``spectrum [b, N]`` (b <= batch, N odd) holds bins ``n = −(N−1)/2 … (N−1)/2``; bin n goes
        to index ``n mod L`` of the padded row, so output k is ``Σ_n c_n e^{−j2πnk/L}``. Returns
        ``out`` (``[b, L]``) or a view of the first b rows of :attr:`output` (valid until the
        next call).
        """
        b, N = spectrum.shape
        h = (N - 1) // 2
        L = self.shape[1]

        def fill(buf):
            buf[:b, : h + 1] = spectrum[:, h:]  # n = 0 … h
            buf[:b, L - h :] = spectrum[:, :h]  # n = −h … −1 (the middle stays zero)

        return self.filled(fill, b, h, out)

    def filled(self, fill, b: int, h: int, out: np.ndarray | None = None) -> np.ndarray:
        """Forward FFT of ``b`` zero-padded centred spectra of half-width ``h`` that ``fill``
        writes straight into the transform's input (thread-safe).

        ``fill(buf)`` must write bins ``n = 0 … h`` of row r to ``buf[r, 0 … h]`` and bins
        ``n = −h … −1`` to ``buf[r, L − h … L − 1]`` for ``r < b``; the middle of every row is
        zero when it is called. What :meth:`centered` does with a copy, for a caller that
        computes the spectra and can write them where they go (one pass less). Returns as
        :meth:`centered`.
        """
        with self.lock:
            buf = self.input
            if self.band != h:  # another spectrum width used this plan: clear the padding
                buf[...] = 0
                self.band = h
            fill(buf)
            if out is not None and b == self.shape[0]:
                return self.execute(out=out)
            res = self.execute()
            if out is None:
                return res[:b]
            out[...] = res[:b]
            return out


#: Batches of fewer rows than this get one-thread plans: a few transforms gain little from
#: threads, and on a busy machine a multi-threaded plan waits for all of them.
ONE_THREAD_BELOW = 4


def batch_fft(batch: int, length: int) -> BatchFFT:
    """A cached :class:`BatchFFT` for this shape (one plan per shape, backend and threads;
    one thread for batches below :data:`ONE_THREAD_BELOW`)."""
    n = 1 if batch < ONE_THREAD_BELOW else threads()
    key = (batch, length, backend(), n)
    with _lock:
        plan = _plans.get(key)
        if plan is None:
            plan = _plans[key] = BatchFFT(batch, length, n_threads=n)
        return plan


def aligned_empty(shape, dtype=np.complex128) -> np.ndarray:
    """An uninitialised array aligned for SIMD FFTs (pyFFTW) or a plain one (SciPy)."""
    if _HAVE_PYFFTW:
        return pyfftw.empty_aligned(shape, dtype=dtype)
    return np.empty(shape, dtype=dtype)


# -- recycled output arrays --------------------------------------------------------------------
#: Arrays of at least this many bytes are recycled by :func:`recycled_empty`; smaller ones come
#: from malloc, which reuses freed memory of that size by itself.
RECYCLE_MIN_BYTES = 1 << 22
#: At most this many arrays are tracked at a time (later ones are plain fresh arrays).
RECYCLE_MAX_ARRAYS = 8
#: A free array is kept this many calls of :func:`recycled_empty` that do not take it, then
#: released: a pipeline that asks for a few arrays per round (a synthesis its signals, a table
#: its spectrum and its values) finds each of them again in the next round.
RECYCLE_KEEP_CALLS = 4
#: A free array larger than this is released at the first call that does not take it: the
#: tables of a 1000-agent network are gigabytes each, and one kept while the next realization
#: (another number of links, so another shape) allocates its own doubled the peak memory
#: (12.8 -> 23 GB). Zeroing fresh memory is ~15 % of a table's cost, not worth a second copy.
RECYCLE_KEEP_MAX_BYTES = 1 << 28
_recycled: list[list] = []  # [owner, array, refs of a free array, refs of a free owner, idle]


def _view_owner(arr: np.ndarray):
    """The array NumPy makes the base of every view of ``arr`` (bases collapse to the first
    array that owns its data), or None if that is ``arr`` itself."""
    o = arr
    while not o.flags.owndata and type(o.base) is type(arr):
        o = o.base
    return None if o is arr else o


def _refs(rec: list) -> tuple[int, int]:
    # counted the same way at tracking time (the free state) and at every check
    return sys.getrefcount(rec[1]), (0 if rec[0] is None else sys.getrefcount(rec[0]))


def _is_free(rec: list) -> bool:
    # Nothing refers to the array or to its memory's owner beyond what did when it was free:
    # any view, slice or reshape refers to the owner, anything holding the array to the array.
    return _refs(rec) == (rec[2], rec[3])


def recycled_empty(shape, dtype=np.complex128) -> np.ndarray:
    """An uninitialised aligned array (as :func:`aligned_empty`) that reuses the memory of a
    large array it handed out before once nothing refers to that array any longer.

    Fresh memory is zeroed by the operating system on first touch, which for a correlation
    table of β ≈ 8 costs ~10 µs per link against ~66 µs for its FFT (``phyloc bench phy``).
    The last arrays handed out (at most :data:`RECYCLE_MAX_ARRAYS`, each at least
    :data:`RECYCLE_MIN_BYTES`) are tracked; a tracked array of the requested shape and dtype
    with no view, slice or other reference left (reference counts, exact in CPython) is handed
    out again. A free tracked array that is not taken is released after
    :data:`RECYCLE_KEEP_CALLS` calls, so the memory kept beyond what the caller holds is at
    most what it dropped during its last few calls; :func:`release_recycled` releases it at
    once.
    """
    shape = tuple(int(n) for n in np.atleast_1d(shape))
    dtype = np.dtype(dtype)
    if math.prod(shape) * dtype.itemsize < RECYCLE_MIN_BYTES:
        return aligned_empty(shape, dtype)
    with _lock:
        busy, free = [], []
        for rec in _recycled:
            (free if _is_free(rec) else busy).append(rec)
        fits = [r for r in free if r[1].shape == shape and r[1].dtype == dtype]
        hit = min(fits, key=lambda r: r[4]) if fits else None  # the last one handed out
        kept = busy
        for rec in busy:
            rec[4] = 0
        for rec in free:
            if rec is not hit:
                rec[4] += 1
                if rec[4] <= RECYCLE_KEEP_CALLS and rec[1].nbytes <= RECYCLE_KEEP_MAX_BYTES:
                    kept.append(rec)
        if hit is None:
            arr = aligned_empty(shape, dtype)
            hit = [_view_owner(arr), arr, 0, 0, 0]
            del arr
            hit[2:4] = _refs(hit)
        hit[4] = 0
        while len(kept) >= RECYCLE_MAX_ARRAYS:  # make room: the longest idle free array first
            idle = [r for r in kept if _is_free(r)]
            if not idle:
                break
            drop = max(idle, key=lambda r: r[4])
            kept = [r for r in kept if r is not drop]  # by identity (== compares the arrays)
        _recycled[:] = [*kept, hit] if len(kept) < RECYCLE_MAX_ARRAYS else kept
        return hit[1]


def release_recycled() -> int:
    """Forget the free arrays :func:`recycled_empty` keeps for reuse; returns how many."""
    with _lock:
        before = len(_recycled)
        _recycled[:] = [rec for rec in _recycled if not _is_free(rec)]
        return before - len(_recycled)


# -- one-off transforms ------------------------------------------------------------------------
def fft(a, axis: int = -1) -> np.ndarray:
    """Unnormalized forward DFT along ``axis`` (NumPy convention)."""
    return scipy.fft.fft(np.asarray(a), axis=axis, workers=threads())


def ifft(a, axis: int = -1) -> np.ndarray:
    """Inverse DFT along ``axis`` with the ``1/L`` factor (NumPy convention)."""
    return scipy.fft.ifft(np.asarray(a), axis=axis, workers=threads())
