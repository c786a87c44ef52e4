"""The FFT seam: smooth lengths, backends, plans and the on-disk wisdom cache."""

import json

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.phy import fft as phyfft


def _smooth(m):
    for p in (2, 3, 5):
        while m % p == 0:
            m //= p
    return m == 1


def test_fast_lengths_are_the_nearest_smooth_ones():
    for n in (1, 7, 367, 2569, 20552, 99991):
        up, down = phyfft.next_fast_len(n), phyfft.prev_fast_len(n)
        assert _smooth(up) and _smooth(down) and down <= n <= up
        # brute force: nothing smooth strictly between
        assert not any(_smooth(m) for m in range(down + 1, n))
        assert not any(_smooth(m) for m in range(n, up) if m != n) or _smooth(n)


@pytest.mark.parametrize("backend", ["pyfftw", "scipy"])
def test_batch_fft_equals_numpy(backend, rng):
    previous = phyfft.backend()
    try:
        phyfft.set_backend(backend, threads=1)
        plan = phyfft.batch_fft(3, 60)
        x = rng.standard_normal((3, 60)) + 1j * rng.standard_normal((3, 60))
        plan.input[...] = x
        out = phyfft.aligned_empty((3, 60))
        np.testing.assert_allclose(plan.execute(out=out), np.fft.fft(x), atol=1e-12)
        np.testing.assert_allclose(plan.execute(), np.fft.fft(x), atol=1e-12)
    finally:
        phyfft.set_backend(previous)


def test_wisdom_is_saved_and_a_corrupt_file_is_ignored(tmp_path, monkeypatch):
    monkeypatch.setenv("PHYLOC_CACHE_DIR", str(tmp_path))
    path = phyfft.wisdom_path()
    assert path.parent == tmp_path
    path.write_text("not json")
    monkeypatch.setitem(phyfft._state, "wisdom_loaded", False)
    phyfft.BatchFFT(2, 48)  # the default estimated plan neither reads nor writes wisdom
    assert path.read_text() == "not json"
    monkeypatch.setitem(phyfft._state, "planner_effort", "FFTW_MEASURE")
    phyfft.BatchFFT(2, 48)  # a timed plan: plans despite the corrupt file, saves fresh wisdom
    data = json.loads(path.read_text())
    assert any("fftw" in w for w in data["wisdom"])


def test_estimated_plans_give_the_same_bits_in_another_process(tmp_path):
    """The default plan is chosen without timing: a fresh process computes the same bits."""
    import subprocess
    import sys

    code = (
        "import hashlib, sys, numpy as np; from phyloc.phy import fft as f; "
        "b = f.BatchFFT(3, 20480); "
        "b.input[...] = np.random.default_rng(5).standard_normal((3, 20480)) + 0j; "
        "sys.stdout.write(hashlib.sha256(b.execute().tobytes()).hexdigest())"
    )
    env = {**__import__("os").environ, "PHYLOC_CACHE_DIR": str(tmp_path)}
    runs = {
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env).stdout
        for _ in range(2)
    }
    assert len(runs) == 1 and next(iter(runs))


def test_bad_backend_settings():
    with pytest.raises(ValidationError, match=r"fft\.backend = cufft"):
        phyfft.set_backend("cufft")
    with pytest.raises(ValidationError, match="planner_effort"):
        phyfft.set_backend("scipy", planner_effort="FFTW_FAST")


def test_odd_length_rows_into_a_misaligned_output(rng):
    plan = phyfft.batch_fft(2, 75)  # 75·16 bytes per row: the second row is not SIMD-aligned
    x = rng.standard_normal((2, 75)) + 1j * rng.standard_normal((2, 75))
    plan.input[...] = x
    big = phyfft.aligned_empty((5, 75))
    np.testing.assert_allclose(plan.execute(out=big[1:3]), np.fft.fft(x), atol=1e-12)
    np.testing.assert_allclose(big[1:3], np.fft.fft(x), atol=1e-12)


@pytest.mark.parametrize("backend", ["pyfftw", "scipy"])
def test_recycled_arrays_are_reused_only_when_nothing_refers_to_them(backend):
    """The memory of a dropped large array is handed out again; an array with any view, slice,
    reshape or memoryview alive, or held itself, never is."""
    if backend == "pyfftw" and not phyfft._HAVE_PYFFTW:
        pytest.skip("pyfftw not installed")
    previous = phyfft.backend()
    phyfft.set_backend(backend)
    try:
        phyfft.release_recycled()
        shape = (8, phyfft.RECYCLE_MIN_BYTES // (8 * 16))
        holders = {
            "array": lambda a: a,
            "slice": lambda a: a[2:5, 1:],
            "reshape": lambda a: a.reshape(-1),
            "view of a view": lambda a: a[1:][::2].T,
            "memoryview": lambda a: memoryview(a),
            "real part": lambda a: a.real,
        }
        for name, hold in holders.items():
            a = phyfft.recycled_empty(shape)
            a[...] = 3.0
            address = a.ctypes.data
            kept = hold(a)
            del a
            b = phyfft.recycled_empty(shape)
            assert b.ctypes.data != address, name
            b[...] = 0.0  # must not reach `kept`
            assert np.all(np.asarray(kept) == 3.0), name
            addresses = {address, b.ctypes.data}
            del kept, b
            c = phyfft.recycled_empty(shape)  # both dropped now: one of them comes back
            assert c.ctypes.data in addresses, name
            del c
        a = phyfft.recycled_empty(shape)
        address = a.ctypes.data
        del a
        assert phyfft.recycled_empty(shape).ctypes.data == address  # dropped: reused
        small = phyfft.recycled_empty((4, 4))  # below the threshold: not tracked
        assert small.shape == (4, 4) and not any(r[1] is small for r in phyfft._recycled)
        assert phyfft.release_recycled() >= 1 and not phyfft._recycled
    finally:
        phyfft.set_backend(previous)


def test_a_plan_does_not_keep_the_callers_output_alive(rng):
    """After transforming into a caller's array the plan lets go of it (or a dropped table's
    memory would stay allocated, and never be recycled, until the next transform)."""
    import sys

    plan = phyfft.batch_fft(4, 64)
    plan.input[...] = rng.standard_normal((4, 64))
    out = phyfft.aligned_empty((4, 64))
    before = sys.getrefcount(out)
    plan.execute(out=out)
    assert sys.getrefcount(out) == before
    np.testing.assert_allclose(out, np.fft.fft(plan.input), atol=1e-12)


def test_recycled_arrays_of_several_shapes_come_back_round_after_round():
    """A caller that asks for a few arrays per round (signals, spectra, tables) and drops them
    gets the same memory every round; a free array nobody asks for is released after
    :data:`~phyloc.phy.fft.RECYCLE_KEEP_CALLS` calls."""
    phyfft.release_recycled()
    small = (8, phyfft.RECYCLE_MIN_BYTES // (8 * 16))
    large = (8, 2 * small[1])
    rounds = []
    for _ in range(3):
        a, b, c = (phyfft.recycled_empty(s) for s in (small, small, large))
        rounds.append({x.ctypes.data for x in (a, b, c)})
        del a, b, c
    assert len(rounds[0]) == 3 and rounds[1] == rounds[0] and rounds[2] == rounds[0]
    # calls that do not take the large one, which stays free
    held = [phyfft.recycled_empty(small) for _ in range(phyfft.RECYCLE_KEEP_CALLS)]
    assert any(r[1].shape == large for r in phyfft._recycled)
    held.append(phyfft.recycled_empty(small))
    assert not any(r[1].shape == large for r in phyfft._recycled)
    del held
    phyfft.release_recycled()


def test_recycling_more_arrays_than_it_tracks():
    """Past :data:`~phyloc.phy.fft.RECYCLE_MAX_ARRAYS` the longest idle free arrays make room,
    held ones are never handed out again, and every array is writable on its own."""
    phyfft.release_recycled()
    shapes = [(8, phyfft.RECYCLE_MIN_BYTES // (8 * 16) + k) for k in range(12)]
    held = [phyfft.recycled_empty(s) for s in shapes[:6]]
    for s in shapes:  # dropped at once
        phyfft.recycled_empty(s)
    held += [phyfft.recycled_empty(s) for s in shapes[6:]]
    assert len(phyfft._recycled) <= phyfft.RECYCLE_MAX_ARRAYS
    for i, a in enumerate(held):
        a[...] = i
    assert all(np.all(a == i) for i, a in enumerate(held))
    del held
    phyfft.release_recycled()
