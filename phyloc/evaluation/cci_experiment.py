"""DiPNet Fig. 2: the conditional concavity indicator of any channel scenarios.

A recipe of ``kind = "cci"`` (and ``phyloc analyze cci SCENARIO...``) evaluates, for every
scenario of ``experiment.scenarios`` (names or scenario files) and the recipe's ``[system]``
(bandwidth ``B = N·f_sc``), the normalized CCI of :mod:`phyloc.analysis.cci` on ``points``
distances from ``d0_range_m[0]`` to ``d0_range_m[1]`` (default 0.1 m to 1 km): the bound for
arbitrary δ and b (DiPNet eqs. (43)–(44)), the exponential closed form (DiPNet App. III), the
AWGN benchmark ``−P_LOS`` and a Monte Carlo estimate from ``links`` links drawn by
:func:`phyloc.channels.draw_links` at each of ``mc_points`` distances. Every Monte Carlo
distance has its own random stream (``SeedSequence(seed).spawn``), so the numbers do not depend
on the worker count.

Figures, for every scenario ``s`` (its name)::

    cci.s.negative_above_m               bound (44) < 0 for every d0 above this [m]
    cci.s.exponential.negative_above_m   the same for the exponential closed form [m]
    cci.s.mc.negative_above_m            the same for the Monte Carlo means (grid) [m]
    cci.s.mc_z                           max |MC − exponential| / standard error over the grid
    cci.s.mc_above_bound_z               max (MC − bound) / standard error (≤ ~3 expected)
    cci.s.min_bandwidth_hz               smallest B making (44) negative at distance_m [Hz]
    cci.s.<curve>_at_max_m               bound, exponential and AWGN at the largest d0
    cci.s.scf_argmax_offset_m            where the expected SCF (DiPNet eq. (35), exponential
                                         delays) around the truth peaks, at distance_m [m]

For the models of :data:`phyloc.analysis.cci.DRAWN_MODELS` (tr38901, tdl) the expected powers
of the bound are estimated from drawn links (:func:`phyloc.analysis.cci.drawn_powers`); their
delays are not exponential, so ``exponential.negative_above_m`` is NaN and there is no
``mc_z`` and no expected SCF.

Series: ``cci.s.d0_m``, ``.bound``, ``.exponential``, ``.awgn``, ``.p_los``,
``.other_power``, ``.min_bandwidth_hz``, ``cci.s.mc_d0_m``, ``.mc``, ``.mc_se`` and the
expected SCF ``cci.s.scf`` over ``cci.s.scf_offset_m`` (±3 c0/B around the truth).

No figure here has ``.ci_low`` / ``.ci_high`` keys (:mod:`~phyloc.evaluation.statistics`): the
curves and their crossings are exact computations, and a unit (one Monte Carlo distance)
estimates the CCI at its own distance, so no figure is pooled over units. The uncertainty of
each Monte Carlo mean is its standard error over the links (``.mc_se``), in ``mc_z`` and
``mc_above_bound_z`` and as the 95 % error bars (±1.96 s.e.) of the plot.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from phyloc import _validate as v
from phyloc.analysis.cci import (
    D0_RANGE_M,
    DRAWN_MODELS,
    cci_bound,
    cci_curves,
    cci_exponential,
    cci_monte_carlo,
    expected_powers,
    expected_scf,
    exponential_rates,
    min_bandwidth_hz,
    negative_above,
    require_los,
)
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment, RunContext
from phyloc.evaluation.statistics import CONFIDENCE
from phyloc.phy.system import C0, OFDMSystem
from phyloc.reporting import new_figure, save_figure


@dataclass(frozen=True)
class CCIExperimentSpec:
    """``[experiment]`` of a ``cci`` recipe (``[experiment.fast]`` for ``--fast``).

    Parameters
    ----------
    scenarios : list of str
        Scenario names (``winner2_c2``, ``exponential``, ...) or scenario files; each needs a
        LOS part (the CCI is normalized to the LOS path power).
    links : int
        Monte Carlo links per distance (0: no Monte Carlo).
    mc_points : int
        Monte Carlo distances, log-spaced over ``d0_range_m`` (2 to 10 000).
    points : int
        Distances of the closed-form curves.
    d0_range_m : (float, float)
        Distance range [m] (DiPNet Fig. 2: 0.1 m to 1 km).
    distance_m : float
        Distance of the reported minimal bandwidth [m].
    """

    scenarios: tuple = ("winner2_c2", "winner2_d1")
    links: int = 20000
    mc_points: int = 21
    points: int = 400
    d0_range_m: tuple = D0_RANGE_M
    distance_m: float = 10.0

    def __post_init__(self):
        sc = self.scenarios
        if isinstance(sc, str) or not isinstance(sc, (list, tuple)) or not sc:
            raise ValidationError(
                "experiment.scenarios", sc, "a non-empty list of scenario names or files"
            )
        object.__setattr__(self, "scenarios", tuple(sc))
        v.integer_field(self, "links", "experiment.links", minimum=0)
        if self.links == 1:
            raise ValidationError("experiment.links", 1, "0 (no Monte Carlo) or >= 2")
        # each point is a Monte Carlo run of ``links`` links
        v.integer_field(self, "mc_points", "experiment.mc_points", minimum=2, maximum=10_000)
        v.integer_field(self, "points", "experiment.points", minimum=2)
        r = self.d0_range_m
        if not isinstance(r, (list, tuple)) or len(r) != 2:
            raise ValidationError("experiment.d0_range_m", r, "[min, max] in m")
        lo, hi = (v.positive("experiment.d0_range_m", x) for x in r)
        if not lo < hi:
            raise ValidationError("experiment.d0_range_m", list(r), "min < max [m]")
        object.__setattr__(self, "d0_range_m", (lo, hi))
        v.positive("experiment.distance_m", self.distance_m)


def _load(scenarios, where: str):
    """``{name: Scenario}`` in order; names must be unique and have a LOS part."""
    out = {}
    for i, s in enumerate(scenarios):
        try:
            scn = require_los(s)
        except ValidationError as exc:
            if exc.field != "scenario":  # a key inside the file: its own message names it
                raise
            raise ValidationError(f"{where}[{i}]", s, exc.allowed) from None
        if scn.name in out:
            raise ValidationError(f"{where}[{i}]", s, f"scenario '{scn.name}' is listed twice")
        out[scn.name] = scn
    return out


def _mc_task(payload, seed_seq):
    scn, d0, links, system = payload
    return cci_monte_carlo(scn, d0, links, np.random.default_rng(seed_seq), system)


def study(
    scenarios,
    system: OFDMSystem | None = None,
    exp: CCIExperimentSpec | None = None,
    *,
    seed: int = 0,
    workers=None,
    scheduler=None,
    progress=True,
    where: str = "experiment.scenarios",
):
    """Closed-form curves, Monte Carlo check and summary numbers for ``scenarios``: the
    ``cci`` experiment on a plan built from arguments instead of a recipe.

    ``where`` names the scenario list in error messages. Returns ``{"figures", "series",
    "meta"}`` (names in the module docstring).
    """
    system = OFDMSystem() if system is None else system
    exp = CCIExperimentSpec(scenarios=tuple(scenarios)) if exp is None else exp
    plan = CCI.plan(scenarios, system, exp, where)
    return CCI.execute(plan, RunContext(seed, False, workers, scheduler, progress))


def _z(diff, se):
    """``diff/se``; agreement to rounding (``|diff| ≤ 1e-12``, e.g. AWGN, where every link is
    the same and ``se`` is rounding noise) gives 0, a difference with ``se = 0`` ``±inf``."""
    diff, se = np.asarray(diff), np.asarray(se)
    tiny = np.abs(diff) <= 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(se > 0, diff / se, np.sign(diff) * np.inf)
    return np.where(tiny, 0.0, z)


#: The normal quantile of a two-sided 95 % interval of a Monte Carlo mean over many links.
_Z95 = float(stats.norm.ppf(0.5 + CONFIDENCE / 2))


def _fmt(x) -> str:
    """A threshold for the table; NaN (None once read back from JSON) is "never"."""
    return "never" if x is None or not math.isfinite(x) else f"{x:.3g}"


def summary_rows(results: dict):
    """Per scenario: where the three curves turn negative, the Monte Carlo check, B_min."""
    f = results["figures"]
    rows = []
    for s in results["meta"]["scenarios"]:
        p = f"cci.{s}"
        mc = f.get(f"{p}.mc.negative_above_m")
        rows.append(
            (
                s,
                _fmt(f[f"{p}.negative_above_m"]),
                _fmt(f[f"{p}.exponential.negative_above_m"])
                if s in results["meta"].get("rates_per_s", {s: None})
                else "n/a (drawn)",
                "" if mc is None else _fmt(mc),
                f.get(f"{p}.mc_z"),
                _fmt(
                    None if f[f"{p}.min_bandwidth_hz"] is None else f[f"{p}.min_bandwidth_hz"] / 1e6
                ),
            )
        )
    return rows


def summary_lines(results: dict):
    """System, distance grid and the meaning of the columns."""
    m = results["meta"]
    lo, hi = m["d0_range_m"]
    return [
        f"B = {m['bandwidth_hz'] / 1e6:.4g} MHz (N = {m['n_subcarriers']}), "
        f"fc = {m['carrier_frequency_hz'] / 1e9:.3g} GHz; d0 from {lo:g} to {hi:g} m",
        f"CCI normalized to the LOS direct-path power; Monte Carlo: {m['links']} links at "
        f"{m['mc_points']} distances; min B for the bound (44) at d0 = {m['distance_m']:g} m",
    ]


def plot(results: dict, path) -> None:
    """DiPNet Fig. 2 (CCI against d0) and the minimal bandwidth of eq. (44) against d0."""
    ser, meta = results["series"], results["meta"]
    has_scf = any(f"cci.{s}.scf" in ser for s in meta["scenarios"])
    if has_scf:
        fig, (ax, bx, cx) = new_figure(1, 3, size=(16.0, 4.8), width_ratios=[1.5, 1, 1])
    else:  # the expected SCF needs exponential delays (none of the drawn models has them)
        fig, (ax, bx) = new_figure(1, 2, size=(12.0, 4.8), width_ratios=[1.5, 1])
    unit = C0 / meta["bandwidth_hz"]
    for i, s in enumerate(meta["scenarios"]):
        col = f"C{i}"
        p = f"cci.{s}"
        d = ser[f"{p}.d0_m"]
        ax.plot(d, ser[f"{p}.bound"], "-", color=col, label=f"{s}: arbitrary δ, b (44)")
        if np.isfinite(np.asarray(ser[f"{p}.exponential"], dtype=float)).any():
            ax.plot(
                d, ser[f"{p}.exponential"], "--", color=col, label=f"{s}: exponential (App. III)"
            )
        ax.plot(d, ser[f"{p}.awgn"], ":", color=col, label=f"{s}: AWGN, −P_LOS")
        if f"{p}.mc" in ser:
            ax.errorbar(
                ser[f"{p}.mc_d0_m"],
                ser[f"{p}.mc"],
                yerr=_Z95 * np.asarray(ser[f"{p}.mc_se"]),
                fmt="o",
                ms=3,
                color=col,
                label=f"{s}: Monte Carlo (95 %: ±{_Z95:.2f} s.e.)",
            )
        b_min = np.asarray(ser[f"{p}.min_bandwidth_hz"], dtype=float)  # JSON null: NaN
        bx.plot(d, b_min / 1e6, color=col, label=s)
        if has_scf and f"{p}.scf" in ser:  # exponential delays only (not the drawn models)
            scf = np.asarray(ser[f"{p}.scf"])
            cx.plot(
                np.asarray(ser[f"{p}.scf_offset_m"]) / unit, scf / scf.max(), color=col, label=s
            )
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xscale("log")
    ax.set_ylim(-1.15, 1.0)
    ax.set_xlabel("LOS distance d0 [m]")
    ax.set_ylabel("CCI / E[A_0 | LOS]  (clipped above 1)")
    ax.set_title(f"Conditional concavity indicator, B = {meta['bandwidth_hz'] / 1e6:.3g} MHz")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=1 if len(meta["scenarios"]) < 3 else 2)
    bx.axhline(meta["bandwidth_hz"] / 1e6, color="k", ls="--", lw=0.8, label="system B")
    bx.set_xscale("log")
    bx.set_yscale("log")
    bx.set_xlabel("LOS distance d0 [m]")
    bx.set_ylabel("minimal bandwidth of (44) [MHz]")
    bx.set_title("Bandwidth that guarantees concavity")
    bx.grid(True, which="both", alpha=0.3)
    bx.legend(fontsize=7)
    if not has_scf:
        save_figure(fig, path)
        return
    cx.set_xlabel("agent displacement Δd [c0/B]")
    cx.set_ylabel("expected SCF / its maximum")
    cx.set_title(f"Expected SCF (35) around the truth, d0 = {meta['distance_m']:g} m")
    cx.grid(True, alpha=0.3)
    cx.legend(fontsize=7)
    save_figure(fig, path)


class CCIExperiment(Experiment):
    """``kind = "cci"``: closed forms per scenario; one Monte Carlo task per (scenario,
    distance)."""

    kind = "cci"
    title = "the conditional concavity indicator of channel scenarios (DiPNet Fig. 2)"
    unit = "Monte Carlo distance"
    spec = CCIExperimentSpec
    task = staticmethod(_mc_task)
    progress_label = "CCI Monte Carlo"
    headers = (
        "scenario",
        "bound < 0 above [m]",
        "exponential < 0 above [m]",
        "MC < 0 above [m]",
        "MC vs exp. max |z|",
        "min B at d [MHz]",
    )

    def prepare(self, recipe, *, fast=False):
        exp = self.experiment_spec(recipe, fast=fast)
        return self.plan(exp.scenarios, recipe.system, exp, "experiment.scenarios")

    @staticmethod
    def plan(scenarios, system, exp, where):
        """``(system, exp, {name: Scenario}, Monte Carlo distances)``, each scenario checked."""
        scns = _load(scenarios, where)
        for scn in scns.values():
            scn.check_frequency(system.carrier_frequency_hz)
        return system, exp, scns, np.geomspace(*exp.d0_range_m, exp.mc_points)

    def tasks(self, plan):
        system, exp, scns, mc_d = plan
        if not exp.links:
            return []
        return [
            ((name, float(d)), (scn, float(d), exp.links, system))
            for name, scn in scns.items()
            for d in mc_d
        ]

    def aggregate(self, plan, keys, results, ctx):
        system, exp, scns, mc_d = plan
        mc = results
        figures, series = {}, {}
        for j, (name, scn) in enumerate(scns.items()):
            c = cci_curves(scn, system, points=exp.points, d0_range_m=exp.d0_range_m)
            p = f"cci.{name}"
            figures[f"{p}.negative_above_m"] = c["negative_above_m"]
            figures[f"{p}.exponential.negative_above_m"] = c["exponential_negative_above_m"]
            at = expected_powers(scn, [exp.distance_m], system)
            figures[f"{p}.min_bandwidth_hz"] = float(min_bandwidth_hz(at)[0])
            for key in ("bound", "exponential", "awgn"):
                figures[f"{p}.{key}_at_max_m"] = float(c[key][-1])
            series.update(
                {
                    f"{p}.d0_m": c["d0_m"],
                    f"{p}.bound": c["bound"],
                    f"{p}.exponential": c["exponential"],
                    f"{p}.awgn": c["awgn"],
                    f"{p}.p_los": c["powers"].p_los,
                    f"{p}.other_power": c["powers"].other_power,
                    f"{p}.min_bandwidth_hz": min_bandwidth_hz(c["powers"]),
                }
            )
            drawn = scn.model in DRAWN_MODELS  # no exponential delays: no App. III, no SCF
            if not drawn:
                offsets = np.linspace(-3.0, 3.0, 121) * C0 / system.bandwidth_hz
                scf = expected_scf(scn, exp.distance_m, np.abs(offsets), system)
                figures[f"{p}.scf_argmax_offset_m"] = float(abs(offsets[np.argmax(scf)]))
                series.update({f"{p}.scf_offset_m": offsets, f"{p}.scf": scf})
            if mc:
                res = np.array(mc[j * exp.mc_points : (j + 1) * exp.mc_points])
                m, se = res[:, 0], res[:, 1]
                pw = expected_powers(scn, mc_d, system)
                z_bound = _z(m - cci_bound(pw, system), se)
                figures[f"{p}.mc.negative_above_m"] = negative_above(mc_d, m)
                if not drawn:
                    z_exp = _z(m - cci_exponential(pw, c["rates"], system), se)
                    figures[f"{p}.mc_z"] = float(np.max(np.abs(z_exp)))
                figures[f"{p}.mc_above_bound_z"] = float(np.max(z_bound))
                series.update({f"{p}.mc_d0_m": mc_d, f"{p}.mc": m, f"{p}.mc_se": se})
        return figures, series

    def meta(self, plan, ctx):
        system, exp, scns, _ = plan
        rates = {
            name: exponential_rates(scn)
            for name, scn in scns.items()
            if scn.model not in DRAWN_MODELS
        }
        return {
            "scenarios": list(scns),
            "bandwidth_hz": system.bandwidth_hz,
            "n_subcarriers": system.n_subcarriers,
            "subcarrier_spacing_hz": system.subcarrier_spacing_hz,
            "carrier_frequency_hz": system.carrier_frequency_hz,
            "links": exp.links,
            "mc_points": exp.mc_points,
            "points": exp.points,
            "d0_range_m": list(exp.d0_range_m),
            "distance_m": exp.distance_m,
            "seed": ctx.seed,
            "rates_per_s": rates,
            "normalization": "expected direct-path power of a LOS link, E[A_0 | LOS]",
        }

    summary_rows = staticmethod(summary_rows)
    summary_lines = staticmethod(summary_lines)
    plot = staticmethod(plot)


CCI = CCIExperiment()
