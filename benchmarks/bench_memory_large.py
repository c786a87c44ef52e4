"""Memory benchmark beyond the memory: ``phyloc evaluate`` of a dataset several times larger
than the memory the command may use, against one a tenth of its size.

Work unit: one ``evaluate`` run end to end as a subprocess (in-process, no workers), on a
dataset of 12 anchor-free agents in WINNER II C2, fully meshed (132 links per realization),
32 769 subcarriers (about 36 MB of waveforms per realization), shards of one realization,
localized with ``corr`` (200 particles, 3 iterations: the localization is cheap, the data is
not). The large dataset has 220 realizations (about 8 GB on disk), the small one 22 (``quick``:
60 and 6). Where the machine allows it (Linux, root, a cgroup memory controller), both runs are
confined to a memory cgroup of :data:`LIMIT_GB` (page cache included), so the large dataset is
about four times what the command may hold; elsewhere they run without a limit and the
figures say so (``memory_limit_gb`` is NaN).

Figures (names are the interface):

``evaluate_large.dataset_gb_small``, ``..._large``   the datasets' size on disk [10⁹ B]
``evaluate_large.memory_limit_gb``      the cgroup's limit [10⁹ B] (NaN: none could be set)
``evaluate_large.peak_rss_mb_small``    peak summed RSS of the command's process tree [10⁶ B]
``evaluate_large.peak_rss_mb_large``    the same on the large dataset
``evaluate_large.rss_ratio``            ``peak_rss_mb_large / peak_rss_mb_small`` (flat: 1.0)
``evaluate_large.cgroup_peak_gb_large`` the cgroup's peak usage on the large dataset, page cache
                                        included [10⁹ B] (NaN without a cgroup)
``evaluate_large.wall_s_small``, ``..._large``       wall time of the runs [s]
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
from pathlib import Path

from .bench_memory import RECIPE as BASE_RECIPE
from .bench_memory import peak_tree_rss

#: :data:`bench_memory.RECIPE` with more agents, subcarriers and a cheaper localization: the
#: data is large, the work per realization small.
RECIPE = (
    BASE_RECIPE.replace('name = "bench_memory"', 'name = "bench_memory_large"')
    .replace(
        "n_subcarriers = 2569\nsubcarrier_spacing_hz = 14.65e3",
        "n_subcarriers = 32769\nsubcarrier_spacing_hz = 30.0e3",
    )
    .replace("n_agents = 8", "n_agents = 12")
    .replace('methods = ["dipnet", "corr"]', 'methods = ["corr"]')
    .replace("n_particles = 500\nn_iterations = 8", "n_particles = 200\nn_iterations = 3")
)
#: The memory cgroup's limit [10⁹ B].
LIMIT_GB = 2.0
CGROUP_V1 = Path("/sys/fs/cgroup/memory")
CGROUP_V2 = Path("/sys/fs/cgroup")


@contextlib.contextmanager
def memory_cgroup(limit_bytes: int):
    """A fresh memory cgroup limited to ``limit_bytes`` (v1 or v2): yields its folder, or
    None where none can be made (not Linux, not root, no memory controller); removed after."""
    name = f"phyloc-bench-{os.getpid()}"
    if (CGROUP_V1 / "memory.limit_in_bytes").exists():
        folder, limit_file = CGROUP_V1 / name, "memory.limit_in_bytes"
    elif "memory" in _read(CGROUP_V2 / "cgroup.controllers").split():
        folder, limit_file = CGROUP_V2 / name, "memory.max"
    else:
        yield None
        return
    try:
        folder.mkdir()
        (folder / limit_file).write_text(str(int(limit_bytes)))
    except OSError:
        yield None
        return
    try:
        yield folder
    finally:
        with contextlib.suppress(OSError):
            folder.rmdir()


def _read(path: Path) -> str:
    try:
        return path.read_text()
    except OSError:
        return ""


def _cgroup_peak(folder: Path | None) -> float:
    """The cgroup's peak memory usage [B] (v1 ``max_usage_in_bytes``, v2 ``memory.peak``)."""
    if folder is None:
        return math.nan
    for name in ("memory.max_usage_in_bytes", "memory.peak"):
        text = _read(folder / name).strip()
        if text:
            return float(text)
    return math.nan


def _reset_peak(folder: Path | None) -> None:
    if folder is not None:
        with contextlib.suppress(OSError):
            (folder / "memory.max_usage_in_bytes").write_text("0")


def _size(path: Path) -> float:
    return float(sum(f.stat().st_size for f in path.rglob("*") if f.is_file()))


def _phyloc(*args: str) -> list[str]:
    return [sys.executable, "-m", "phyloc.cli", *args, "--no-progress"]


def report(quick: bool = False) -> dict[str, float]:
    """Peak RSS of ``evaluate`` on a small and a large dataset (see the module)."""
    sizes = {"small": 6, "large": 60} if quick else {"small": 22, "large": 220}
    fig: dict[str, float] = {}
    with (
        tempfile.TemporaryDirectory(prefix="phyloc-bench-memory-large-") as tmp,
        memory_cgroup(int(LIMIT_GB * 1e9)) as cgroup,
    ):
        folder = Path(tmp)
        fig["evaluate_large.memory_limit_gb"] = LIMIT_GB if cgroup is not None else math.nan

        def enter_cgroup():
            if cgroup is not None:
                (cgroup / "cgroup.procs").write_text(str(os.getpid()))

        for tag, n in sizes.items():
            recipe = folder / f"{tag}.toml"
            recipe.write_text(RECIPE.format(realizations=n))
            h5 = folder / f"{tag}.h5"
            peak_tree_rss(_phyloc("generate", str(recipe), "-o", str(h5), "--workers", "2"))
            fig[f"evaluate_large.dataset_gb_{tag}"] = (
                _size(h5.parent / (h5.name + ".shards")) + h5.stat().st_size
            ) / 1e9
            _reset_peak(cgroup)
            rss, wall = peak_tree_rss(
                _phyloc("evaluate", str(h5), "--out", str(folder / tag)), preexec_fn=enter_cgroup
            )
            fig[f"evaluate_large.peak_rss_mb_{tag}"] = rss / 1e6
            fig[f"evaluate_large.wall_s_{tag}"] = wall
            if tag == "large":
                fig["evaluate_large.cgroup_peak_gb_large"] = _cgroup_peak(cgroup) / 1e9
            for f in (h5.parent / (h5.name + ".shards")).glob("*"):
                f.unlink()  # the disk back before the next dataset
    fig["evaluate_large.rss_ratio"] = (
        fig["evaluate_large.peak_rss_mb_large"] / fig["evaluate_large.peak_rss_mb_small"]
    )
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`'s figures."""
    from phyloc.reporting import format_table

    limit = fig["evaluate_large.memory_limit_gb"]
    rows = [
        (
            tag,
            f"{fig[f'evaluate_large.dataset_gb_{tag}']:.2f} GB",
            f"{fig[f'evaluate_large.peak_rss_mb_{tag}']:.0f} MB",
            f"{fig[f'evaluate_large.wall_s_{tag}']:.0f} s",
        )
        for tag in ("small", "large")
    ]
    table = format_table(rows, ("dataset", "on disk", "evaluate peak RSS", "wall"))
    where = (
        f"in a memory cgroup of {limit:.1f} GB (peak use with page cache "
        f"{fig['evaluate_large.cgroup_peak_gb_large']:.2f} GB)"
        if math.isfinite(limit)
        else "without a memory limit (no cgroup could be made: not root, or not Linux)"
    )
    return (
        f"{table}\nlarge / small peak RSS: {fig['evaluate_large.rss_ratio']:.2f}x "
        f"(flat: 1.0), {where}"
    )
