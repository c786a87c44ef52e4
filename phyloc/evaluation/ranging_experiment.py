"""Ranging RMSE of two-step front ends versus distance, against CRB and ZZB (DiPNet Fig. 4).

A recipe of ``kind = "ranging"`` runs, for every scenario token (e.g. ``c2`` → ``winner2_c2``),
every network size in ``experiment.agents`` and every realization: a fully meshed network
(``[network]``), a channel draw per directed link (``[channel]``), the received signals and
their correlation tables (``[system]``, ``ranging.beta``), and every estimator of
``ranging.methods`` on all links. Errors are pooled over sizes and realizations and binned by
true distance. The bounds are the one-path CRB (DiPNet eq. (24)) and ZZB at each link's link-budget
SNR (received power over noise, as if the power arrived in one path), pooled per bin as
``sqrt(mean(bound))``. An AWGN sweep of post-correlation SNR checks the correlation estimator
against the CRB and locates the threshold below which wrong-peak outliers appear (an outlier
is an error beyond the first null of the autocorrelation, ``c0/B``).

Figures (``results.json``; ``<m>`` a method, ``<s>`` a scenario token; † marks a figure pooled
over the realizations of ``<s>`` — every network size and realization is one unit — which
comes with its 95 % interval ``<name>.ci_low`` / ``<name>.ci_high`` and its per-realization
values ``series["<name>.units"]``, :mod:`~phyloc.evaluation.statistics`):

* ``<m>.<s>.rmse_m`` †: ranging RMSE over all valid links;
* ``<m>.<s>.rmse_los_m`` / ``rmse_nlos_m`` †: the same over LOS / NLOS links;
* ``<m>.<s>.valid_fraction`` †: fraction of links with a range;
* ``<m>.<s>.rmse_over_zzb``: ``rmse_m`` over the pooled √ZZB of the same links (its interval:
  ``<m>_vs_zzb.<s>.rmse_m.ratio``, below);
* ``<a>_vs_<b>.<s>.rmse_m.ratio`` (with ``.ci_low`` / ``.ci_high``): ``rmse_m`` of method
  ``<a>`` over that of ``<b>`` (every pair, in the order of ``ranging.methods``), with the
  interval of the paired bootstrap over the realizations both ran on (below 1 favours ``<a>``);
* ``<m>_vs_zzb.<s>.rmse_m.ratio`` (with its interval): ``rmse_m`` over the pooled √ZZB of the
  same links — ``rmse_over_zzb`` up to rounding, with its paired interval;
* ``crb.<s>.rmse_m`` / ``zzb.<s>.rmse_m``: pooled √CRB / √ZZB over all links (bounds: no
  interval);
* ``<s>.los_fraction`` †, ``<s>.n_links``;
* ``corr.awgn.crb_ratio_<x>db``: RMSE/√CRB of the correlation peak at post-correlation SNR
  x dB (one task per SNR: no interval);
* ``corr.awgn.threshold_snr_db``: lowest swept SNR from which on outliers stay <= 1 %;
* ``zzb.awgn.threshold_snr_db``: the same SNR as predicted by the ZZB (ZZB <= 1.15 CRB).

Series: ``distance_bin_centers_m``, ``<m>.<s>.rmse_by_distance_m`` (and its 95 % interval per
bin over the realizations, ``.ci_low`` / ``.ci_high``), ``crb.<s>.rmse_by_distance_m``,
``zzb.<s>.rmse_by_distance_m``, ``<s>.links_by_distance``, ``awgn.pc_snr_db``,
``corr.awgn.rmse_over_sqrt_crb``, ``corr.awgn.outlier_fraction``, ``zzb.awgn.over_crb``; the
``<name>.units`` of every † figure.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

S. M. Kay, *Fundamentals of Statistical Signal Processing, Volume I: Estimation Theory*,
Prentice Hall, 1993 (the Cramér–Rao bound, ch. 3).

K. L. Bell, Y. Steinberg, Y. Ephraim and H. L. Van Trees, "Extended Ziv–Zakai lower bound for
vector parameter estimation," IEEE Trans. Information Theory 43(2), pp. 624–637, 1997.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from phyloc import _validate as v
from phyloc.channels import ChannelSpec
from phyloc.datasets.simulate import check_heights, simulate_realization
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment
from phyloc.evaluation.sections import RangingSpec, network_specs, scenario_specs
from phyloc.evaluation.statistics import Paired, Pooled, interval
from phyloc.phy import C0, PathSet
from phyloc.phy.bounds import crb_range, zzb_range
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols
from phyloc.ranging import estimate, ranging_variance
from phyloc.reporting import new_figure, save_figure, with_interval


@dataclass(frozen=True)
class RangingExperimentSpec:
    """``[experiment]`` of a ranging recipe (``[experiment.fast]`` overrides for ``--fast``)."""

    scenarios: dict = field(default_factory=lambda: {"c2": "winner2_c2", "d1": "winner2_d1"})
    agents: tuple = (3, 6, 9, 12, 15, 18, 21, 24, 27, 30)
    realizations: int = 5
    distance_bins_m: tuple = tuple(float(x) for x in range(0, 150, 10))
    awgn_snr_db: tuple = tuple(float(x) for x in np.arange(0.0, 41.0, 2.5))
    awgn_links: int = 1000

    def __post_init__(self):
        if not isinstance(self.scenarios, dict) or not self.scenarios:
            raise ValidationError(
                "experiment.scenarios", self.scenarios, "a table token = scenario name"
            )
        agents = tuple(v.integer("experiment.agents", a, minimum=2) for a in self.agents)
        if not agents:
            raise ValidationError("experiment.agents", [], "at least one network size >= 2")
        object.__setattr__(self, "agents", agents)
        v.integer_field(self, "realizations", "experiment.realizations", minimum=1)
        bins = tuple(float(b) for b in self.distance_bins_m)
        if len(bins) < 2 or np.any(np.diff(bins) <= 0):
            raise ValidationError(
                "experiment.distance_bins_m", self.distance_bins_m, "increasing edges, >= 2"
            )
        object.__setattr__(self, "distance_bins_m", bins)
        object.__setattr__(self, "awgn_snr_db", tuple(float(x) for x in self.awgn_snr_db))
        v.integer_field(self, "awgn_links", "experiment.awgn_links", minimum=0)


def _task(payload, seed_seq):
    """One network realization of one scenario: ranging errors of every method on every link."""
    system, net_spec, chan_spec, rspec = payload
    real = simulate_realization(system, net_spec, chan_spec, np.random.default_rng(seed_seq))
    net, links, draw = real.network, real.links[0], real.channels[0]
    d = net.distances(0)
    tx = links[:, 1]
    table = correlation_tables(real.received[0], real.symbols, system, beta=rspec.beta, tx_index=tx)
    ways = real.ways
    out = {
        "distance_m": d,
        "los": np.asarray(draw.los, bool),
        "snr_budget": draw.received_power_w / system.noise_power_w,
    }
    for m in rspec.methods:
        est = estimate(m, table, los=draw.los, **rspec.method_options(m))
        out[f"{m}.range_m"] = est.range_m / ways
        out[f"{m}.valid"] = np.asarray(est.valid, bool)
    return out


def _awgn_task(payload, seed_seq):
    """Correlation-peak errors of one-path AWGN links at one post-correlation SNR."""
    system, pc_db, n_links, beta, window = payload
    rng = np.random.default_rng(seed_seq)
    S = qpsk_symbols(system, 1, rng)
    snr = 10 ** (pc_db / 10) / float((np.abs(S[0]) ** 2).sum())
    d = rng.uniform(5.0, 140.0, n_links)
    gains = math.sqrt(snr * system.noise_power_w) * np.exp(2j * np.pi * rng.uniform(size=n_links))
    R = synthesize(PathSet.single_path(d / C0, gains), S, system, rng)
    est = estimate("corr", correlation_tables(R, S, system, beta=beta), window_m=window)
    return {"err": est.range_m - d, "snr": snr}


def _run_one(payload, seed_seq):
    """Dispatch one task: ``("network", ...)`` or ``("awgn", ...)``."""
    kind, body = payload
    return _task(body, seed_seq) if kind == "network" else _awgn_task(body, seed_seq)


def _rmse(x) -> float:
    x = np.asarray(x, float)
    return float(math.sqrt(np.mean(x**2))) if x.size else float("nan")


def _binned_sqrt_mean(x, b, mask, n_bins):
    out = np.full(n_bins, np.nan)
    if mask.any():
        s = np.bincount(b[mask], weights=x[mask], minlength=n_bins)
        c = np.bincount(b[mask], minlength=n_bins)
        ok = c > 0
        out[ok] = np.sqrt(s[ok] / c[ok])
    return out


def _binned_interval(sq_per_unit, bin_per_unit, mask_per_unit, n_bins, *, seed, name):
    """Per distance bin, the 95 % interval of the RMSE pooled over units (each unit's squared
    errors ``sq``, bin indices and mask): two ``[n_bins]`` arrays, NaN where a bin has too few
    units (:func:`~phyloc.evaluation.statistics.interval`)."""
    num = np.array(
        [
            np.bincount(b[k], weights=x[k], minlength=n_bins)
            for x, b, k in zip(sq_per_unit, bin_per_unit, mask_per_unit, strict=True)
        ]
    ).reshape(-1, n_bins)
    den = np.array(
        [
            np.bincount(b[k], minlength=n_bins)
            for b, k in zip(bin_per_unit, mask_per_unit, strict=True)
        ]
    ).reshape(-1, n_bins)
    lo, hi = np.full(n_bins, np.nan), np.full(n_bins, np.nan)
    for j in np.flatnonzero(den.sum(axis=0) > 0):
        lo[j], hi[j] = interval(
            Pooled(num[:, j], den[:, j], "rmse"), seed=seed, name=f"{name}[{j}]"
        )
    return lo, hi


def _comparisons(figures, methods, tok):
    """Paired ratios of ``rmse_m`` over the same realizations for every pair of methods
    (``<a>_vs_<b>``, in the order of ``methods``; below 1 favours ``<a>``)."""
    for i, a in enumerate(methods):
        for bm in methods[i + 1 :]:
            figures[f"{a}_vs_{bm}.{tok}.rmse_m"] = Paired(
                figures[f"{a}.{tok}.rmse_m"], figures[f"{bm}.{tok}.rmse_m"]
            )


def _awgn_figures(results, exp, system, S_ref, rspec, figures, series):
    pc = np.asarray(exp.awgn_snr_db)
    ratio, outl = [], []
    first_null = C0 / system.bandwidth_hz
    for res in results:
        err = res["err"]
        ratio.append(_rmse(err) / math.sqrt(float(crb_range(res["snr"], S_ref, system))))
        outl.append(float(np.mean(np.abs(err) > first_null)))
    ratio, outl = np.asarray(ratio), np.asarray(outl)
    snr = 10 ** (pc / 10) / system.n_subcarriers
    zzb_over = zzb_range(snr, S_ref, system, prior_range_m=rspec.prior_range_m) / crb_range(
        snr, S_ref, system
    )
    series["awgn.pc_snr_db"] = pc
    series["corr.awgn.rmse_over_sqrt_crb"] = ratio
    series["corr.awgn.outlier_fraction"] = outl
    series["zzb.awgn.over_crb"] = np.sqrt(zzb_over)
    for db in (20.0, 30.0, 40.0):
        hit = np.flatnonzero(np.isclose(pc, db))
        if hit.size:
            figures[f"corr.awgn.crb_ratio_{int(db)}db"] = float(ratio[hit[0]])
    figures["corr.awgn.threshold_snr_db"] = _threshold(pc, outl <= 0.01)
    figures["zzb.awgn.threshold_snr_db"] = _threshold(pc, np.sqrt(zzb_over) <= 1.15)


def _threshold(pc, ok) -> float:
    """Lowest SNR from which on ``ok`` holds at every higher swept SNR (NaN if never)."""
    order = np.argsort(pc)
    pc, ok = pc[order], ok[order]
    bad = np.flatnonzero(~ok)
    if bad.size == 0:
        return float(pc[0])
    if bad[-1] == pc.size - 1:
        return float("nan")
    return float(pc[bad[-1] + 1])


def plot(results: dict, path) -> None:
    """Draw the ranging figure (DiPNet Fig. 4 layout plus the AWGN sweep) from results only."""
    fig_d, ser, meta = results["figures"], results["series"], results["meta"]
    tokens = list(meta["scenarios"])
    fig, axes = new_figure(1, len(tokens) + 1, size=(5.0 * (len(tokens) + 1), 4.2))
    x = np.asarray(ser["distance_bin_centers_m"])
    styles = {"corr": "o-", "first_peak": "v-", "sage": "s-", "sage_los": "d--"}
    for ax, tok in zip(axes, tokens, strict=False):
        for i, m in enumerate(meta["methods"]):
            label = f"{m} (oracle)" if m == "sage_los" else m
            name = f"{m}.{tok}.rmse_by_distance_m"
            ax.semilogy(x, ser[name], styles.get(m, "x-"), color=f"C{i}", label=label)
            _error_bars(ax, x, ser, name, f"C{i}")
        ax.semilogy(x, ser[f"crb.{tok}.rmse_by_distance_m"], "k-", lw=1, label="√CRB")
        ax.semilogy(x, ser[f"zzb.{tok}.rmse_by_distance_m"], "k:", lw=1.5, label="√ZZB")
        ax.set_title(
            f"{tok}: LOS {100 * fig_d[f'{tok}.los_fraction']:.1f} %, "
            f"{int(fig_d[f'{tok}.n_links'])} links (bars: 95 % intervals)"
        )
        ax.set_xlabel("distance [m]")
        ax.set_ylabel("ranging RMSE [m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    ax = axes[-1]
    if "awgn.pc_snr_db" in ser:
        ax.semilogy(
            ser["awgn.pc_snr_db"],
            ser["corr.awgn.rmse_over_sqrt_crb"],
            "o-",
            label="corr RMSE / √CRB",
        )
        ax.semilogy(ser["awgn.pc_snr_db"], ser["zzb.awgn.over_crb"], "k:", label="√ZZB / √CRB")
        ax.axhline(1.15, color="grey", lw=0.8, ls="--", label="1.15")
        thr = fig_d.get("corr.awgn.threshold_snr_db")
        if thr is not None and np.isfinite(thr):
            ax.axvline(thr, color="C3", lw=0.8, label=f"outlier threshold {thr:g} dB")
        ax.set_xlabel("post-correlation SNR [dB]")
        ax.set_ylabel("ratio")
        ax.set_title("AWGN: correlation peak vs CRB")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(
        f"Ranging RMSE versus bounds — {meta['recipe']}{' (fast)' if meta.get('fast') else ''}"
    )
    save_figure(fig, path)


def _error_bars(ax, x, series: dict, name: str, color) -> None:
    """Error bars of the per-bin 95 % interval of the series ``name`` (bins without one —
    fewer than two realizations with links there — get none; a band would bridge them)."""
    lo, hi = series.get(name + ".ci_low"), series.get(name + ".ci_high")
    if lo is None or hi is None:
        return
    y = np.asarray(series[name], dtype=float)
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    ok = np.isfinite(lo) & np.isfinite(hi) & np.isfinite(y)
    if ok.any():
        err = np.clip([y[ok] - lo[ok], hi[ok] - y[ok]], 0.0, None)
        ax.errorbar(np.asarray(x)[ok], y[ok], yerr=err, fmt="none", ecolor=color, capsize=2, lw=1)


def summary_lines(results: dict):
    """Extra printed lines: what the brackets are, the paired RMSE ratios of the methods and
    the AWGN check."""
    f, meta = results["figures"], results["meta"]
    out = [
        "RMSE, valid fraction [95 % interval over realizations]; RMSE/√ZZB on the links each "
        "method ranged [paired 95 % interval]"
    ]
    methods = meta.get("methods", [])
    for tok in meta.get("scenarios", []):
        pairs = [
            f"{a}/{b} {with_interval(f, key)}"
            for i, a in enumerate(methods)
            for b in methods[i + 1 :]
            if (key := f"{a}_vs_{b}.{tok}.rmse_m.ratio") in f
        ]
        if pairs:
            out.append(f"{tok}: RMSE ratios (paired over realizations): " + ", ".join(pairs))
    if "corr.awgn.threshold_snr_db" in f:
        ratios = ", ".join(
            f"{db} dB: {f[k]:.3f}"
            for db in (20, 30, 40)
            if (k := f"corr.awgn.crb_ratio_{db}db") in f
        )
        out.append(
            f"AWGN correlation peak RMSE/√CRB — {ratios}; outliers stay <= 1 % from "
            f"{f['corr.awgn.threshold_snr_db']:g} dB post-correlation SNR "
            f"(ZZB within 15 % of CRB from {f['zzb.awgn.threshold_snr_db']:g} dB)"
        )
    return out


def summary_rows(results: dict):
    """Rows (scenario, method, RMSE, LOS, NLOS, valid, RMSE/√ZZB) for the printed table, each
    Monte Carlo figure with its 95 % interval when the run has one."""
    f, meta = results["figures"], results["meta"]
    rows = []
    for tok in meta["scenarios"]:
        for m in meta["methods"]:
            name = f"{m} (oracle)" if m == "sage_los" else m
            ratio = f"{m}_vs_zzb.{tok}.rmse_m.ratio"
            rows.append(
                (
                    tok,
                    name,
                    with_interval(f, f"{m}.{tok}.rmse_m"),
                    with_interval(f, f"{m}.{tok}.rmse_los_m"),
                    with_interval(f, f"{m}.{tok}.rmse_nlos_m"),
                    with_interval(f, f"{m}.{tok}.valid_fraction"),
                    with_interval(f, ratio) if ratio in f else f[f"{m}.{tok}.rmse_over_zzb"],
                )
            )
        rows.append((tok, "√CRB", f[f"crb.{tok}.rmse_m"], None, None, None, None))
        rows.append((tok, "√ZZB", f[f"zzb.{tok}.rmse_m"], None, None, None, None))
    return rows


class RangingExperiment(Experiment):
    """``kind = "ranging"``: one task per (scenario token, network size, realization), then one
    per AWGN SNR point."""

    kind = "ranging"
    title = "ranging RMSE of the estimators against the CRB and ZZB (DiPNet Fig. 4)"
    unit = "realization"
    spec = RangingExperimentSpec
    task = staticmethod(_run_one)
    headers = ("scenario", "method", "RMSE [m]", "LOS [m]", "NLOS [m]", "valid", "RMSE/√ZZB")

    def prepare(self, recipe, *, fast=False):
        exp = self.experiment_spec(recipe, fast=fast)
        rspec = recipe.section("ranging", RangingSpec)
        nets = network_specs(recipe.section("network"), exp.agents)
        specs = scenario_specs(recipe.section("channel", ChannelSpec), exp.scenarios)
        check_heights(nets.values(), specs.values())
        return SimpleNamespace(system=recipe.system, exp=exp, rspec=rspec, nets=nets, specs=specs)

    def tasks(self, plan):
        system, exp, rspec, nets, specs = plan.system, plan.exp, plan.rspec, plan.nets, plan.specs
        work = [
            ((tok, n, r), ("network", (system, nets[n], spec, rspec)))
            for tok, spec in specs.items()
            for n in exp.agents
            for r in range(exp.realizations)
        ]
        if exp.awgn_links:
            work += [
                (("awgn", db), ("awgn", (system, db, exp.awgn_links, rspec.beta, rspec.window_m)))
                for db in exp.awgn_snr_db
            ]
        return work

    def aggregate(self, plan, keys, results, ctx):
        system, exp, rspec, specs = plan.system, plan.exp, plan.rspec, plan.specs
        n_net = sum(1 for k in keys if k[0] != "awgn")
        keys, net_results, awgn_results = keys[:n_net], results[:n_net], results[n_net:]
        S_ref = qpsk_symbols(system, 1, np.random.default_rng(0))[0]  # unit modulus: any row
        edges = np.asarray(exp.distance_bins_m)
        centers = 0.5 * (edges[1:] + edges[:-1])
        figures: dict[str, float] = {}
        series: dict[str, list] = {"distance_bin_centers_m": centers}
        for tok in specs:
            parts = [res for (t, _, _), res in zip(keys, net_results, strict=True) if t == tok]
            d = np.concatenate([p["distance_m"] for p in parts])
            los = np.concatenate([p["los"] for p in parts])
            snr = np.concatenate([p["snr_budget"] for p in parts])
            crb = crb_range(snr, S_ref, system)
            zzb = ranging_variance(
                snr, S_ref, system, kind="zzb", prior_range_m=rspec.prior_range_m
            )
            b = np.digitize(d, edges) - 1
            inb = (b >= 0) & (b < centers.size)
            cuts = np.cumsum([p["distance_m"].size for p in parts])[:-1]  # link ranges per unit
            figures[f"{tok}.n_links"] = int(d.size)
            figures[f"{tok}.los_fraction"] = Pooled.fraction([p["los"] for p in parts])
            figures[f"crb.{tok}.rmse_m"] = float(math.sqrt(np.mean(crb)))
            figures[f"zzb.{tok}.rmse_m"] = float(math.sqrt(np.mean(zzb)))
            series[f"{tok}.links_by_distance"] = np.bincount(b[inb], minlength=centers.size)
            series[f"crb.{tok}.rmse_by_distance_m"] = _binned_sqrt_mean(crb, b, inb, centers.size)
            series[f"zzb.{tok}.rmse_by_distance_m"] = _binned_sqrt_mean(zzb, b, inb, centers.size)
            for m in rspec.methods:
                rng_est = np.concatenate([p[f"{m}.range_m"] for p in parts])
                valid = np.concatenate([p[f"{m}.valid"] for p in parts])
                err = rng_est - d
                # per realization (unit): its valid links' errors, LOS flags and ZZB
                u_err, u_valid, u_los = (np.split(x, cuts) for x in (err, valid, los))
                u_zzb = np.split(zzb, cuts)
                ok = list(zip(u_err, u_valid, u_los, strict=True))
                figures[f"{m}.{tok}.rmse_m"] = Pooled.rmse([e[v] for e, v, _ in ok])
                figures[f"{m}.{tok}.rmse_los_m"] = Pooled.rmse([e[v & s] for e, v, s in ok])
                figures[f"{m}.{tok}.rmse_nlos_m"] = Pooled.rmse([e[v & ~s] for e, v, s in ok])
                figures[f"{m}.{tok}.valid_fraction"] = Pooled.fraction(u_valid)
                figures[f"{m}.{tok}.rmse_over_zzb"] = (
                    _rmse(err[valid]) / math.sqrt(np.mean(zzb[valid]))
                    if valid.any()
                    else float("nan")
                )
                # √ZZB pooled over the links m ranged, per unit: the paired ratio's denominator
                zzb_m = Pooled(
                    [float(np.sum(z[v])) for z, v in zip(u_zzb, u_valid, strict=True)],
                    [int(v.sum()) for v in u_valid],
                    "rmse",
                )
                figures[f"{m}_vs_zzb.{tok}.rmse_m"] = Paired(figures[f"{m}.{tok}.rmse_m"], zzb_m)
                name = f"{m}.{tok}.rmse_by_distance_m"
                series[name] = _binned_sqrt_mean(err**2, b, inb & valid, centers.size)
                u_b, u_inb = np.split(b, cuts), np.split(inb, cuts)
                lo, hi = _binned_interval(
                    [e**2 for e in u_err],
                    u_b,
                    [i & v for i, v in zip(u_inb, u_valid, strict=True)],
                    centers.size,
                    seed=ctx.seed,
                    name=name,
                )
                series[name + ".ci_low"], series[name + ".ci_high"] = lo, hi
            _comparisons(figures, rspec.methods, tok)
        if awgn_results:
            _awgn_figures(awgn_results, exp, system, S_ref, rspec, figures, series)
        return figures, series

    def meta(self, plan, ctx):
        exp, rspec = plan.exp, plan.rspec
        return {
            "agents": list(exp.agents),
            "realizations": exp.realizations,
            "scenarios": dict(exp.scenarios),
            "methods": list(rspec.methods),
            "bounds_snr": "link budget (total received power / noise), one-path bounds",
            "oracle_methods": [m for m in rspec.methods if m == "sage_los"],
        }

    summary_rows = staticmethod(summary_rows)
    summary_lines = staticmethod(summary_lines)
    plot = staticmethod(plot)


RANGING = RangingExperiment()
