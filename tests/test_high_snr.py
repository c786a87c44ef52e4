"""Accuracy does not fall as the SNR rises (two-step filters on NLOS-biased ranges).

A range estimator's model variance (its ZZB at the estimated SNR) is thermal: it vanishes as
the transmit power grows while an NLOS bias (~90 m in WINNER II C2) does not. With the plain
Gaussian likelihood of DiPNet §V-A a biased range then becomes certain and the two-step
filter's error grows with the power; the per-link evidence bound (``outlier_nats``) and the
range model error (``model_error_m``) keep it from doing so.

In a 5-agent network that is not enough: 10 pairs leave 3 distances beyond the 7 degrees of
freedom, and at high power every NLOS pair is detected (at 0 dBm most are too weak to pass the
detection test, which then acts as an NLOS filter). There the NLOS identification from the
waveform (``los_min_concentration``: the correlation's energy concentration, which grows more
reliable with the SNR) and the one-sided robust start (NLOS biases are positive) keep the
error flat, and DiPNet's evidence bound survives peak heights of 1e20 nats (+200 dBm).
"""

import pytest

from phyloc.config import load_recipe
from phyloc.evaluation import localization_experiment as lx

RECIPE = """
kind = "localization"
name = "high_snr"
seed = 11
[system]
n_subcarriers = 2569
subcarrier_spacing_hz = 14.65e3
tx_power_dbm = {power}
[network]
region_m = [100.0, 100.0]
[channel]
nlos_bias_mean_s = 3.0e-7
[ranging]
window_m = [0.0, 300.0]
[localization]
n_particles = 500
n_iterations = 8
model_error_m = 0.3
{extra}
[experiment]
scenarios = {{ c2 = "winner2_c2" }}
agents = [12]
realizations = 3
methods = ["corr"]
inits = ["informed"]
cdf_agents = [12]
"""
PLAIN = "[localization.corr]\noutlier_nats = inf\nmodel_error_m = 0.0\n"


def _rmse(power, extra=""):
    res = lx.LOCALIZATION.run(load_recipe(RECIPE.format(power=power, extra=extra)), progress=False)
    return res["figures"]["corr.c2_informed.agents_12.framework_rmse_m"]


SMALL = (
    RECIPE.replace("agents = [12]", "agents = [5]")
    .replace("cdf_agents = [12]", "cdf_agents = [5]")
    .replace("realizations = 3", "realizations = 8")
    .replace('methods = ["corr"]', 'methods = ["dipnet", "corr"]')
    .replace('inits = ["informed"]', 'inits = ["truth_free", "informed"]')
)


@pytest.mark.slow
def test_small_network_error_does_not_grow_with_the_transmit_power(monkeypatch):
    """5 agents, C2, 0 / +60 / +200 dBm, the same networks and draws: no method's RMSE rises by
    more than 15 % (the spread of these 8-network means). Before the NLOS identification the
    informed two-step error doubled at +60 dBm and DiPNet's tripled at +200 dBm.

    Truth-free, the RMSE is taken over the pairs the detected links determine
    (``framework_rmse_observable_m``): 5–6 % of the pairs are left undetermined at every power,
    their nodes land on one of their mirror positions by chance, and in these 8 networks that
    chance alone moves the all-pairs RMSE from 5.9 m (0 dBm) to 16.5 m (+60 dBm) while the
    determined pairs go from 6.0 to 3.2 m (over 20 networks the all-pairs RMSE is flat, 12.6 /
    12.8 / 12.7 m; docs/guide/experiments.rst). The informed start constrains every pair, so
    there the RMSE is over all pairs."""
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    figs = {
        p: lx.LOCALIZATION.run(load_recipe(SMALL.format(power=p, extra="")), progress=False)[
            "figures"
        ]
        for p in (0.0, 60.0, 200.0)
    }
    keys = [
        f"{method}.{key}"
        for method in ("dipnet", "corr")
        for key in (
            "c2.agents_5.framework_rmse_observable_m",
            "c2_informed.agents_5.framework_rmse_m",
        )
    ]
    for key in keys:
        low = figs[0.0][key]
        for p in (60.0, 200.0):
            assert figs[p][key] <= 1.15 * low, (key, p, figs[p][key], low)


@pytest.mark.slow
def test_two_step_error_does_not_grow_with_the_transmit_power(monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    bounded_0, bounded_60 = _rmse(0.0), _rmse(60.0)
    plain_60 = _rmse(60.0, PLAIN)
    # one seed: the same networks, channel draws and priors in every run
    assert bounded_60 <= bounded_0
    assert plain_60 > 3.0 * bounded_60  # the plain Gaussian at +60 dBm: certain biased ranges
