"""The memory cgroup of ``phyloc bench memory_large`` really confines the command it runs: a
process placed in it that touches more memory than the limit is killed, one below it is not.
Skipped where no cgroup can be made (not Linux, not root, no memory controller)."""

import subprocess
import sys

import pytest

from benchmarks.bench_memory_large import memory_cgroup

TOUCH = "b = bytearray({n}); b[::4096] = b'\\x01' * len(b[::4096]); print('done')"


def _run_in(cgroup, n_bytes):
    def enter():
        (cgroup / "cgroup.procs").write_text("0")  # "0": the writing process itself

    return subprocess.run(
        [sys.executable, "-c", TOUCH.format(n=n_bytes)],
        preexec_fn=enter,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_a_process_over_the_limit_is_killed_and_one_under_it_is_not():
    limit = 300_000_000
    with memory_cgroup(limit) as cgroup:
        if cgroup is None:
            pytest.skip("no memory cgroup can be made here (needs Linux, root and a controller)")
        under = _run_in(cgroup, 100_000_000)
        over = _run_in(cgroup, 900_000_000)
    assert under.returncode == 0 and under.stdout.strip() == "done", under.stderr
    assert over.returncode != 0 and "done" not in over.stdout
    assert not cgroup.exists()  # removed after use
