"""PHY-core benchmarks: synthesis, correlation tables, the FFT floor, table interpolation.

Work unit: one link of the DiPNet system (N = 2569 subcarriers) with 24 paths, in batches of
256 links, tables at β ≈ 8 (L = 20480). Figures (names are the interface, see README):

``synthesis_links_per_s``        Numba synthesis incl. AWGN (links/s)
``synthesis_numpy_links_per_s``  its plain-NumPy twin (``tests/naive_phy.py``), incl. AWGN
``pipeline_links_per_s``         synthesis + correlation table
``pipeline_numpy_links_per_s``   the same with the NumPy twin and ``numpy.fft``
``fft_floor_links_per_s``        one bare planned FFT of length L per link (the floor)
``pipeline_cost_over_floor``     (1/pipeline) / (1/floor): the pipeline's cost in FFT floors
``pipeline_streaming_links_per_s``  the pipeline writing each batch's tables into the same
                                 array (``correlation_tables(..., out=)``), as a caller that
                                 drops a batch's tables before the next does
``pipeline_streaming_cost_over_floor``  its cost in FFT floors (the floor's output buffer is
                                 reused too, so this compares like with like)
``pipeline_cpu_over_floor_1t``    the pipeline's cost in FFT floors with one Numba and one FFT
                                 thread, timed in CPU time of this thread: the work alone, which
                                 other processes on the machine do not change (the wall-clock
                                 ratios above count the waits of each parallel region for a
                                 CPU, and the pipeline has one more region than the floor)
``synthesis_speedup_vs_numpy``   synthesis / synthesis_numpy
``interp.<m>.points_per_s``      table evaluations per second (m = linear, cubic, quintic)
``interp.<m>.max_rel_error``     max |f̃ − f| / max|f| over random distances, β ≈ 8
``interp.<m>.peak_bias_m``       max distance error of the interpolated |f|² peak of a
                                 noise-free one-path link (what a particle filter would see)
``<nr>.pipeline_links_per_s``    the pipeline in a 3GPP NR numerology (``nr_30khz``: 3277 x
                                 30 kHz; ``nr_120khz``: 793 x 120 kHz; :data:`NUMEROLOGIES`)
``<nr>.pipeline_cost_over_floor`` its cost in FFT floors of its own padded length
``peak_rmse_over_sqrt_crb.<s>db`` RMSE of the refined correlation peak over √CRB (eq. (24)),
                                 AWGN, post-correlation SNR s = 20, 30, 40 dB, 1000 links each

The NumPy twin is test code, loaded from the source checkout by
:func:`benchmarks._reference.naive`; without one the three ``*numpy*`` figures are not measured
(the table says ``MISSING``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from phyloc.phy import C0, OFDMSystem, PathSet
from phyloc.phy import fft as phyfft
from phyloc.phy.bounds import crb_range
from phyloc.phy.correlation import correlation_tables, fft_length
from phyloc.phy.synthesis import complex_noise, synthesize
from phyloc.phy.waveform import qpsk_symbols

try:
    from phyloc.benchmarks._reference import MISSING, naive
    from phyloc.benchmarks._timing import best_seconds, best_seconds_interleaved
except ImportError:  # run from the source tree by asv
    from benchmarks._reference import MISSING, naive
    from benchmarks._timing import best_seconds, best_seconds_interleaved

N_LINKS = 256
N_PATHS = 24
BETA = 8.0


#: 3GPP NR numerologies at about 100 MHz (TS 38.211 subcarrier spacings; N odd, symmetric about
#: DC): the cost per link of the same pipeline beside the DiPNet system's.
NUMEROLOGIES = {
    "nr_30khz": dict(n_subcarriers=3277, subcarrier_spacing_hz=30e3, carrier_frequency_hz=3.5e9),
    "nr_120khz": dict(n_subcarriers=793, subcarrier_spacing_hz=120e3, carrier_frequency_hz=28e9),
}


def make_batch(n_links=N_LINKS, n_paths=N_PATHS, seed=0, system=None):
    """A seeded batch: the paper's system (or ``system``), one pilot row, ``n_paths`` paths per
    link."""
    system = OFDMSystem() if system is None else system
    rng = np.random.default_rng(seed)
    S = qpsk_symbols(system, 1, rng)
    total = n_links * n_paths
    d = np.repeat(rng.uniform(5.0, 140.0, n_links), n_paths) / C0
    delays = d + rng.exponential(50e-9, total)
    gains = 1e-6 * (rng.standard_normal(total) + 1j * rng.standard_normal(total))
    paths = PathSet(delays, gains, np.arange(0, total + 1, n_paths))
    return system, S, paths, rng


def numpy_synthesize(twin, paths, S, system, rng):
    """:func:`synthesize` (one pilot row, AWGN of ``system.noise_power_w``) by the NumPy twin
    ``twin.synthesize_numpy`` of the synthesis kernel (``twin`` = the ``naive_phy`` module)."""
    n_links, N = paths.n_links, system.n_subcarriers
    noise = complex_noise((n_links, N), system.noise_power_w, rng)
    tx = np.zeros(n_links, dtype=np.int64)
    n_first = -float((N - 1) // 2)
    return twin.synthesize_numpy(
        S, tx, paths.delays, paths.gains, paths.offsets, system.omega, n_first, noise
    )


def numpy_pipeline(twin, paths, S, system, rng, beta=BETA):
    """Plain-NumPy reference: NumPy-twin synthesis and ``numpy.fft`` of the padded spectrum."""
    R = numpy_synthesize(twin, paths, S, system, rng)
    L = fft_length(system, beta)
    h = (system.n_subcarriers - 1) // 2
    c = np.conj(R) * S[0]
    buf = np.zeros((R.shape[0], L), dtype=np.complex128)
    buf[:, : h + 1] = c[:, h:]
    buf[:, L - h :] = c[:, :h]
    return np.fft.fft(buf, axis=1)


class Synthesis:
    """asv: received signals of 256 links × 24 paths."""

    params = [["numba", "numpy"]]
    param_names = ["backend"]

    def setup(self, backend):
        self.system, self.S, self.paths, self.rng = make_batch()
        if backend == "numba":
            self.run = lambda: synthesize(self.paths, self.S, self.system, self.rng)
        else:
            twin = naive("naive_phy")
            if twin is None:
                raise NotImplementedError(MISSING)  # asv skips the parameter
            self.run = lambda: numpy_synthesize(twin, self.paths, self.S, self.system, self.rng)
        self.run()  # compile

    def time_synthesize(self, backend):
        self.run()


class Pipeline:
    """asv: synthesis + correlation tables, and the bare FFT floor of the same length."""

    def setup(self):
        self.system, self.S, self.paths, self.rng = make_batch()
        self.L = fft_length(self.system, BETA)
        self.plan = phyfft.batch_fft(64, self.L)
        self.buf = phyfft.aligned_empty((N_LINKS, self.L))
        self.time_pipeline()

    def time_pipeline(self):
        R = synthesize(self.paths, self.S, self.system, self.rng)
        correlation_tables(R, self.S, self.system, beta=BETA)

    def time_pipeline_streaming(self):
        R = synthesize(self.paths, self.S, self.system, self.rng)
        correlation_tables(R, self.S, self.system, beta=BETA, out=self.buf)

    def time_fft_floor(self):
        for _ in range(N_LINKS // 64):
            self.plan.execute()


class Interpolation:
    """asv: evaluating a table at 10⁵ random distances."""

    params = [["linear", "cubic", "quintic"]]
    param_names = ["method"]

    def setup(self, method):
        system, S, paths, rng = make_batch(n_links=16, n_paths=4)
        self.table = correlation_tables(synthesize(paths, S, system, rng), S, system, beta=BETA)
        self.d = rng.uniform(0.0, 200.0, (16, 100_000 // 16))
        self.table.evaluate(self.d[:, :2], interpolation=method)

    def time_evaluate(self, method):
        self.table.evaluate(self.d, interpolation=method)


def _interp_accuracy(method, rng, n_links=32):
    system = OFDMSystem()
    S = qpsk_symbols(system, 1, rng)
    d_true = rng.uniform(5.0, 140.0, n_links)
    R = synthesize(PathSet.single_path(d_true / C0, 1e-6), S, system, None)
    tab = correlation_tables(R, S, system, beta=BETA)
    d = rng.uniform(0.0, 200.0, (n_links, 2000))
    err = np.abs(tab.evaluate(d, interpolation=method) - tab.exact(d)).max()
    rel = err / np.abs(tab.values).max()
    # peak of the interpolated |f|² on a fine (1 mm) grid around the truth
    off = np.arange(-1.0, 1.0, 1e-3)
    dd = d_true[:, None] + off[None, :]
    f = tab.evaluate(dd, interpolation=method)
    bias = np.abs(off[np.argmax(np.abs(f), axis=1)]).max()
    return float(rel), float(bias)


def peak_rmse_over_sqrt_crb(pc_snr_db: float, n_links: int = 1000, seed: int = 0) -> float:
    """RMSE of :meth:`CorrelationTable.peak` over √CRB for one-path AWGN links."""
    system = OFDMSystem()
    rng = np.random.default_rng(seed)
    S = qpsk_symbols(system, 1, rng)
    snr = 10 ** (pc_snr_db / 10) / system.n_subcarriers
    d_true = rng.uniform(5.0, 140.0, n_links)
    gains = math.sqrt(snr * system.noise_power_w) * np.exp(2j * np.pi * rng.uniform(size=n_links))
    R = synthesize(PathSet.single_path(d_true / C0, gains), S, system, rng)
    est = correlation_tables(R, S, system, beta=BETA).peak(window_m=(0.0, 200.0))
    return math.sqrt(np.mean((est - d_true) ** 2) / crb_range(snr, S[0], system))


def report(quick: bool = False) -> dict[str, float]:
    """Measure every figure of the module docstring; ``quick`` shortens the runs."""
    repeat = 2 if quick else 5
    system, S, paths, rng = make_batch()
    L = fft_length(system, BETA)
    fig: dict[str, float] = {"n_links": N_LINKS, "n_paths": N_PATHS, "n_fft": L, "beta": L / 2569}

    twin = naive("naive_phy")
    t_syn = best_seconds(lambda: synthesize(paths, S, system, rng), repeat=repeat)
    if twin is not None:
        t_syn_np = best_seconds(
            lambda: numpy_synthesize(twin, paths, S, system, rng), repeat=max(1, repeat - 2)
        )

    def pipeline():
        correlation_tables(synthesize(paths, S, system, rng), S, system, beta=BETA)

    buf = phyfft.aligned_empty((N_LINKS, L))

    def pipeline_streaming():
        correlation_tables(synthesize(paths, S, system, rng), S, system, beta=BETA, out=buf)

    plan = phyfft.batch_fft(64, L)

    def floor():
        for _ in range(N_LINKS // 64):
            plan.execute()

    # the pipelines and their floor in turn: their ratios compare runs under the same load
    # (3·repeat rounds: on a busy machine the longer pipeline is preempted more often than the
    # floor, and its best round needs more tries to be an undisturbed one)
    best = best_seconds_interleaved(
        {"pipe": pipeline, "stream": pipeline_streaming, "floor": floor}, repeat=3 * repeat
    )
    t_pipe, t_stream, t_floor = best["pipe"], best["stream"], best["floor"]
    if twin is not None:
        t_pipe_np = best_seconds(
            lambda: numpy_pipeline(twin, paths, S, system, rng), repeat=max(1, repeat - 2)
        )
    fig["synthesis_links_per_s"] = N_LINKS / t_syn
    if twin is not None:
        fig["synthesis_numpy_links_per_s"] = N_LINKS / t_syn_np
        fig["synthesis_speedup_vs_numpy"] = t_syn_np / t_syn
    fig["pipeline_links_per_s"] = N_LINKS / t_pipe
    if twin is not None:
        fig["pipeline_numpy_links_per_s"] = N_LINKS / t_pipe_np
    fig["fft_floor_links_per_s"] = N_LINKS / t_floor
    fig["pipeline_cost_over_floor"] = t_pipe / t_floor
    import numba

    from phyloc.parallel import limit_threads

    threads = (numba.get_num_threads(), phyfft.threads())
    limit_threads(1)
    try:
        plan1 = phyfft.batch_fft(64, L)

        def floor1():
            for _ in range(N_LINKS // 64):
                plan1.execute()

        cpu = best_seconds_interleaved(
            {"pipe": pipeline_streaming, "floor": floor1}, repeat=2 * repeat, clock=time.thread_time
        )
    finally:
        limit_threads(threads[0])
        phyfft.set_backend(phyfft.backend(), threads=threads[1])
    fig["pipeline_cpu_over_floor_1t"] = cpu["pipe"] / cpu["floor"]
    fig["pipeline_streaming_links_per_s"] = N_LINKS / t_stream
    fig["pipeline_streaming_cost_over_floor"] = t_stream / t_floor
    fig["fft_threads"] = phyfft.threads()

    for tag, kw in NUMEROLOGIES.items():  # the pipeline in NR numerologies, its own floor
        nsys, nS, npaths, nrng = make_batch(system=OFDMSystem(**kw))
        nL = fft_length(nsys, BETA)
        nplan = phyfft.batch_fft(64, nL)

        def npipe(nsys=nsys, nS=nS, npaths=npaths, nrng=nrng):
            correlation_tables(synthesize(npaths, nS, nsys, nrng), nS, nsys, beta=BETA)

        def nfloor(nplan=nplan):
            for _ in range(N_LINKS // 64):
                nplan.execute()

        nbest = best_seconds_interleaved({"pipe": npipe, "floor": nfloor}, repeat=2 * repeat)
        fig[f"{tag}.n_fft"] = nL
        fig[f"{tag}.pipeline_links_per_s"] = N_LINKS / nbest["pipe"]
        fig[f"{tag}.pipeline_cost_over_floor"] = nbest["pipe"] / nbest["floor"]
    acc_rng = np.random.default_rng(1)
    for method in ("linear", "cubic", "quintic"):
        it = Interpolation()
        it.setup(method)
        t = best_seconds(lambda it=it, m=method: it.time_evaluate(m), repeat=repeat)
        fig[f"interp.{method}.points_per_s"] = it.d.size / t
        rel, bias = _interp_accuracy(method, acc_rng)
        fig[f"interp.{method}.max_rel_error"] = rel
        fig[f"interp.{method}.peak_bias_m"] = bias
    for pc_db in (20, 30, 40):
        fig[f"peak_rmse_over_sqrt_crb.{pc_db}db"] = peak_rmse_over_sqrt_crb(pc_db, seed=pc_db)
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`'s figures."""
    from phyloc.reporting import format_table

    def us(rate):
        return 1e6 / rate

    floor = fig["fft_floor_links_per_s"]
    has_twin = "synthesis_numpy_links_per_s" in fig
    if has_twin:
        floor_np = fig["pipeline_numpy_links_per_s"]
        twin_rows = [
            (
                "synthesis (NumPy twin)",
                fig["synthesis_numpy_links_per_s"],
                us(fig["synthesis_numpy_links_per_s"]),
                "reference",
            ),
            (
                "pipeline (plain NumPy)",
                fig["pipeline_numpy_links_per_s"],
                us(fig["pipeline_numpy_links_per_s"]),
                f"reference ({fig['pipeline_links_per_s'] / floor_np:.0f}x slower)",
            ),
        ]
    else:
        twin_rows = [
            ("synthesis (NumPy twin)", "MISSING", None, None),
            ("pipeline (plain NumPy)", "MISSING", None, None),
        ]
    rows = [
        (
            "synthesis (Numba, with AWGN)",
            fig["synthesis_links_per_s"],
            us(fig["synthesis_links_per_s"]),
            f"{fig['synthesis_speedup_vs_numpy']:.1f}x NumPy twin" if has_twin else None,
        ),
        twin_rows[0],
        (
            "pipeline: synthesis + table",
            fig["pipeline_links_per_s"],
            us(fig["pipeline_links_per_s"]),
            f"{fig['pipeline_cost_over_floor']:.2f}x floor cost",
        ),
        (
            "pipeline, tables into one reused array",
            fig["pipeline_streaming_links_per_s"],
            us(fig["pipeline_streaming_links_per_s"]),
            f"{fig['pipeline_streaming_cost_over_floor']:.2f}x floor cost",
        ),
        twin_rows[1],
        ("floor: one planned FFT per link", floor, us(floor), f"L = {int(fig['n_fft'])}"),
        (
            "pipeline on one thread, CPU time",
            None,
            None,
            f"{fig['pipeline_cpu_over_floor_1t']:.2f}x floor cost",
        ),
    ]
    nrows = [
        (
            f"{tag}: N = {kw['n_subcarriers']}, {kw['subcarrier_spacing_hz'] / 1e3:g} kHz",
            fig[f"{tag}.pipeline_links_per_s"],
            us(fig[f"{tag}.pipeline_links_per_s"]),
            f"{fig[f'{tag}.pipeline_cost_over_floor']:.2f}x its floor "
            f"(L = {int(fig[f'{tag}.n_fft'])})",
        )
        for tag, kw in NUMEROLOGIES.items()
        if f"{tag}.pipeline_links_per_s" in fig
    ]
    rows += nrows
    head = (
        f"N = 2569 subcarriers, {int(fig['n_paths'])} paths/link, batches of "
        f"{int(fig['n_links'])} links, beta = {fig['beta']:.3f}, "
        f"{int(fig['fft_threads'])} FFT threads"
    )
    t1 = format_table(rows, ["work", "links/s", "us/link", "ratio"])
    irows = [
        (
            m,
            fig[f"interp.{m}.points_per_s"],
            fig[f"interp.{m}.max_rel_error"],
            fig[f"interp.{m}.peak_bias_m"],
        )
        for m in ("linear", "cubic", "quintic")
    ]
    t2 = format_table(irows, ["interpolation", "points/s", "max rel error", "peak bias [m]"])
    crows = [(f"{db} dB", fig[f"peak_rmse_over_sqrt_crb.{db}db"]) for db in (20, 30, 40)]
    t3 = format_table(crows, ["post-corr. SNR", "peak RMSE / sqrt(CRB)"])
    missing = "" if has_twin else f"\nMISSING: {MISSING}"
    return f"{head}\n{t1}{missing}\n\n{t2}\n\n{t3}"
