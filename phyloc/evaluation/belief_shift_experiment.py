"""DiPNet Fig. 3 as a recipe: the belief shift under a distance offset, DiPNet against two-step.

A recipe of ``kind = "belief_shift"`` evaluates :func:`phyloc.analysis.belief_shift.figure3`
for ``experiment.nu`` (ν = CRB/σ0², DiPNet Fig. 3: 1) and the recipe's ``N``
(``system.n_subcarriers``) on ``points`` offsets δ in ``[0, delta_max]`` (units of c0/B), the
same computation as ``phyloc analyze belief-shift``. No randomness: the seed is unused.

Figures (all in units of the sample distance c0/B)::

    belief_shift.max_over_c0_b              largest DiPNet shift over δ
    belief_shift.argmax_delta_over_c0_b     the δ where it occurs
    belief_shift.at_10_over_c0_b            DiPNet shift at δ = 10
    belief_shift.max_10_to_11_over_c0_b     largest DiPNet shift for δ in [10, 11]
    belief_shift.two_step_at_10_over_c0_b   the Gaussian two-step shift at δ = 10
    belief_shift.bound_violations           grid points where the shift exceeds Theorem 2

Series ``belief_shift.<curve>`` over ``belief_shift.delta``: ``dipnet`` (ascent from the
truth), ``dipnet_global``, ``bound`` (Theorem 2), ``theorem1``, ``two_step``.

Every figure is an exact computation (no tasks, no Monte Carlo units): none has ``.ci_low`` /
``.ci_high`` keys (:mod:`~phyloc.evaluation.statistics`).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

from dataclasses import dataclass

from phyloc import _validate as v
from phyloc.analysis.belief_shift import figure3, plot_figure3
from phyloc.evaluation.experiment import Experiment


@dataclass(frozen=True)
class BeliefShiftSpec:
    """``[experiment]`` of a ``belief_shift`` recipe.

    Parameters
    ----------
    nu : float
        ν = CRB/σ0² (> 0); DiPNet Fig. 3 uses 1.
    delta_max : float
        Largest offset δ [c0/B] (> 0).
    points : int
        Offsets on the grid (>= 2).
    """

    nu: float = 1.0
    delta_max: float = 20.0
    points: int = 401

    def __post_init__(self):
        v.positive("experiment.nu", self.nu)
        v.positive("experiment.delta_max", self.delta_max)
        v.integer_field(self, "points", "experiment.points", minimum=2)


class BeliefShiftExperiment(Experiment):
    """``kind = "belief_shift"``: closed-form curves, no tasks (the seed is unused)."""

    kind = "belief_shift"
    title = "the belief shift under a distance offset, DiPNet against two-step (DiPNet Fig. 3)"
    spec = BeliefShiftSpec
    headers = ("figure", "value [c0/B]")

    def prepare(self, recipe, *, fast=False):
        return self.experiment_spec(recipe, fast=fast), recipe.system.n_subcarriers

    def tasks(self, plan):
        return []

    def aggregate(self, plan, keys, results, ctx):
        exp, n = plan
        res = figure3(exp.nu, n, exp.delta_max, exp.points)
        return (
            {f"belief_shift.{k}": x for k, x in res["figures"].items()},
            {f"belief_shift.{k}": x for k, x in res["series"].items()},
        )

    def meta(self, plan, ctx):
        exp, n = plan
        return {"nu": exp.nu, "n_subcarriers": n, "delta_max": exp.delta_max, "points": exp.points}

    def summary_rows(self, results):
        """One row per belief-shift figure."""
        return [(k, x) for k, x in results["figures"].items() if k.startswith("belief_shift.")]

    def summary_lines(self, results):
        """ν and N."""
        m = results["meta"]
        return [f"ν = {m['nu']:g}, N = {m['n_subcarriers']}; δ from 0 to {m['delta_max']:g} c0/B"]

    def plot(self, results, path):
        """DiPNet Fig. 3 (see :func:`~phyloc.analysis.belief_shift.plot_figure3`)."""
        ser = {k.removeprefix("belief_shift."): x for k, x in results["series"].items()}
        plot_figure3({"series": ser, "figures": {}}, path, results["meta"]["nu"])


BELIEF_SHIFT = BeliefShiftExperiment()
