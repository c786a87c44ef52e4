"""Belief shift under a wrong distance (DiPNet §IV-B, Theorems 1–2, Fig. 3)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from phyloc.analysis import belief_shift as bs
from phyloc.cli import main
from phyloc.errors import ValidationError

GRID = np.round(np.arange(0.0, 20.0001, 0.05), 10)


@pytest.mark.parametrize("nu", [0.25, 1.0, 4.0])
def test_shift_below_theorem2_bound_and_one_sample(nu):
    shift, _ = bs.belief_shift(GRID, nu)
    bound = bs.theorem2_bound(GRID, nu)
    assert np.all(shift <= bound + 1e-9), GRID[shift > bound + 1e-9]
    assert np.all(shift < 1.0)
    assert shift[GRID >= 5.0].max() < 0.01  # negligible for large offsets
    two, _ = bs.belief_shift(GRID, nu, model="two_step")
    assert np.all(np.diff(two) > 0) and two[-1] == pytest.approx(20.0 / (1 + nu))


@pytest.mark.parametrize("nu", [0.5, 2.0])
def test_two_step_shift_is_the_gaussian_optimum(nu):
    u = np.linspace(-1, 12, 130001)
    for delta in (0.7, 3.0, 10.0):
        h = bs.log_belief(u, delta, nu, model="two_step")
        assert bs.belief_shift(delta, nu, model="two_step")[0][0] == pytest.approx(
            u[np.argmax(h)], abs=1e-4
        )


@pytest.mark.parametrize("delta", [0.3, 0.65, 1.3, 2.7, 7.45])
def test_ascent_ends_at_the_first_local_maximum(delta):
    """h' = 0 and h'' < 0 at the shift, and h' keeps its sign between the truth and it."""
    x = bs._ascent_maximum(delta, 1.0, bs.DEFAULT_N)

    def h(t):
        return bs.log_belief(t, delta, 1.0)

    e = 1e-5
    assert abs((h(x + e) - h(x - e)) / (2 * e)) < 1e-5
    assert h(x + e) + h(x - e) - 2 * h(x) < 0
    path = np.linspace(0.0, x, 2001)[1:-1]
    d = (h(path + 1e-7) - h(path - 1e-7)) / 2e-7
    assert np.all(np.sign(d) == np.sign(x)) if x != 0 else True


def test_measurement_curvature_at_the_peak_is_one_over_nu():
    """ν = CRB/σ0²: −z''(δ) = 1/ν in units of σ0 (DiPNet (VI.4)), from finite differences of
    the periodic sinc (checks (2π²/3)(N² − 1)/N)."""
    for nu, n in ((1.0, 2569), (0.3, 64)):
        e = 1e-4
        d = 4.2

        def z(t, nu=nu, n=n, d=d):
            return bs.log_belief(t, d, nu, n) + 0.5 * t * t  # remove the prior

        second = (z(d + e) + z(d - e) - 2 * z(d)) / e**2
        assert second == pytest.approx(-1.0 / nu, rel=1e-5)


def test_theorem1_bound_decreases_from_one_sample_to_half():
    rho = bs.theorem1_bound(np.arange(0, 30) + 0.5)
    assert rho[0] == pytest.approx(1.0)
    assert np.all(np.diff(rho) <= 1e-12)
    assert np.all(rho > 0.5) and rho[-1] < 0.51


def test_extreme_offsets_give_finite_numbers():
    shift, glob = bs.belief_shift([0.0, 1e-9, 1e4], 1.0)
    assert np.all(np.isfinite(shift)) and np.all(np.isfinite(glob))
    assert shift[0] == 0.0 and shift[2] < 1e-3


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [({"nu": 0.0}, "nu"), ({"nu": float("nan")}, "nu"), ({"n_subcarriers": 1}, "n_subcarriers")],
)
def test_bad_arguments_name_the_key(kwargs, key):
    with pytest.raises(ValidationError, match=key):
        bs.belief_shift([1.0], **kwargs)
    with pytest.raises(ValidationError, match="delta"):
        bs.belief_shift([float("nan")])


def test_cli_writes_the_figure_names(tmp_path, capsys):
    out = tmp_path / "bs.json"
    png = tmp_path / "bs.png"
    assert main(["analyze", "belief-shift", "--json", str(out), "--png", str(png)]) == 0
    fig = json.loads(out.read_text())["figures"]
    for k in ("max_over_c0_b", "argmax_delta_over_c0_b", "at_10_over_c0_b"):
        assert f"belief_shift.{k}" in fig
    assert fig["belief_shift.two_step_at_10_over_c0_b"] == 5.0
    assert 0 < fig["belief_shift.max_over_c0_b"] < 0.5 and png.stat().st_size > 0
    assert main(["analyze", "belief-shift", "--nu", "-1", "--png", str(tmp_path / "b.png")]) == 2
    assert "nu" in capsys.readouterr().err


def test_recipe_figures_are_exact_without_intervals():
    """No randomness: the recipe's figures are those of the analysis, with no 95 % interval
    keys and no per-unit values (there are no units)."""
    from pathlib import Path

    from phyloc.config import load_recipe
    from phyloc.evaluation.belief_shift_experiment import BELIEF_SHIFT

    recipe = load_recipe(Path(__file__).parents[1] / "datasets" / "dipnet_fig3_belief_shift.toml")
    res = BELIEF_SHIFT.run(recipe, fast=True, progress=False)
    f = res["figures"]
    assert not [k for k in f if k.endswith((".ci_low", ".ci_high", ".ratio"))]
    assert not [k for k in res["series"] if k.endswith(".units")]
    assert f["belief_shift.two_step_at_10_over_c0_b"] == 10.0 / (1.0 + 1.0)  # δ/(1 + ν), ν = 1
    ref = bs.figure3(1.0, recipe.system.n_subcarriers, 20.0, 81)["figures"]
    assert f == {f"belief_shift.{k}": x for k, x in ref.items()}
