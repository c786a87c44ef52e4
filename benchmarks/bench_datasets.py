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
``generate_speedup_2w_over_1w``  ``2w / 1w``: what 2 workers gain over one process that already
                                 uses every core in its parallel kernels
``write_mb_per_s``               bytes of shard files written / time spent writing them (HDF5
                                 writes, close, fsync; summed over the shards of the 1-worker
                                 run), in 10⁶ B/s

Every run starts after ``os.sync()`` and its files are deleted when it ends, so that no run pays
for the write-back of an earlier one; the best of several runs is reported.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
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
REALIZATIONS_QUICK = 24


def _recipe(realizations: int) -> str:
    return RECIPE.format(realizations=realizations)


def _run(recipe: str, folder: Path, tag: str, **kw) -> dict:
    """Generate into ``folder/<tag>.h5``, then delete the files. Every run starts from the same
    I/O state: the dirty pages of earlier runs are flushed first (``os.sync``), and no earlier
    output piles up. Without that the runs measured last (the 2-worker ones) paid for the
    write-back of the gigabyte written before them (four runs in a row on 2 workers: 8246,
    8031, 7669, 7192 links/s)."""
    import shutil

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


def report(quick: bool = False) -> dict[str, float]:
    """Generation throughput with 1 and 2 workers and the write bandwidth (see module doc)."""
    from dask.distributed import Client

    n = REALIZATIONS_QUICK if quick else REALIZATIONS
    repeat = 1 if quick else 2
    recipe = _recipe(n)
    old = os.environ.get("PHYLOC_NO_PROGRESS")
    os.environ["PHYLOC_NO_PROGRESS"] = "1"
    try:
        with tempfile.TemporaryDirectory(prefix="phyloc-bench-datasets-") as tmp:
            folder = Path(tmp)
            _run(_recipe(1), folder, "warm1")  # JIT caches, scenario files, FFT plans
            one = [_run(recipe, folder, f"w1_{i}") for i in range(repeat)]
            import numba

            from phyloc.phy import fft

            before = (numba.get_num_threads(), fft.threads())
            limit_threads(1)
            try:
                one_t = [_run(recipe, folder, f"w1t_{i}") for i in range(repeat)]
            finally:
                numba.set_num_threads(before[0])
                fft.set_backend(fft.backend(), threads=before[1])
            with contextlib.ExitStack() as stack:
                cluster = stack.enter_context(local_cluster(2))
                stack.enter_context(Client(cluster))
                addr = cluster.scheduler_address
                _run(
                    _recipe(2).replace("shard_size = 4", "shard_size = 1"),
                    folder,
                    "warm2",
                    scheduler=addr,
                )  # both workers import phyloc and load the kernels
                two = [_run(recipe, folder, f"w2_{i}", scheduler=addr) for i in range(repeat)]
    finally:
        if old is None:
            os.environ.pop("PHYLOC_NO_PROGRESS", None)
        else:
            os.environ["PHYLOC_NO_PROGRESS"] = old
    rate1 = max(s["links_per_s"] for s in one)
    rate1t = max(s["links_per_s"] for s in one_t)
    rate2 = max(s["links_per_s"] for s in two)
    write = max(s["write_mb_per_s"] for s in one)
    return {
        "generate_links_per_s_1w": rate1,
        "generate_links_per_s_1w_1t": rate1t,
        "generate_links_per_s_2w": rate2,
        "generate_scaling_efficiency": rate2 / (2.0 * rate1t),
        "generate_speedup_2w_over_1w": rate2 / rate1,
        "write_mb_per_s": write,
    }


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
    return (
        f"{table}\n"
        f"scaling efficiency 2w/(2*1w_1t): {fig['generate_scaling_efficiency']:.2f}; "
        f"speedup of 2 workers over one process on every core: "
        f"{fig['generate_speedup_2w_over_1w']:.2f}\n"
        f"shard write bandwidth: {fig['write_mb_per_s']:.1f} MB/s"
    )
