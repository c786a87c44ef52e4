"""Memory benchmark: peak RSS of ``phyloc generate`` and ``phyloc evaluate`` at 1× and 10×
the realizations (generation and evaluation stream shard by shard, so memory stays flat).

Work unit: one command run end to end as a subprocess (``--workers 2``: the parent and its
two Dask worker processes). The recipe is a small quickstart network: 8 anchor-free agents
in WINNER II C2, fully meshed (56 links per realization), one snapshot, shards of one
realization; ``evaluate`` localizes with ``dipnet`` and ``corr``. 1× is 4 realizations, 10×
is 40 (``quick``: 2 and 20). Figures (names are the interface):

``<command>.peak_rss_mb_1x``    peak over time of the summed resident set size of the command's
                                process tree (parent + workers) at 1× [10⁶ B]
``<command>.peak_rss_mb_10x``   the same at 10× the realizations
``<command>.rss_ratio_10x``     ``peak_rss_mb_10x / peak_rss_mb_1x``: 1.0 is perfectly flat
                                (the goal is ≤ 1.2)
``<command>.wall_s_1x``, ``<command>.wall_s_10x``  wall time of the runs [s]

``<command>`` is ``generate`` or ``evaluate``. RSS is sampled every 50 ms with psutil; a sum
over processes counts shared pages once per process, an upper bound on the memory used.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

RECIPE = """
kind = "dataset"
name = "bench_memory"
seed = 5

[system]
n_subcarriers = 2569
subcarrier_spacing_hz = 14.65e3

[network]
n_agents = 8
region_m = [100.0, 100.0]

[channel]
scenario = "winner2_c2"

[dataset]
realizations = {realizations}
shard_size = 1

[experiment]
methods = ["dipnet", "corr"]
inits = ["truth_free"]

[localization]
n_particles = 500
n_iterations = 8
"""
SAMPLE_S = 0.05


def peak_tree_rss(
    cmd: list[str], *, sample_s: float = SAMPLE_S, preexec_fn=None
) -> tuple[float, float]:
    """Run ``cmd`` (``preexec_fn`` as :class:`subprocess.Popen`'s); return (peak summed RSS of
    its process tree [B], wall time [s]).

    Raises ``RuntimeError`` with the command's stderr when it fails.
    """
    import psutil

    t0 = time.perf_counter()
    proc = subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, preexec_fn=preexec_fn
    )
    root = psutil.Process(proc.pid)
    peak = 0
    while proc.poll() is None:
        total = 0
        try:
            members = [root, *root.children(recursive=True)]
        except psutil.NoSuchProcess:
            break
        for p in members:
            try:
                total += p.memory_info().rss
            except psutil.NoSuchProcess:
                pass
        peak = max(peak, total)
        time.sleep(sample_s)
    err = proc.stderr.read()
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {err.strip()[-500:]}")
    return float(peak), wall


def _phyloc(*args: str) -> list[str]:
    return [sys.executable, "-m", "phyloc.cli", *args, "--workers", "2", "--no-progress"]


def report(quick: bool = False) -> dict[str, float]:
    """Peak RSS of generate and evaluate at 1× and 10× the realizations (see module doc)."""
    base = 2 if quick else 4
    fig: dict[str, float] = {"realizations_1x": base, "realizations_10x": 10 * base}
    with tempfile.TemporaryDirectory(prefix="phyloc-bench-memory-") as tmp:
        folder = Path(tmp)
        warm = folder / "warm.toml"  # JIT caches and scenario files, not measured
        warm.write_text(RECIPE.format(realizations=1))
        peak_tree_rss(_phyloc("generate", str(warm), "-o", str(folder / "warm.h5")))
        for tag, n in (("1x", base), ("10x", 10 * base)):
            recipe = folder / f"r{tag}.toml"
            recipe.write_text(RECIPE.format(realizations=n))
            h5 = folder / f"r{tag}.h5"
            rss, wall = peak_tree_rss(_phyloc("generate", str(recipe), "-o", str(h5)))
            fig[f"generate.peak_rss_mb_{tag}"] = rss / 1e6
            fig[f"generate.wall_s_{tag}"] = wall
            rss, wall = peak_tree_rss(_phyloc("evaluate", str(h5), "--out", str(folder / tag)))
            fig[f"evaluate.peak_rss_mb_{tag}"] = rss / 1e6
            fig[f"evaluate.wall_s_{tag}"] = wall
    for cmd in ("generate", "evaluate"):
        fig[f"{cmd}.rss_ratio_10x"] = fig[f"{cmd}.peak_rss_mb_10x"] / fig[f"{cmd}.peak_rss_mb_1x"]
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`'s figures."""
    from phyloc.reporting import format_table

    rows = []
    for cmd in ("generate", "evaluate"):
        rows.append(
            (
                cmd,
                f"{fig[f'{cmd}.peak_rss_mb_1x']:.0f} MB ({fig[f'{cmd}.wall_s_1x']:.0f} s)",
                f"{fig[f'{cmd}.peak_rss_mb_10x']:.0f} MB ({fig[f'{cmd}.wall_s_10x']:.0f} s)",
                f"{fig[f'{cmd}.rss_ratio_10x']:.2f}x (goal <= 1.2)",
            )
        )
    head = (
        "command",
        f"peak RSS, {int(fig['realizations_1x'])} realizations",
        f"{int(fig['realizations_10x'])} realizations",
        "ratio",
    )
    return format_table(rows, head)
