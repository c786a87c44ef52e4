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
from phyloc.config import Recipe
from phyloc.evaluation._common import experiment_from_dict

SUMMARY_HEADERS = ["figure", "value [c0/B]"]


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
        v.integer("experiment.points", self.points, minimum=2)

    @classmethod
    def from_dict(cls, d: dict, *, fast: bool = False) -> BeliefShiftSpec:
        """From ``[experiment]``; with ``fast`` the ``[experiment.fast]`` values win."""
        return experiment_from_dict(cls, d, fast=fast)


def prepare(recipe: Recipe, *, fast: bool = False):
    """Validate everything :func:`run` reads from ``recipe`` (the ``fast`` setting or the
    full one) and return what it runs; no work is done (``phyloc evaluate`` and
    :func:`phyloc.evaluation.recipes.validate_recipe` call it for both settings first)."""
    return BeliefShiftSpec.from_dict(recipe.section("experiment"), fast=fast)


def run(recipe: Recipe, *, fast: bool = False, workers=None, scheduler=None, progress=True):
    """Run a ``kind = "belief_shift"`` recipe; returns ``{"figures", "series", "meta"}``."""
    exp = prepare(recipe, fast=fast)
    n = recipe.system.n_subcarriers
    res = figure3(exp.nu, n, exp.delta_max, exp.points)
    return {
        "figures": {f"belief_shift.{k}": x for k, x in res["figures"].items()},
        "series": {f"belief_shift.{k}": x for k, x in res["series"].items()},
        "meta": {
            "recipe": recipe.name,
            "kind": recipe.kind,
            "fast": fast,
            "nu": exp.nu,
            "n_subcarriers": n,
            "delta_max": exp.delta_max,
            "points": exp.points,
        },
    }


def summary_rows(results: dict):
    """One row per belief-shift figure."""
    return [(k, x) for k, x in results["figures"].items() if k.startswith("belief_shift.")]


def summary_lines(results: dict):
    """ν and N."""
    m = results["meta"]
    return [f"ν = {m['nu']:g}, N = {m['n_subcarriers']}; δ from 0 to {m['delta_max']:g} c0/B"]


def plot(results: dict, path) -> None:
    """DiPNet Fig. 3 (see :func:`~phyloc.analysis.belief_shift.plot_figure3`)."""
    ser = {k.removeprefix("belief_shift."): x for k, x in results["series"].items()}
    plot_figure3({"series": ser, "figures": {}}, path, results["meta"]["nu"])
