"""Confidence intervals of Monte Carlo figures (phyloc.evaluation.statistics)."""

import math

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.evaluation.statistics import (
    Paired,
    Pooled,
    interval,
    paired_interval,
    ratio_interval,
    resolve,
    units_of,
    verdict,
)


def test_pooled_values_are_the_pooled_figures():
    errs = [np.array([1.0, 2.0]), np.array([3.0]), np.array([4.0])]
    p = Pooled.rmse(errs)
    assert p.value == pytest.approx(math.sqrt((1 + 4 + 9 + 16) / 4))
    assert list(p.den) == [2, 1, 1]
    assert math.isnan(Pooled.rmse([*errs, [np.nan]]).value)  # a failure is not averaged away
    m = Pooled.mean([[1.0, 3.0], 5.0])
    assert m.value == pytest.approx(3.0)
    f = Pooled.fraction([[True, False, False], [True]])
    assert f.value == pytest.approx(0.5)


def test_clopper_pearson_closed_forms():
    # k = 0 of n: [0, 1 − (α/2)^(1/n)]; k = n: [(α/2)^(1/n), 1]
    n = 17
    lo, hi = interval(Pooled.fraction([np.zeros(n, bool)]))
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / n), rel=1e-9)
    lo, hi = interval(Pooled.fraction([np.ones(5, bool), np.ones(12, bool)]))
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / n), rel=1e-9)


def test_mean_interval_covers_the_truth_about_95_percent():
    rng = np.random.default_rng(20261127)
    hits, n_rep = 0, 300
    for r in range(n_rep):
        x = rng.normal(2.0, 1.0, size=40)
        lo, hi = interval(Pooled.mean(list(x)), seed=r, name="m")
        hits += lo <= 2.0 <= hi
    # binomial(300, 0.95): 0.91–0.98 holds with probability > 0.999
    assert 0.91 <= hits / n_rep <= 0.98


def test_rmse_interval_covers_the_truth_and_shrinks_with_units():
    rng = np.random.default_rng(11)
    hits, widths = 0, {}
    for r in range(200):
        units = [rng.normal(0.0, 0.5, size=rng.integers(5, 15)) for _ in range(30)]
        lo, hi = interval(Pooled.rmse(units), seed=r, name="e")
        hits += lo <= 0.5 <= hi
    assert 0.89 <= hits / 200 <= 0.99
    for n in (10, 160):
        units = [rng.normal(0.0, 0.5, size=8) for _ in range(n)]
        lo, hi = interval(Pooled.rmse(units), seed=1, name="e")
        widths[n] = hi - lo
    assert widths[160] < 0.5 * widths[10]  # ~1/sqrt(16) = 0.25 expected


def test_paired_ratio_exact_when_one_figure_scales_the_other():
    rng = np.random.default_rng(5)
    e = [rng.normal(size=10) for _ in range(25)]
    a, b = Pooled.rmse(e), Pooled.rmse([2.0 * x for x in e])
    lo, hi = paired_interval(Paired(a, b))
    assert Paired(a, b).value == pytest.approx(0.5)
    assert lo == pytest.approx(0.5) and hi == pytest.approx(0.5)


def test_pairing_narrows_the_ratio_interval():
    """Two methods sharing most of their error per realization: the paired interval of the
    ratio is far narrower than one from independently resampled units."""
    rng = np.random.default_rng(8)
    common = [rng.gamma(2.0, 1.0) * rng.normal(size=20) for _ in range(40)]
    a = Pooled.rmse([0.9 * c + 0.05 * rng.normal(size=20) for c in common])
    b = Pooled.rmse(common)
    lo, hi = paired_interval(Paired(a, b), seed=3, name="r")
    truth = math.sqrt(0.81 + 0.05**2 / 6.0)  # E[c²] = E[gamma(2, 1)²] = 6
    assert lo < truth < hi and hi - lo < 0.05
    # unpaired: the ratio of two independent bootstraps (brute force)
    ia, ib = rng.integers(0, 40, (2, 2000, 40))
    ra = np.sqrt(a.num[ia].sum(1) / a.den[ia].sum(1))
    rb = np.sqrt(b.num[ib].sum(1) / b.den[ib].sum(1))
    q = np.quantile(ra / rb, [0.025, 0.975])
    assert q[1] - q[0] > 5 * (hi - lo)
    assert verdict(lo, hi, claim="<") == "holds"


def test_intervals_are_reproducible_and_nan_without_units():
    p = Pooled.rmse([np.arange(3.0) + k for k in range(6)])
    assert interval(p, seed=4, name="x") == interval(p, seed=4, name="x")
    assert all(math.isnan(v) for v in interval(Pooled.rmse([np.ones(4)])))
    assert all(math.isnan(v) for v in interval(Pooled.rmse([[], []])))
    assert interval(Pooled.rmse([np.ones(2), np.ones(3)])) == (1.0, 1.0)


def test_a_figure_is_the_same_bits_for_any_order_of_its_units():
    rng = np.random.default_rng(11)
    num, den = rng.lognormal(0, 3, 12), rng.integers(1, 9, 12).astype(float)
    for kind in ("rmse", "mean"):
        ref = Pooled(num, den, kind).value
        for _ in range(20):
            perm = rng.permutation(12)
            assert Pooled(num[perm], den[perm], kind).value == ref


def test_interval_ends_follow_the_data_not_their_last_bits():
    """Eight heavy-tailed units (one 1e5 times the others): changing every unit by ~3e-9
    relative moves an interval end by about as much. With the units summed in their resampled
    order, a resample that permutes the units fell on either side of the figure by rounding,
    BCa's bias count changed by one, and lower ends jumped by up to 20 % (trials 6 and 23)."""
    rng = np.random.default_rng(7)
    worst = 0.0
    for trial in range(40):
        num = rng.lognormal(0, 1, 8)
        num[0] *= 1e5
        den = np.ones(8)
        moved = num * (1 + 3e-9 * rng.normal(size=8))
        a = interval(Pooled(num, den, "mean"), seed=3605, name=f"t{trial}")
        b = interval(Pooled(moved, den, "mean"), seed=3605, name=f"t{trial}")
        worst = max(worst, *(abs(y - x) / abs(x) for x, y in zip(a, b, strict=True)))
    assert worst < 1e-6


def test_resolve_writes_values_intervals_and_units():
    a = Pooled.rmse([[1.0, 2.0], [0.5], [3.0, 1.0]])
    b = Pooled.rmse([[2.0, 2.0], [1.0], [3.0, 2.0]])
    figs, ser = resolve({"t": 1.5, "a": a, "b": b, "a_vs_b": Paired(a, b)}, {"s": [1]}, seed=9)
    assert list(figs)[:4] == ["t", "a", "a.ci_low", "a.ci_high"]
    assert figs["a"] == a.value and figs["a_vs_b.ratio"] == pytest.approx(a.value / b.value)
    assert figs["a.ci_low"] <= figs["a"] <= figs["a.ci_high"]
    assert "a_vs_b.ratio.ci_low" in figs and ser["s"] == [1]
    back = units_of(ser, "a")
    assert back.value == a.value and units_of(ser, "nothing") is None
    assert units_of(ser, "a").kind == "rmse"


def test_a_paired_figure_can_keep_its_own_name():
    """A ratio by definition (an RMSE over its bound) is written under its name, not
    ``.ratio``, with the same paired interval."""
    rng = np.random.default_rng(12)
    a = Pooled.rmse([rng.normal(size=4) for _ in range(30)])
    b = Pooled(rng.uniform(0.5, 1.5, 30), np.ones(30), "rmse")
    figs, _ = resolve({"r": Paired(a, b, suffix="")}, {}, seed=2)
    assert set(figs) == {"r", "r.ci_low", "r.ci_high"}
    assert figs["r"] == pytest.approx(a.value / b.value)
    lo, hi = paired_interval(Paired(a, b), seed=2, name="r")
    assert (figs["r.ci_low"], figs["r.ci_high"]) == (lo, hi) and lo < figs["r"] < hi


def test_unpaired_ratio_interval_matches_brute_force():
    """Figures of different units (network sizes): each resampled on its own; the BCa
    interval is close to the brute-force percentile interval of the ratio."""
    rng = np.random.default_rng(21)
    a = Pooled.rmse([rng.normal(0, 1.0, 10) for _ in range(60)])
    b = Pooled.rmse([rng.normal(0, 2.0, 10) for _ in range(60)])
    lo, hi = ratio_interval(a, b, paired=False, seed=2, name="u")
    ia, ib = rng.integers(0, 60, (2, 4000, 60))
    q = np.quantile(
        np.sqrt(a.num[ia].sum(1) / a.den[ia].sum(1)) / np.sqrt(b.num[ib].sum(1) / b.den[ib].sum(1)),
        [0.025, 0.975],
    )
    assert lo < 0.5 < hi
    assert abs(lo - q[0]) < 0.02 and abs(hi - q[1]) < 0.02


def test_verdicts():
    assert verdict(0.1, 0.2, claim=">", value=0.05) == "holds"
    assert verdict(0.01, 0.04, claim=">", value=0.05) == "differs"
    assert verdict(math.nan, 1.0, claim="<") == "undecided"
    assert verdict(1.02, 1.08, claim="=", tolerance=0.1) == "holds"
    with pytest.raises(ValidationError):
        verdict(0, 1, claim="~")


def test_bad_units_are_rejected():
    with pytest.raises(ValidationError, match=r"Pooled\.den"):
        Pooled([1.0, 2.0], [1.0])
    with pytest.raises(ValidationError, match=r"Pooled\.kind"):
        Pooled([1.0], [1.0], "median")
    with pytest.raises(ValidationError, match=r"Paired\.b"):
        Paired(Pooled.rmse([[1.0]]), Pooled.rmse([[1.0], [2.0]]))


# -- quantiles of values pooled over units (cluster bootstrap) --------------------------------
def test_quantile_point_is_the_inverted_cdf_quantile_of_all_values():
    from phyloc.evaluation.statistics import Quantile

    rng = np.random.default_rng(4)
    units = [rng.exponential(1.0, 7 + i) for i in range(9)]
    pooled = np.sort(np.concatenate(units))
    for q in (0.5, 0.8, 0.9):
        k = math.ceil(q * pooled.size) - 1  # the smallest value whose ECDF reaches q
        assert Quantile(units, q).value == pooled[k]
    with pytest.raises(ValidationError, match=r"Quantile\.q"):
        Quantile(units, 1.0)
    assert all(math.isnan(x) for x in Quantile([units[0]], 0.5).interval())  # one unit


@pytest.mark.slow
def test_quantile_interval_covers_the_true_quantile_of_clustered_values():
    """Errors of one realization share its conditions: unit i's values are ``(1 + u_i)·e``,
    ``u_i ~ U(0, 1)``, ``e ~ Exp(1)``. Over 300 experiments of 30 units x 20 values the 95 %
    interval of the 90 % point covers the true one (by numerical inversion of the mixture's
    CDF) in 0.95 ± 3.5 s.e. of the trials."""
    from scipy.optimize import brentq

    from phyloc.evaluation.statistics import Quantile

    def cdf(x):  # P[(1+u) e <= x] = 1 - E[exp(-x/(1+u))], u ~ U(0, 1)
        u = (np.arange(4000) + 0.5) / 4000
        return 1.0 - np.mean(np.exp(-x / (1.0 + u)))

    truth = brentq(lambda x: cdf(x) - 0.9, 0.1, 20.0)
    rng = np.random.default_rng(90)
    hits, trials = 0, 300
    for t in range(trials):
        units = [(1.0 + rng.uniform()) * rng.exponential(1.0, 20) for _ in range(30)]
        lo, hi = Quantile(units, 0.9).interval(seed=t, name="p90")
        hits += lo <= truth <= hi
    se = math.sqrt(0.95 * 0.05 / trials)
    assert abs(hits / trials - 0.95) < 3.5 * se, hits / trials
