"""Confidence intervals of Monte Carlo figures, computed from their per-unit values.

An experiment's task is one *unit* (a realization, a run, a trial block). A figure pooled over
units is declared in an aggregation as a :class:`Pooled` value instead of a number: per unit a
numerator and a denominator (the sum of squared errors and the number of errors; the sum of
values and their number; the successes and the trials), and how they combine::

    kind        figure                     95 % interval
    "rmse"      sqrt(Σ num / Σ den)        bootstrap over units (BCa)
    "mean"      Σ num / Σ den              bootstrap over units (BCa)
    "fraction"  Σ num / Σ den              exact binomial (Clopper–Pearson) on the totals

A quantile of values pooled over units (the 50 / 80 / 90 % points of an error CDF) is a
:class:`Quantile` value: its interval comes from the cluster bootstrap, which resamples whole
units and takes the quantile of their pooled values (percentile interval).

A comparison of two figures over the *same* units (methods run on the same realizations) is a
:class:`Paired` value: the ratio of the two figures, with its interval from the bootstrap that
resamples the same units for both (a paired bootstrap).

:func:`resolve` (called once by the runner,
:meth:`~phyloc.evaluation.experiment.Experiment.execute`) turns them into plain figures:
``<name>`` (the point value), ``<name>.ci_low`` and ``<name>.ci_high`` in ``figures``, and the
per-unit values ``<name>.units`` (``{"kind", "num", "den"}``) in ``series``; a
paired ratio is written as ``<name>.ratio`` (or under its own name, :attr:`Paired.suffix`) and its
interval. The bootstrap's stream is derived
from the run's seed and the figure's name, so the same results give the same intervals however
many workers ran the tasks. With fewer than two units (or none that count), the interval is
NaN: nothing can be said about its width.

:func:`verdict` reads an interval against a claimed value: ``holds``, ``differs`` or
``undecided``.

References
----------
B. Efron, "Better bootstrap confidence intervals," J. American Statistical Association 82(397),
pp. 171–185, 1987 (BCa; :func:`scipy.stats.bootstrap`). C. J. Clopper and E. S. Pearson, "The
use of confidence or fiducial limits illustrated in the case of the binomial," Biometrika
26(4), pp. 404–413, 1934.
"""

from __future__ import annotations

import math
import warnings
import zlib
from dataclasses import dataclass

import numpy as np
from scipy import stats

from phyloc.errors import ValidationError

#: Confidence level of every interval.
CONFIDENCE = 0.95
#: Bootstrap resamples per interval.
N_RESAMPLES = 2000
#: The kinds of a :class:`Pooled` figure.
KINDS = ("rmse", "mean", "fraction")
#: The verdicts of :func:`verdict`.
VERDICTS = ("holds", "differs", "undecided")


@dataclass(frozen=True)
class Pooled:
    """A figure pooled over units, with its per-unit numerator and denominator.

    Parameters
    ----------
    num, den : [n_units] float
        Per unit: the numerator and the denominator of the pooled figure (``den >= 0``; a unit
        with ``den == 0`` contributes nothing but still counts as a unit).
    kind : str
        ``"rmse"``, ``"mean"`` or ``"fraction"`` (see the module).
    point : float, optional
        The point value as the experiment computes it over all units' values at once (set by
        :meth:`at`); None: pooled from ``num`` and ``den``.
    """

    num: np.ndarray
    den: np.ndarray
    kind: str = "rmse"
    point: float | None = None

    def __post_init__(self):
        num = np.asarray(self.num, dtype=np.float64).ravel()
        den = np.asarray(self.den, dtype=np.float64).ravel()
        if num.shape != den.shape:
            raise ValidationError("Pooled.den", f"{den.size} units", f"{num.size} (as num)")
        if self.kind not in KINDS:
            raise ValidationError("Pooled.kind", self.kind, ", ".join(KINDS))
        if np.any(den < 0) or np.any(np.isnan(den)):
            raise ValidationError("Pooled.den", "a negative or NaN entry", ">= 0")
        object.__setattr__(self, "num", num)
        object.__setattr__(self, "den", den)

    @classmethod
    def rmse(cls, errors_per_unit) -> Pooled:
        """From each unit's errors: ``sqrt(Σ e² / count)`` pooled (a NaN error makes its unit,
        and so the figure, NaN: a failure is not averaged away)."""
        errs = [np.asarray(e, dtype=np.float64).ravel() for e in errors_per_unit]
        return cls([float(np.sum(e**2)) for e in errs], [e.size for e in errs], "rmse")

    @classmethod
    def mean(cls, values_per_unit) -> Pooled:
        """From each unit's values (an array or one number; NaN left out): their mean pooled."""
        vals = [np.asarray(x, dtype=np.float64).ravel() for x in values_per_unit]
        vals = [x[np.isfinite(x)] for x in vals]
        return cls([float(np.sum(x)) for x in vals], [x.size for x in vals], "mean")

    @classmethod
    def fraction(cls, flags_per_unit) -> Pooled:
        """From each unit's boolean outcomes: the share of true ones pooled."""
        flags = [np.asarray(f, dtype=bool).ravel() for f in flags_per_unit]
        return cls([int(f.sum()) for f in flags], [f.size for f in flags], "fraction")

    def at(self, point) -> Pooled:
        """This figure with the point value ``point``: the same number computed over every
        unit's values at once (a different order of additions, so it may differ from the
        pooled sums in the last bits). An error unless ``point`` equals the pooled value to
        1e-12 (both NaN included), so a figure cannot come from other units than its
        interval.

        >>> Pooled.mean([[0.1, 0.2], [0.3]]).at(0.2).value
        0.2
        """
        point, pooled = float(point), _combine(self.num, self.den, self.kind)
        same = math.isclose(point, pooled, rel_tol=1e-12, abs_tol=1e-300)
        if not (same or (math.isnan(point) and math.isnan(pooled))):
            raise ValidationError("Pooled.point", point, f"the pooled value {pooled!r}")
        return Pooled(self.num, self.den, self.kind, point)

    @property
    def n_units(self) -> int:
        """Number of units."""
        return int(self.num.size)

    @property
    def value(self) -> float:
        """The pooled figure (NaN when no unit counts), or the :meth:`at` point."""
        if self.point is not None:
            return float(self.point)
        return _combine(self.num, self.den, self.kind)


@dataclass(frozen=True, eq=False)
class Quantile:
    """The ``q``-quantile of values pooled over units, e.g. the 90 % point of the position
    errors of every agent of every realization (a unit: a realization).

    The point value is the inverted-CDF quantile of all values (the smallest value whose
    empirical CDF reaches ``q``; what the CDF figure shows). Its 95 % interval resamples
    units, not values (the errors of one realization are not independent): per resample the
    units are drawn with replacement and the quantile of their pooled values taken; the
    interval is the percentile one of :data:`N_RESAMPLES` such quantiles (NaN with fewer than
    two units).

    >>> Quantile([[1.0, 2.0], [3.0, 4.0]], 0.5).value
    2.0
    """

    values: tuple
    q: float

    def __post_init__(self):
        vals = tuple(np.asarray(x, dtype=np.float64).ravel() for x in self.values)
        if not 0.0 < float(self.q) < 1.0:
            raise ValidationError("Quantile.q", self.q, "a probability in (0, 1)")
        object.__setattr__(self, "values", vals)

    @property
    def value(self) -> float:
        """The quantile of all units' values pooled (NaN without values)."""
        pooled = np.concatenate(self.values) if self.values else np.zeros(0)
        if pooled.size == 0:
            return math.nan
        return float(np.quantile(pooled, self.q, method="inverted_cdf"))

    def interval(self, *, seed: int = 0, name: str = "") -> tuple[float, float]:
        """The 95 % cluster-bootstrap interval (see the class)."""
        units = [x for x in self.values if x.size]
        n = len(units)
        if n < 2:
            return math.nan, math.nan
        pooled = np.concatenate(units)
        label = np.repeat(np.arange(n), [x.size for x in units])
        order = np.argsort(pooled, kind="stable")
        values, label = pooled[order], label[order]
        rng = _stream(seed, name)
        out = np.empty(N_RESAMPLES)
        block = max(1, 2_000_000 // values.size)  # resamples at a time: bounded memory
        for i in range(0, N_RESAMPLES, block):
            k = min(block, N_RESAMPLES - i)
            counts = rng.multinomial(n, np.full(n, 1.0 / n), size=k)  # units drawn per resample
            cw = np.cumsum(counts[:, label], axis=1, dtype=np.float64)
            reach = cw >= self.q * cw[:, -1:]
            out[i : i + k] = values[reach.argmax(axis=1)]  # the inverted-CDF quantile
        alpha = (1.0 - CONFIDENCE) / 2.0
        lo, hi = np.quantile(out, [alpha, 1.0 - alpha])
        return float(lo), float(hi)


@dataclass(frozen=True)
class Paired:
    """The ratio ``a / b`` of two figures pooled over the same units, in the same order.

    ``suffix`` is appended to the figure's name when it is written (:func:`resolve`):
    ``".ratio"`` for a comparison of two methods, ``""`` for a figure that is a ratio by
    definition (an RMSE over its bound)."""

    a: Pooled
    b: Pooled
    suffix: str = ".ratio"

    def __post_init__(self):
        if self.a.n_units != self.b.n_units:
            raise ValidationError(
                "Paired.b", f"{self.b.n_units} units", f"{self.a.n_units} (the units of a)"
            )

    @property
    def value(self) -> float:
        """``a.value / b.value`` (NaN when either is NaN or ``b`` is 0)."""
        return _ratio(self.a.value, self.b.value)


def _ratio(a, b):
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.divide(a, b)) if b != 0 else math.nan


def _sum(x, axis):
    """``Σ x`` over ``axis`` in ascending order: the same bits for any order of the same
    values, so a resample that is a permutation of the units gives the figure itself exactly.
    Summed in the units' order instead, it differs from the figure in its last bits, and BCa's
    bias count ``#(θ*_b < θ̂)`` then counts it on either side at random; with a few units
    (10 units: one resample in 3000 is a permutation) and a gappy bootstrap distribution, that
    moved an interval end by up to 20 % when the data changed by 1e-9."""
    return np.sum(np.sort(x, axis=axis), axis=axis)


def _combine(num, den, kind, axis=-1):
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.divide(_sum(num, axis), _sum(den, axis))
        x = np.sqrt(x) if kind == "rmse" else x
    return float(x) if np.ndim(x) == 0 else x


def _divide(a, b):
    """``a / b`` elementwise, NaN/inf instead of an exception where ``b`` is 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.divide(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))


def _stream(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(name.encode())]))


def _bootstrap(data, statistic, rng) -> tuple[float, float]:
    """BCa interval of ``statistic`` over units (paired resampling of every array in ``data``);
    the percentile interval where BCa is undefined (a statistic constant in the jackknife);
    NaN with fewer than two units."""
    if data[0].size < 2:
        return math.nan, math.nan
    return _bootstrap_samples(data, statistic, rng, paired=True)


def _bootstrap_samples(data, statistic, rng, *, paired=False) -> tuple[float, float]:
    """:func:`scipy.stats.bootstrap` (BCa, then percentile) of ``statistic`` over ``data``,
    the arrays resampled together (``paired``) or each on its own."""
    state = rng.bit_generator.state
    for method in ("BCa", "percentile"):
        rng.bit_generator.state = state  # the same resamples for either method
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            res = stats.bootstrap(
                data,
                statistic,
                paired=paired,
                vectorized=True,
                n_resamples=N_RESAMPLES,
                confidence_level=CONFIDENCE,
                method=method,
                rng=rng,
            )
        lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if np.isfinite(lo) and np.isfinite(hi):
            return lo, hi
    return math.nan, math.nan


def interval(p: Pooled, *, seed: int = 0, name: str = "") -> tuple[float, float]:
    """The 95 % interval of a pooled figure (see the module); ``seed`` and ``name`` fix the
    bootstrap's stream.

    >>> lo, hi = interval(Pooled.fraction([[True, False], [True, True]]))
    >>> round(lo, 3), round(hi, 3)
    (0.194, 0.994)
    """
    if p.kind == "fraction":
        return _clopper_pearson(int(np.rint(p.num.sum())), int(np.rint(p.den.sum())))
    if p.n_units < 2 or not np.any(p.den > 0):
        return math.nan, math.nan
    point = p.value
    if np.all(p.den > 0) and np.ptp(p.num / p.den) == 0:
        return point, point  # every unit gives the same value: no spread to resample
    return _bootstrap(
        (p.num, p.den), lambda n, d, axis=-1: _combine(n, d, p.kind, axis), _stream(seed, name)
    )


def paired_interval(c: Paired, *, seed: int = 0, name: str = "") -> tuple[float, float]:
    """The 95 % interval of the ratio ``a / b`` by the paired bootstrap over their units."""
    a, b = c.a, c.b

    def ratio(na, da, nb, db, axis=-1):
        return _divide(_combine(na, da, a.kind, axis), _combine(nb, db, b.kind, axis))

    if not (np.any(a.den > 0) and np.any(b.den > 0)):
        return math.nan, math.nan
    return _bootstrap((a.num, a.den, b.num, b.den), ratio, _stream(seed, name))


def _clopper_pearson(k: int, n: int) -> tuple[float, float]:
    if n <= 0:
        return math.nan, math.nan
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=CONFIDENCE, method="exact")
    return float(ci.low), float(ci.high)


def resolve(figures: dict, series: dict, *, seed: int = 0) -> tuple[dict, dict]:
    """Replace the :class:`Pooled` and :class:`Paired` values of ``figures`` by numbers: the
    figure, its interval (``.ci_low``, ``.ci_high``) and (``Pooled``) its per-unit values in
    ``series`` (``<name>.units``: ``{"kind": ..., "num": [...], "den": [...]}``). A ``Paired``
    value under ``<name>`` becomes ``<name><suffix>`` (``<name>.ratio`` unless the value says
    otherwise) with its interval. Other entries are kept as they are, in their order."""
    out_f: dict = {}
    out_s = dict(series)
    for name, x in figures.items():
        if isinstance(x, Pooled):
            lo, hi = interval(x, seed=seed, name=name)
            out_f[name] = x.value
            out_f[name + ".ci_low"], out_f[name + ".ci_high"] = lo, hi
            out_s[name + ".units"] = {"kind": x.kind, "num": x.num, "den": x.den}
        elif isinstance(x, Quantile):
            out_f[name] = x.value
            out_f[name + ".ci_low"], out_f[name + ".ci_high"] = x.interval(seed=seed, name=name)
        elif isinstance(x, Paired):
            key = name + x.suffix
            lo, hi = paired_interval(x, seed=seed, name=key)
            out_f[key] = x.value
            out_f[key + ".ci_low"], out_f[key + ".ci_high"] = lo, hi
        else:
            out_f[name] = x
    return out_f, out_s


def units_of(series: dict, name: str) -> Pooled | None:
    """The :class:`Pooled` figure ``name`` back from stored ``series`` (None when the run did
    not store its units)."""
    u = series.get(name + ".units")
    if u is None:
        return None
    return Pooled(u["num"], u["den"], u["kind"])


def ratio_interval(
    a: Pooled, b: Pooled, *, paired: bool, seed: int = 0, name: str = ""
) -> tuple[float, float]:
    """The 95 % interval of ``a.value / b.value``: the paired bootstrap
    (:func:`paired_interval`) when ``a`` and ``b`` share their units, otherwise each figure's
    units resampled independently (figures of different network sizes, say)."""
    if paired:
        return paired_interval(Paired(a, b), seed=seed, name=name)
    if a.n_units < 2 or b.n_units < 2 or not (np.any(a.den > 0) and np.any(b.den > 0)):
        return math.nan, math.nan

    def ratio(i, j, axis=-1):
        i, j = i.astype(np.intp), j.astype(np.intp)
        return _divide(
            _combine(a.num[i], a.den[i], a.kind, axis), _combine(b.num[j], b.den[j], b.kind, axis)
        )

    return _bootstrap_samples(
        (np.arange(a.n_units, dtype=float), np.arange(b.n_units, dtype=float)),
        ratio,
        _stream(seed, name),
    )


def verdict(
    low: float, high: float, *, claim: str, value: float = 1.0, tolerance: float = 0.1
) -> str:
    """Read a 95 % interval ``[low, high]`` against a claim about the figure.

    ``claim`` is ``"<"`` (the figure is below ``value``), ``">"`` (above it) or ``"="`` (equal
    to it within a relative ``tolerance``: inside the band ``value·(1 ± tolerance)``).
    ``holds`` when the whole interval is on the claimed side (inside the band), ``differs``
    when the whole interval is on the other side (outside the band), ``undecided`` otherwise
    (or when the interval is NaN: too few units).

    >>> verdict(0.7, 0.9, claim="<"), verdict(0.9, 1.2, claim="<"), verdict(1.1, 1.3, claim="<")
    ('holds', 'undecided', 'differs')
    >>> verdict(0.95, 1.04, claim="="), verdict(0.8, 1.04, claim="="), verdict(1.2, 1.3, claim="=")
    ('holds', 'undecided', 'differs')
    """
    if claim not in ("<", ">", "="):
        raise ValidationError("claim", claim, "<, > or =")
    if not (np.isfinite(low) and np.isfinite(high)):
        return "undecided"
    if claim == "=":
        band = (value * (1 - tolerance), value * (1 + tolerance))
        if band[0] <= low and high <= band[1]:
            return "holds"
        return "differs" if high < band[0] or low > band[1] else "undecided"
    if claim == "<":
        return "holds" if high < value else "differs" if low >= value else "undecided"
    return "holds" if low > value else "differs" if high <= value else "undecided"
