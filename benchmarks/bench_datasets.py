"""Dataset-generation benchmarks: received waveforms (links) generated and stored per second.

Work unit: one *link* — one directed link of one snapshot: its channel draw (WINNER II C2),
its received OFDM symbol at the DiPNet system (N = 2569 subcarriers), the time-domain
conversion to complex64 samples, and its share of the shard file (samples, pilots, channel
truth, SHA-256 checksums, fsync, atomic rename) and of the master file. The recipe is the
quickstart network: 12 anchor-free agents, fully meshed (132 links per realization), one
snapshot; 96 realizations (12 672 links) in shards of 4 (``quick``: 24). Figures (names are
the interface):

``generate_links_per_s_1w``      links/s of :func:`phyloc.datasets.generate` in this process
                                 (``workers=1``; its Numba kernels and FFTs may use every core)
``generate_links_per_s_2w``      links/s on a 2-worker Dask ``LocalCluster`` (one process and
                                 one thread per worker, :func:`phyloc.parallel.local_cluster`),
                                 already started and warmed up: the cluster start (a few
                                 seconds) is not counted
``generate_links_per_s_1w_1t``   links/s in this process with Numba and FFTs kept to one
                                 thread: one worker as each of the 2 Dask workers runs it
``generate_scaling_efficiency``  ``2w / (2 · 1w_1t)``: like against like (one thread per
                                 worker); 1.0 would be perfect scaling over workers
``generate_cpu_wait_share_1w_1t`` / ``_2w``  share of the time that the working threads (the
                                 in-process run's main thread, each Dask worker's task thread)
                                 waited for a CPU held by another thread, in the runs reported
                                 (Linux schedstat; absent elsewhere). 0 on an idle machine; above
                                 a few percent other work took the CPUs, and the efficiency
                                 compares loads as much as code (the summary says so)
``generate_speedup_2w_over_1w``  ``2w / 1w``: what 2 workers gain over one process that already
                                 uses every core in its parallel kernels
``write_mb_per_s``               bytes of shard files written / time spent writing them (HDF5
                                 writes, close, fsync; summed over the shards of the 1-worker
                                 run), in 10⁶ B/s

The three set-ups run in turn, round after round, and each figure is the best of its rounds:
on a machine shared with other work (2 cores), a 2-worker run needs both cores while a
one-thread run needs one, so runs made minutes apart compared different loads (the same command
gave 0.96–1.02 on an idle machine and 0.76 next to another job). Every worker, and this process
at one thread and at every core, runs a small generation before the timed runs (kernels
compiled or loaded from the cache, one-thread variants included; channel files read). Every run
starts after ``os.sync()`` and its files are deleted when it ends, so that no run pays for the
write-back of an earlier one.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import threading
from pathlib import Path

from phyloc.parallel import limit_threads, local_cluster

RECIPE = """
kind = "dataset"
name = "bench_datasets"
seed = 1

[system]
n_subcarriers = 2569
subcarrier_spacing_hz = 14.65e3

[network]
n_agents = 12
region_m = [100.0, 100.0]

[channel]
scenario = "winner2_c2"

[dataset]
realizations = {realizations}
shard_size = 4
"""
REALIZATIONS = 96
#: Above these shares of the working threads' time spent waiting for a CPU, the summary says
#: that other work held the CPUs. On an idle 2-core machine (load 0.6-1.1, 2026-11-27, three
#: runs) the 1-thread run waited 0 % and the 2-worker run 9-10 %: the parent process (the Dask
#: scheduler and client, the shard bookkeeping) shares the two cores with the two workers.
#: Under other jobs (load 10-16) the working threads waited 40-79 %.
BUSY_WAIT_SHARE = {"1w_1t": 0.05, "2w": 0.20}
REALIZATIONS_QUICK = 24


def _recipe(realizations: int) -> str:
    return RECIPE.format(realizations=realizations)


def _run(recipe: str, folder: Path, tag: str, **kw) -> dict:
    """Generate into ``folder/<tag>.h5``, then delete the files. Every run starts from the same
    I/O state: the dirty pages of earlier runs are flushed first (``os.sync``), and no earlier
    output piles up. Without that the runs measured last (the 2-worker ones) paid for the
    write-back of the gigabyte written before them (four runs in a row on 2 workers: 8246,
    8031, 7669, 7192 links/s)."""
    from phyloc.datasets import generate

    if hasattr(os, "sync"):
        os.sync()
    out = folder / f"{tag}.h5"
    try:
        return generate(recipe, out, progress=False, **kw)
    finally:
        out.unlink(missing_ok=True)
        shutil.rmtree(folder / f"{tag}.h5.shards", ignore_errors=True)


class Generate:
    """asv: generate 24 realizations (3168 links) in this process."""

    def setup(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.n = 0
        _run(_recipe(1), Path(self.tmp.name), "warm")

    def teardown(self):
        self.tmp.cleanup()

    def time_generate_1w(self):
        self.n += 1
        _run(_recipe(REALIZATIONS_QUICK), Path(self.tmp.name), f"run{self.n}")


def _thread_clock() -> dict:
    """``{thread id: (seconds on a CPU, seconds waiting for one)}`` of this process's threads
    (``/proc/self/task/*/schedstat``; empty where Linux does not provide it)."""
    clock = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return clock
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/schedstat") as fh:
                run_ns, wait_ns = fh.read().split()[:2]
        except (OSError, ValueError):
            continue
        clock[int(tid)] = (int(run_ns) / 1e9, int(wait_ns) / 1e9)
    return clock


def _worker_wait(before: dict, after: dict) -> float | None:
    """Seconds the working thread (the one that ran most between the two clocks) waited for a
    CPU; None without schedstat."""
    if not after:
        return None
    zero = (0.0, 0.0)
    delta = [
        (r - before.get(t, zero)[0], w - before.get(t, zero)[1]) for t, (r, w) in after.items()
    ]
    return max(delta)[1]


def _warm_workers(client, folder: Path) -> None:
    """A one-realization generation on every worker, one at a time, at the thread count of the
    timed runs (one): kernels compiled or loaded, channel files read."""
    from phyloc.datasets import generate

    for i, addr in enumerate(client.scheduler_info()["workers"]):
        client.run(limit_threads, 1, workers=[addr])
        out = folder / f"warm-w{i}.h5"
        client.run(generate, _recipe(1), str(out), progress=False, workers=[addr])
        out.unlink(missing_ok=True)
        shutil.rmtree(folder / f"warm-w{i}.h5.shards", ignore_errors=True)


def report(quick: bool = False) -> dict[str, float]:
    """Generation throughput with 1 and 2 workers and the write bandwidth (see module doc)."""
    import numba
    from dask.distributed import Client

    from phyloc.phy import fft

    n = REALIZATIONS_QUICK if quick else REALIZATIONS
    repeat = 2 if quick else 3
    recipe = _recipe(n)
    old = os.environ.get("PHYLOC_NO_PROGRESS")
    os.environ["PHYLOC_NO_PROGRESS"] = "1"
    every = (numba.get_num_threads(), fft.threads())
    main = threading.get_native_id()
    runs: dict[str, list] = {"1w": [], "1w_1t": [], "2w": []}
    try:
        with tempfile.TemporaryDirectory(prefix="phyloc-bench-datasets-") as tmp:
            folder = Path(tmp)
            with contextlib.ExitStack() as stack:
                cluster = stack.enter_context(local_cluster(2))
                client = stack.enter_context(Client(cluster))
                addr = cluster.scheduler_address
                _run(_recipe(1), folder, "warm1")  # every core: the parallel kernels
                limit_threads(1)
                _run(_recipe(1), folder, "warm1t")  # one thread: the serial variants
                limit_threads(every[0])
                fft.set_backend(fft.backend(), threads=every[1])
                _warm_workers(client, folder)
                for i in range(repeat):  # the three set-ups in turn: the same load for each
                    runs["1w"].append((_run(recipe, folder, f"w1_{i}"), None))
                    limit_threads(1)
                    try:
                        c0 = _thread_clock()
                        s1 = _run(recipe, folder, f"w1t_{i}")
                        c1 = _thread_clock()
                    finally:
                        limit_threads(every[0])
                        fft.set_backend(fft.backend(), threads=every[1])
                    wait = None
                    if main in c0 and main in c1:
                        wait = [c1[main][1] - c0[main][1]]
                    runs["1w_1t"].append((s1, wait))
                    c0 = client.run(_thread_clock)
                    s2 = _run(recipe, folder, f"w2_{i}", scheduler=addr)
                    c1 = client.run(_thread_clock)
                    waits = [_worker_wait(c0.get(w, {}), c1[w]) for w in c1]
                    runs["2w"].append((s2, None if None in waits else waits))
    finally:
        if old is None:
            os.environ.pop("PHYLOC_NO_PROGRESS", None)
        else:
            os.environ["PHYLOC_NO_PROGRESS"] = old
    rate = {k: max(s["links_per_s"] for s, _ in v) for k, v in runs.items()}
    fig = {
        "generate_links_per_s_1w": rate["1w"],
        "generate_links_per_s_1w_1t": rate["1w_1t"],
        "generate_links_per_s_2w": rate["2w"],
        "generate_scaling_efficiency": rate["2w"] / (2.0 * rate["1w_1t"]),
        "generate_speedup_2w_over_1w": rate["2w"] / rate["1w"],
        "write_mb_per_s": max(s["write_mb_per_s"] for s, _ in runs["1w"]),
    }
    for k in ("1w_1t", "2w"):  # the load the reported (best) run of each set-up ran under
        s, w = max(runs[k], key=lambda r: r[0]["links_per_s"])
        if w is not None:
            fig[f"generate_cpu_wait_share_{k}"] = sum(w) / (len(w) * s["seconds"])
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`: links/s and µs per link for 1 and 2 workers, the
    scaling efficiency and the write bandwidth."""
    from phyloc.reporting import format_table

    r1, r2 = fig["generate_links_per_s_1w"], fig["generate_links_per_s_2w"]
    r1t = fig["generate_links_per_s_1w_1t"]
    rows = [
        ("generate, 1 worker (in-process, every core)", r1, 1e6 / r1),
        ("generate, 1 worker, 1 thread", r1t, 1e6 / r1t),
        ("generate, 2 Dask workers, 1 thread each", r2, 1e6 / r2),
    ]
    table = format_table(rows, ["run", "links/s", "us/link"])
    eff = f"scaling efficiency 2w/(2*1w_1t): {fig['generate_scaling_efficiency']:.2f}"
    waits = [fig.get(f"generate_cpu_wait_share_{k}") for k in ("1w_1t", "2w")]
    if None not in waits:
        eff += (
            f" (the working threads waited for a CPU {100 * waits[0]:.0f} % of the 1-thread "
            f"run and {100 * waits[1]:.0f} % of the 2-worker run"
        )
        busy = waits[0] > BUSY_WAIT_SHARE["1w_1t"] or waits[1] > BUSY_WAIT_SHARE["2w"]
        eff += "; other work held the CPUs: the figure is uncertain)" if busy else ")"
    return (
        f"{table}\n{eff}\n"
        f"speedup of 2 workers over one process on every core: "
        f"{fig['generate_speedup_2w_over_1w']:.2f}\n"
        f"shard write bandwidth: {fig['write_mb_per_s']:.1f} MB/s"
    )
