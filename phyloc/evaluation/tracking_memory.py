"""The tracking experiment's memory study: peak resident memory of every method per network
size, each run in a fresh process (PF-BP abstract: PF-BP keeps a Gaussian per agent where
SIR-BP keeps and exchanges particles).

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from phyloc.evaluation.rss import peak_rss_mb, reset_peak_rss, status_mb
from phyloc.evaluation.statistics import Pooled
from phyloc.evaluation.tracking_scenarios import gaussian_run
from phyloc.localization import METHODS
from phyloc.localization.tracking import paper_prior


def _memory_probe(payload) -> tuple[float, float]:
    """Peak RSS of one method on one network, in a fresh process: ``(before, peak)`` [MB].

    The method first runs on a 2-agent, 1-step network with the same options (its kernels
    compile or load from the cache there, so compiler memory is not counted), then the
    scenario is simulated and the prior drawn. ``before`` is the resident set size then, and
    the peak is measured from there on: the kernel's peak-RSS mark is reset to the current RSS
    (``/proc/self/clear_refs``), so memory freed earlier (imports, compilation) cannot hide
    the run's; where that reset is impossible, ``before`` is the high-water mark so far
    (``ru_maxrss``) and a run below it reads as 0."""
    exp, scen, options, base, seed = payload
    rng = np.random.default_rng(seed)
    method = METHODS[base]
    tiny = dataclasses.replace(exp, n_steps=1)
    sc, _ = gaussian_run(tiny, {"n_agents": 2, "comm_range_m": math.inf}, rng)
    small = options
    if hasattr(options, "n_particles"):  # a small warm-up run
        small = dataclasses.replace(options, n_particles=min(options.n_particles, 64))
    meas = sc.measurements()
    method.run(meas, paper_prior(meas, rng), rng, small)
    sc, _ = gaussian_run(exp, scen, rng)
    meas = sc.measurements()
    prior = paper_prior(meas, rng, sigma_p=exp.sigma_p, accel_init_factor=exp.accel_init_factor)
    if reset_peak_rss():
        before = status_mb("VmRSS")
        method.run(meas, prior, rng, options)
        return before, status_mb("VmHWM")
    before = peak_rss_mb()
    method.run(meas, prior, rng, options)
    return before, peak_rss_mb()


def memory_study(exp, options, bases, seed, *, progress=True) -> dict:
    """Peak memory of every method per network size (PF-BP abstract: PF-BP keeps a Gaussian
    per agent where SIR-BP keeps and exchanges particles).

    Each (method, network) runs :func:`_memory_probe` in a fresh spawned process, one at a
    time (``ru_maxrss`` is a per-process high-water mark), ``exp.memory_repeats`` times: the
    repeats are the figures' units (each a network and prior of its own, the same ones for
    every method, so two methods compare paired). Networks: every scenario of ``exp`` at its
    own size, and ``exp.memory_agents`` at the first scenario's communication range,
    ``exp.memory_steps`` steps each, Gaussian range measurements (the tracker's memory does not
    depend on how the ranges were measured). Returns :class:`~phyloc.evaluation.statistics.Pooled`
    means over the repeats: ``<m>.<s>.peak_rss_mb`` (the process's peak RSS during the run)
    and ``<m>.<s>.run_rss_mb`` (that peak minus the RSS before the run: what the method itself
    needed), and the same per size as ``<m>.<s>.agents_<n>.peak_rss_mb`` / ``.run_rss_mb``.
    Repeat 0 draws its network from the job's seed as a single measurement does; repeat
    ``i > 0`` from that seed's ``i``-th spawned child."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from tqdm.auto import tqdm

    from phyloc.parallel import _quiet_progress

    first = next(iter(exp.scenarios))
    short = dataclasses.replace(exp, n_steps=exp.memory_steps)
    jobs = []
    for tok, scen in exp.scenarios.items():
        jobs.append((f"{tok}", scen))
    for n in exp.memory_agents:
        r = exp.scenarios[first]["comm_range_m"]
        jobs.append((f"{first}.agents_{n}", {"n_agents": n, "comm_range_m": r}))
    reps = exp.memory_repeats
    seeds = [[s, *s.spawn(reps - 1)] for s in np.random.SeedSequence(seed).spawn(len(jobs))]
    ctx = multiprocessing.get_context("spawn")
    todo = [
        (m, label, scen, s)
        for m in exp.methods
        for (label, scen), s in zip(jobs, seeds, strict=True)
    ]
    bar = tqdm(total=len(todo) * reps, desc="memory", disable=not progress or _quiet_progress())
    figures = {}
    try:
        for m, label, scen, job_seeds in todo:
            peak, run = [], []
            for s in job_seeds:
                with ProcessPoolExecutor(1, mp_context=ctx) as pool:
                    payload = (short, scen, options[m], bases[m], s)
                    before, after = pool.submit(_memory_probe, payload).result()
                peak.append(after)
                run.append(max(after - before, 0.0))
                bar.update(1)
            figures[f"{m}.{label}.peak_rss_mb"] = Pooled.mean(peak)
            figures[f"{m}.{label}.run_rss_mb"] = Pooled.mean(run)
    finally:
        bar.close()
    return figures
