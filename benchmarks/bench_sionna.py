"""phyloc's link synthesis beside Sionna's, in one process, on the same workload.

Sionna (NVIDIA's link-level library; optional: ``pip install "phyloc[sionna]"``) builds the
OFDM channel of a channel impulse response with ``cir_to_ofdm_channel`` (``h(f) = Σ_m a_m
e^{−j2πfτ_m}``), multiplies the pilots and adds noise with ``AWGN``. phyloc's
:func:`~phyloc.phy.synthesis.synthesize` does the same in one kernel. Work unit: one link of
the DiPNet system (N = 2569 subcarriers) with 24 paths; batches of 1024 links; one thread for
both (``torch.set_num_threads(1)``, Numba and FFTs limited to one thread). Figures:

``sionna.synthesis_links_per_s``           phyloc synthesis incl. pilots and AWGN (links/s)
``sionna.sionna_c64_links_per_s``          Sionna ``cir_to_ofdm_channel`` + pilots + ``AWGN``,
                                           complex64 (its default precision)
``sionna.sionna_c128_links_per_s``         the same in complex128 (phyloc's precision)
``sionna.speedup_c64`` / ``speedup_c128``  phyloc over Sionna (the ratio of the issue table)
``sionna.speedup_c64_no_noise``            the same without noise on either side
``sionna.one_link_phyloc_s``               steady-state median latency of one link (batch 1, default
                                           threads): synthesis + correlation table
``sionna.one_link_sionna_s``               the same for Sionna's synthesis of one link (timed in
                                           blocks alternating with phyloc's)
``sionna.one_link_ratio``                  Sionna's latency over phyloc's
``sionna.one_link_validation_s``           median latency of the pilot checks a one-link call
                                           makes (:func:`~phyloc.phy.waveform.check_symbols`,
                                           once in the synthesis and once in the table)
``sionna.one_link_validation_share``       that over ``one_link_phyloc_s`` (goal <= 0.1)
``sionna.max_rel_diff``                    max |R_phyloc − S·h_sionna| / max |R| of the
                                           noise-free complex128 signals (the two compute the
                                           same thing)

Without Sionna only the one-link latency of phyloc and its validation share are measured, and
the table says how to install Sionna.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import check_symbols

try:
    from phyloc.benchmarks._timing import best_seconds
    from phyloc.benchmarks.bench_phy import N_PATHS, make_batch  # the links of bench phy
except ImportError:  # run from the source tree
    from benchmarks._timing import best_seconds
    from benchmarks.bench_phy import N_PATHS, make_batch

N_LINKS = 1024
INSTALL = (
    'Sionna is not installed: pip install "phyloc[sionna]" (Sionna 2.2 with the CPU build of '
    "PyTorch 2.13) to compare"
)


def available() -> bool:
    """Whether ``sionna.phy`` imports."""
    try:
        import sionna.phy  # noqa: F401
    except ImportError:
        return False
    return True


class SionnaLinks:
    """Sionna's synthesis of the same links: CIR tensors in Sionna's layout, the subcarrier
    frequencies, the pilots, and ``AWGN``."""

    def __init__(self, system, S, paths, precision="single"):
        import torch
        from sionna.phy.channel import AWGN, subcarrier_frequencies

        self.torch = torch
        cdt = torch.complex64 if precision == "single" else torch.complex128
        rdt = torch.float32 if precision == "single" else torch.float64
        B, P = paths.n_links, paths.offsets[1] - paths.offsets[0]
        a = torch.as_tensor(paths.gains.reshape(B, P), dtype=cdt)
        self.a = a.reshape(B, 1, 1, 1, 1, P, 1)
        self.tau = torch.as_tensor(paths.delays.reshape(B, P), dtype=rdt).reshape(B, 1, 1, P)
        self.freq = subcarrier_frequencies(
            system.n_subcarriers, system.subcarrier_spacing_hz, precision=precision
        )
        self.x = torch.as_tensor(S[0], dtype=cdt)
        self.awgn = AWGN(precision=precision)
        self.no = torch.tensor(system.noise_power_w, dtype=rdt)

    def channel(self):
        """``h [B, N]`` of ``cir_to_ofdm_channel``."""
        from sionna.phy.channel import cir_to_ofdm_channel

        h = cir_to_ofdm_channel(self.freq, self.a, self.tau, normalize=False)
        return h.reshape(h.shape[0], -1)

    def received(self, noise=True):
        """Pilots through the channel, plus AWGN: ``[B, N]``."""
        y = self.channel() * self.x
        return self.awgn(y, self.no) if noise else y


def _median_latencies(fns: dict, n=30, block=25, settle=5) -> dict:
    """Steady-state median latency of one call of each function: ``n`` timed calls each, made
    in alternating blocks of ``settle`` untimed and ``block`` timed calls. Both medians see the
    same drift of the machine's speed, and each function is timed with its own data back in
    the caches (timed right after the other library's call, phyloc's one link took 303
    instead of 226 µs)."""
    times = {name: [] for name in fns}
    for _ in range(max(1, -(-n // block))):
        for name, fn in fns.items():
            for _ in range(settle):
                fn()
            for _ in range(block):
                t0 = time.perf_counter()
                fn()
                times[name].append(time.perf_counter() - t0)
    return {name: statistics.median(t) for name, t in times.items()}


def _one_link(quick: bool, sionna: bool) -> dict[str, float]:
    """The one-link figures: phyloc's synthesis + table, its pilot checks and (``sionna``)
    Sionna's synthesis, timed in alternating blocks at the default thread counts."""
    sys1, S1, p1, rng1 = make_batch(1, seed=3)

    def ours_one():
        correlation_tables(synthesize(p1, S1, sys1, rng1), S1, sys1, beta=8.0)

    def checks():  # what ours_one spends validating its pilots
        check_symbols(S1, sys1)
        check_symbols(S1, sys1)

    fns = {"phyloc": ours_one, "checks": checks}
    n = 20 if quick else 100
    if not sionna:
        med = _median_latencies(fns, n)
    else:
        import torch

        one = SionnaLinks(sys1, S1, p1, precision="single")
        with torch.no_grad():  # in turn, so that the medians see the same load
            med = _median_latencies({"sionna": one.received, **fns}, n)
    fig = {
        "sionna.one_link_phyloc_s": med["phyloc"],
        "sionna.one_link_validation_s": med["checks"],
        "sionna.one_link_validation_share": med["checks"] / med["phyloc"],
    }
    if sionna:
        fig["sionna.one_link_sionna_s"] = med["sionna"]
        fig["sionna.one_link_ratio"] = med["sionna"] / med["phyloc"]
    return fig


def report(quick: bool = False) -> dict[str, float]:
    """Measure every figure of the module docstring (without Sionna only phyloc's one-link
    latency and its validation share)."""
    if not available():
        return _one_link(quick, sionna=False)
    import numba
    import torch

    from phyloc.parallel import limit_threads
    from phyloc.phy import fft as phyfft

    repeat = 2 if quick else 5
    threads = (torch.get_num_threads(), numba.get_num_threads(), phyfft.threads())
    system, S, paths, rng = make_batch(256 if quick else N_LINKS)
    fig: dict[str, float] = {"sionna.n_links": paths.n_links, "sionna.n_paths": N_PATHS}
    # correctness first: noise-free signals in complex128
    ref = SionnaLinks(system, S, paths, precision="double")
    ours = synthesize(paths, S, system, None)
    theirs = ref.received(noise=False).numpy()
    fig["sionna.max_rel_diff"] = float(np.abs(ours - theirs).max() / np.abs(ours).max())
    try:
        torch.set_num_threads(1)
        limit_threads(1)
        n = paths.n_links
        t_ours = best_seconds(lambda: synthesize(paths, S, system, rng), repeat=repeat)
        t_ours_nn = best_seconds(lambda: synthesize(paths, S, system, None), repeat=repeat)
        fig["sionna.synthesis_links_per_s"] = n / t_ours
        for precision, tag in (("single", "c64"), ("double", "c128")):
            sl = ref if precision == "double" else SionnaLinks(system, S, paths, precision)
            with torch.no_grad():
                t = best_seconds(sl.received, repeat=repeat)
                fig[f"sionna.sionna_{tag}_links_per_s"] = n / t
                fig[f"sionna.speedup_{tag}"] = t / t_ours
                if tag == "c64":
                    t_nn = best_seconds(lambda sl=sl: sl.received(noise=False), repeat=repeat)
                    fig["sionna.speedup_c64_no_noise"] = t_nn / t_ours_nn
    finally:
        torch.set_num_threads(threads[0])
        limit_threads(max(threads[1], threads[2]))
    # one link at a time, default threads: phyloc's synthesis + table vs Sionna's synthesis
    fig.update(_one_link(quick, sionna=True))
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`'s figures."""
    from phyloc.reporting import format_table

    checks = (
        f"pilot checks {fig['sionna.one_link_validation_s'] * 1e6:.1f} us = "
        f"{100 * fig['sionna.one_link_validation_share']:.1f} % of it"
    )
    if "sionna.synthesis_links_per_s" not in fig:
        return (
            f"{INSTALL}\none link at a time (default threads): phyloc synthesis + table "
            f"{fig['sionna.one_link_phyloc_s'] * 1e6:.0f} us, {checks}"
        )
    ours = fig["sionna.synthesis_links_per_s"]
    rows = [
        ("phyloc synthesize (pilots + AWGN)", ours, 1e6 / ours, "reference"),
        (
            "Sionna cir_to_ofdm_channel + pilots + AWGN, complex64",
            fig["sionna.sionna_c64_links_per_s"],
            1e6 / fig["sionna.sionna_c64_links_per_s"],
            f"phyloc {fig['sionna.speedup_c64']:.1f}x faster "
            f"({fig['sionna.speedup_c64_no_noise']:.1f}x without noise)",
        ),
        (
            "the same, complex128",
            fig["sionna.sionna_c128_links_per_s"],
            1e6 / fig["sionna.sionna_c128_links_per_s"],
            f"phyloc {fig['sionna.speedup_c128']:.1f}x faster",
        ),
    ]
    head = (
        f"N = 2569 subcarriers, {int(fig['sionna.n_paths'])} paths/link, batches of "
        f"{int(fig['sionna.n_links'])} links, 1 thread each; noise-free signals agree to "
        f"{fig['sionna.max_rel_diff']:.1e} (relative)"
    )
    t1 = format_table(rows, ["work", "links/s", "us/link", "ratio"])
    lat = (
        f"one link at a time (default threads): phyloc synthesis + table "
        f"{fig['sionna.one_link_phyloc_s'] * 1e6:.0f} us ({checks}), Sionna synthesis alone "
        f"{fig['sionna.one_link_sionna_s'] * 1e6:.0f} us: "
        f"{fig['sionna.one_link_ratio']:.1f}x"
    )
    return f"{head}\n{t1}\n{lat}"
