"""The recipe sections every experiment shares, parsed in one place.

* ``[system]`` is :class:`~phyloc.phy.OFDMSystem` (read by :func:`phyloc.config.load_recipe`);
* ``[channel]`` is :class:`~phyloc.channels.ChannelSpec`, one per scenario token of
  ``experiment.scenarios`` (:func:`scenario_specs`);
* ``[network]`` is :class:`~phyloc.network.NetworkSpec`, one per network size
  (:func:`network_specs`);
* ``[ranging]`` is :class:`RangingSpec`: the range estimators and their options;
* ``[localization]`` is :class:`LocalizationSpec`: the direct family's options, the priors of
  the experiments and one sub-table per method.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.errors import ValidationError
from phyloc.evaluation.methods import check_labels, method_plan
from phyloc.localization import DirectOptions
from phyloc.localization.initialization import PAIR_COMBINE, SOLVERS
from phyloc.network import NetworkSpec
from phyloc.phy import C0, OFDMSystem, PathSet
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols
from phyloc.ranging import estimate
from phyloc.ranging.estimators import ESTIMATORS, ORACLES
from phyloc.ranging.nlos import check_min_concentration


def scenario_specs(channel, scenarios: dict) -> dict:
    """One channel spec per scenario token (``{token: scenario name}``), each loaded once so
    that a bad name fails before any work starts."""
    specs = {tok: dataclasses.replace(channel, scenario=name) for tok, name in scenarios.items()}
    for tok, spec in specs.items():
        try:
            spec.load()
        except ValidationError as exc:
            raise ValidationError(f"experiment.scenarios.{tok}", exc.value, exc.allowed) from None
    return specs


def network_specs(network: dict, sizes) -> dict:
    """``{n: NetworkSpec}``: the ``[network]`` table with ``n_agents = n`` for every size, each
    validated before any work starts."""
    return {n: NetworkSpec.from_dict({**network, "n_agents": n}) for n in sizes}


RANGING_METHODS = ("corr", "first_peak", "sage", "sage_los")
"""The range estimators a ``[ranging]`` section may name (``sage_los``: an oracle)."""


@dataclass(frozen=True)
class RangingSpec:
    """``[ranging]``: estimators and their options.

    ``methods`` from ``corr``, ``first_peak``, ``sage``, ``sage_los`` (oracle: SAGE on LOS links
    only); ``beta`` the table interpolation factor; ``window_m`` the distance search window;
    ``variance`` the ranging-variance model (``zzb`` or ``crb``); ``prior_range_m`` the ZZB's
    a-priori distance interval; per-method option tables ``[ranging.<method>]``.
    """

    methods: tuple = ("corr", "sage")
    beta: float = 8.0
    window_m: tuple = (0.0, 300.0)
    variance: str = "zzb"
    prior_range_m: float = 150.0
    options: dict = field(default_factory=dict)

    def __post_init__(self):
        methods = check_labels(self.methods, "ranging.methods")
        if not methods:
            raise ValidationError("ranging.methods", [], f"at least one of {RANGING_METHODS}")
        for m in methods:
            if m not in RANGING_METHODS:
                raise ValidationError(
                    "ranging.methods", m, f"each one of {', '.join(RANGING_METHODS)}"
                )
        object.__setattr__(self, "methods", methods)
        b = v.positive("ranging.beta", self.beta)
        if b < 1:
            raise ValidationError("ranging.beta", self.beta, ">= 1")
        w = tuple(float(x) for x in self.window_m)
        if len(w) != 2 or not w[0] < w[1]:
            raise ValidationError("ranging.window_m", self.window_m, "[lo, hi] with lo < hi [m]")
        object.__setattr__(self, "window_m", w)
        if self.variance not in ("zzb", "crb"):
            raise ValidationError("ranging.variance", self.variance, "'zzb' or 'crb'")
        v.positive("ranging.prior_range_m", self.prior_range_m)
        for m, opts in self.options.items():
            _check_estimator_options(m, opts, self.method_options(m))

    @classmethod
    def from_dict(cls, d: dict) -> RangingSpec:
        """From the ``[ranging]`` table; sub-tables named after methods are their options."""
        d = dict(d)
        options = {m: d.pop(m) for m in list(d) if m in RANGING_METHODS and isinstance(d[m], dict)}
        check_keys(d, ["methods", "beta", "window_m", "variance", "prior_range_m"], "ranging")
        v.check_types(cls, d, "ranging")
        return cls(**d, options=options)

    def method_options(self, method: str) -> dict:
        """Keyword options of one estimator."""
        base = {"window_m": self.window_m, "variance": self.variance}
        if self.variance == "zzb":
            base["prior_range_m"] = self.prior_range_m
        key = "sage" if method == "sage_los" else method
        return {**base, **self.options.get(key, {})}


def _check_estimator_options(method: str, own: dict, merged: dict) -> None:
    """Validate ``[ranging.<method>]`` before any work: its keys against the estimator's
    keyword options, then every value by a dry run of the estimator on a one-link table
    (the estimator's own checks, its error renamed to the recipe key)."""
    import inspect

    fn = ESTIMATORS[ORACLES.get(method, method)]
    params = inspect.signature(fn).parameters.values()
    check_keys(own, [p.name for p in params if p.kind is p.KEYWORD_ONLY], f"ranging.{method}")
    if "window_m" not in own:  # the recipe's window was checked above, for its own system
        merged = {**merged, "window_m": (0.0, 300.0)}
    try:
        estimate(method, _dry_run_table(), los=np.ones(1, bool), **merged)
    except ValidationError as err:
        raise ValidationError(f"ranging.{method}.{err.field}", err.value, err.allowed) from None
    except TypeError as err:  # a value of the wrong kind the estimator's checks did not name
        raise ValidationError(f"ranging.{method}", own, f"options of {method}: {err}") from None


@functools.lru_cache(maxsize=1)
def _dry_run_table():
    """A one-link correlation table: 2049 subcarriers at 10 kHz (30 km unambiguous range),
    β = 4 (a 3.7 m grid)."""
    system = OFDMSystem(n_subcarriers=2049, subcarrier_spacing_hz=1.0e4)
    rng = np.random.default_rng(0)
    S = qpsk_symbols(system, 1, rng)
    R = synthesize(PathSet.single_path([40.0 / C0], [1e-6]), S, system, rng)
    return correlation_tables(R, S, system, beta=4.0)


PRIOR_KEYS = (
    "prior_std_m",
    "informed_std_m",
    "gauge_extent_m",
    "init_pair_range",
    "init_robust_scale_m",
    "init_restarts",
    "init_one_sided",
    "init_solver",
    "los_min_concentration",
)
"""``[localization]`` keys of the experiment's priors; every other key is a method option."""


@dataclass(frozen=True)
class LocalizationSpec:
    """``[localization]``: the methods' options and the experiment's priors.

    ``prior_std_m`` std of the truth-free Gaussian priors around the coarse solution [m], or
    ``"start"`` (the default): per agent, the start's own accuracy estimate
    (:func:`~phyloc.localization.initialization.start_scale` with ``position=True``: the
    robust scale of the agent's range residuals against the start, as a position std through
    the CRB form of its measured directions), at least
    :data:`~phyloc.evaluation.front_end.START_PRIOR_FLOOR_M` and at most
    :data:`~phyloc.evaluation.front_end.START_PRIOR_FALLBACK_M`, which agents the start cannot
    place get);
    ``informed_std_m`` σ0 of the informed start [m]; ``gauge_extent_m`` half-width of the
    uniform gauge priors [m]; ``init_pair_range`` (``"min"``, or ``"mean"``) how the
    truth-free start combines the two directions' correlation ranges of a pair and
    ``init_robust_scale_m`` (default ``[5.0, 2.0, 1.0]``; a number for one scale; 0: plain
    SMACOF) the Cauchy scales of its robust reweighting, the configuration with the lowest
    cost at the smallest scale winning, ``init_restarts`` (default 10) the random SMACOF
    starts it adds to the MDS start, the lowest robust cost winning, and ``init_one_sided``
    (default true) whether the reweighting spares ranges shorter than the fitted distance
    (NLOS biases are positive: a short range is noise, a long one may be biased), and
    ``init_solver`` (``"auto"``, default: ``"dense"`` up to
    :data:`~phyloc.localization.initialization.SPARSE_ABOVE_NODES` nodes, ``"sparse"`` above;
    or either by name) whether it solves on ``n × n`` matrices or on the measured pairs only
    (:func:`~phyloc.localization.initialization.coarse_positions`).
    ``los_min_concentration`` (default 0.6; 0: off) is the NLOS identification: a link whose
    correlation has an energy concentration below it
    (:func:`~phyloc.ranging.nlos.energy_concentration`, 1 for one path) is left out of the
    start and of every method's likelihood (``LinkMeasurements.usable``). Every other
    key is an option of the direct family (:class:`~phyloc.localization.DirectOptions`: the
    :class:`~phyloc.localization.DPFOptions` fields, ``outlier_nats`` …), kept as written in
    ``options``, shared by every method whose options have them; a subtable
    ``[localization.<label>]`` (``method_options``) holds one label's options and, for a label
    that is not a registered name, ``method = "<registered name>"`` (:meth:`plan`, the method
    grammar of every kind: :mod:`phyloc.evaluation.methods`).
    """

    options: dict = field(default_factory=dict)
    prior_std_m: float | str = "start"
    informed_std_m: float = 10.0
    gauge_extent_m: float = 150.0
    method_options: dict = field(default_factory=dict)
    init_pair_range: str = "min"
    init_robust_scale_m: tuple = (5.0, 2.0, 1.0)
    init_restarts: int = 10
    init_one_sided: bool = True
    init_solver: str = "auto"
    los_min_concentration: float = 0.6

    def __post_init__(self):
        std = self.prior_std_m
        if std != "start" and (isinstance(std, bool) or not isinstance(std, int | float)):
            raise ValidationError("localization.prior_std_m", std, 'a std > 0 [m], or "start"')
        if std != "start":
            v.positive("localization.prior_std_m", std)
        v.choice("localization.init_pair_range", self.init_pair_range, PAIR_COMBINE)
        raw = self.init_robust_scale_m
        scales = tuple(
            v.positive("localization.init_robust_scale_m", c, allow_zero=True)
            for c in ((raw,) if np.ndim(raw) == 0 else raw)
        )
        if not scales or (0.0 in scales and len(scales) > 1):
            raise ValidationError(
                "localization.init_robust_scale_m", raw, "scales > 0 [m], or 0 (plain SMACOF)"
            )
        object.__setattr__(self, "init_robust_scale_m", scales)
        v.integer_field(self, "init_restarts", "localization.init_restarts", minimum=0)
        v.choice("localization.init_solver", self.init_solver, SOLVERS)
        check_min_concentration(self.los_min_concentration, "localization.los_min_concentration")
        v.positive("localization.informed_std_m", self.informed_std_m)
        v.positive("localization.gauge_extent_m", self.gauge_extent_m)
        object.__setattr__(self, "options", dict(self.options))
        object.__setattr__(self, "method_options", dict(self.method_options))
        DirectOptions.from_dict(self.options, "localization")  # names a bad key or value
        self.plan(())  # every [localization.<label>] table, before any work

    def plan(self, labels) -> dict:
        """``{label: (registered name, options)}`` of the direct-family labels ``labels``
        (:func:`~phyloc.evaluation.methods.method_plan`: shared keys, then the label's table;
        the shared keys are checked against :class:`~phyloc.localization.DirectOptions`)."""
        table = {**self.options, **self.method_options}
        return method_plan(table, tuple(labels), "direct", check_shared=False)

    @classmethod
    def from_dict(cls, d: dict) -> LocalizationSpec:
        """From ``[localization]``: the prior keys, the direct family's option keys and the
        per-method subtables."""
        d = dict(d)
        own = {k: d.pop(k) for k in PRIOR_KEYS if k in d}
        scale = own.get("init_robust_scale_m")
        if isinstance(scale, int | float) and not isinstance(scale, bool):
            own["init_robust_scale_m"] = [scale]  # one scale, written as a number
        # prior_std_m: a number or "start", checked by __post_init__
        v.check_types(cls, {k: x for k, x in own.items() if k != "prior_std_m"}, "localization")
        sub = {k: d.pop(k) for k in list(d) if isinstance(d[k], dict)}
        return cls(options=d, method_options=sub, **own)

    def options_for(self, label: str):
        """The options of ``label`` (a registered name, or a label with a ``method`` key)."""
        return self.plan((label,))[label][1]

    @property
    def dpf(self):
        """The filter options written in the recipe (``n_particles`` of the priors, meta)."""
        return DirectOptions.from_dict(self.options, "localization").dpf
