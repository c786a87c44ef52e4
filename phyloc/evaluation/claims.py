"""The claims ledger: the papers' checkable statements, each with a verdict from a stored run.

The ledger is a TOML file (the repository's ``docs/claims.toml``), one ``[[claim]]`` table per
statement::

    [[claim]]
    id = "dipnet-fig5-below-corr"                # unique
    paper = "DiPNet"                             # the source paper
    where = "§V-A, text under Fig. 5"            # where the paper says it
    statement = "DiPNet's RMSE is below the correlation-based two-step method's."  # our words
    run = "dipnet_fig5_evidence"                 # docs/results/<run>/results.json
    check = "dipnet.{s}.agents_{n}.framework_rmse_m / corr.{s}.agents_{n}.framework_rmse_m < 1"
    each = { s = ["c2", "d1"], n = [12, 30] }    # optional: every combination is checked
    paired = true                                # a ratio over the same realizations (default)
    exact = false                                # true: the figures are exact computations
    verdict = "holds"                            # what the stored run gives at 95 %
    explained_by = ""                            # for "differs": the stored run that explains it
    note = ""                                    # optional

``check`` is ``LHS OP VALUE``: ``LHS`` is one figure name or a ratio ``A / B`` of two, ``OP``
one of ``<``, ``>`` or ``≈`` (equal within ``tolerance``, default 0.1 relative). The verdict of
one check comes from its 95 % interval (:func:`phyloc.evaluation.statistics.verdict`):

* a ratio: from the stored per-unit values of both figures, by the paired bootstrap
  (``paired = true``: the same realizations, e.g. two methods at one network size) or by
  resampling each figure's units on its own (``paired = false``: different sizes);
* one figure: its stored ``.ci_low`` / ``.ci_high``;
* a claim on exact computations (``exact = true``: an analysis, not a Monte Carlo run): the
  value decides (``holds`` / ``differs``). A Monte Carlo figure stored without its interval or
  units (a run from before intervals were kept) gives ``undecided``.

A claim with ``each`` holds when every combination holds, differs when one differs, and is
undecided otherwise. A ``differs`` claim names in ``explained_by`` the stored run (an ablation,
a diagnostic) that measures its cause. :func:`check_ledger` recomputes every verdict;
``phyloc claims`` prints them, and a test fails when one no longer matches the ledger.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
TOML v1.0.0, https://toml.io/en/v1.0.0 (the ledger's format).
"""

from __future__ import annotations

import itertools
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from phyloc.errors import PhylocError, ValidationError
from phyloc.evaluation.statistics import VERDICTS, ratio_interval, units_of, verdict

#: The keys of a ``[[claim]]`` table (``each``, ``paired``, ``tolerance``, ``explained_by``
#: and ``note`` are optional).
CLAIM_KEYS = (
    "id",
    "paper",
    "where",
    "statement",
    "run",
    "check",
    "each",
    "paired",
    "exact",
    "tolerance",
    "verdict",
    "explained_by",
    "note",
)
_REQUIRED = ("id", "paper", "where", "statement", "run", "check", "verdict")
_CHECK = re.compile(
    r"^\s*(?P<a>[^\s/<>≈]+)\s*(?:/\s*(?P<b>[^\s/<>≈]+)\s*)?(?P<op><|>|≈)\s*(?P<v>[-+0-9.eE]+)\s*$"
)


@dataclass(frozen=True)
class Claim:
    """One ``[[claim]]`` of the ledger (see the module)."""

    id: str
    paper: str
    where: str
    statement: str
    run: str
    check: str
    verdict: str
    each: dict = field(default_factory=dict)
    paired: bool = True
    exact: bool = False
    tolerance: float = 0.1
    explained_by: str = ""
    note: str = ""

    def instances(self) -> list[str]:
        """The check with every combination of ``each`` filled in."""
        if not self.each:
            return [self.check]
        keys = list(self.each)
        return [
            self.check.format(**dict(zip(keys, combo, strict=True)))
            for combo in itertools.product(*(self.each[k] for k in keys))
        ]


@dataclass(frozen=True)
class Outcome:
    """The recomputed verdict of one check instance."""

    check: str
    value: float
    ci_low: float
    ci_high: float
    verdict: str
    exact: bool = False


def load_ledger(path) -> list[Claim]:
    """Read and validate a ledger (one-line errors naming the claim and key)."""
    path = Path(path)
    if not path.is_file():
        raise PhylocError(
            f"claims ledger {path} not found; run from the repository root or pass --ledger PATH"
        )
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise PhylocError(f"claims ledger {path}: not valid TOML ({exc})") from None
    tables = doc.get("claim", [])
    if not isinstance(tables, list) or not tables:
        raise ValidationError(f"{path}: claim", tables, "one or more [[claim]] tables")
    claims, seen = [], set()
    for i, t in enumerate(tables):
        where = f"claim[{i}]" + (f" ({t['id']})" if isinstance(t.get("id"), str) else "")
        unknown = sorted(set(t) - set(CLAIM_KEYS))
        if unknown:
            raise ValidationError(f"{where}.{unknown[0]}", t[unknown[0]], ", ".join(CLAIM_KEYS))
        for k in _REQUIRED:
            if not isinstance(t.get(k), str) or not t[k].strip():
                raise ValidationError(f"{where}.{k}", t.get(k), "a non-empty string")
        if t["id"] in seen:
            raise ValidationError(f"{where}.id", t["id"], "an id no other claim has")
        seen.add(t["id"])
        if t["verdict"] not in VERDICTS:
            raise ValidationError(f"{where}.verdict", t["verdict"], ", ".join(VERDICTS))
        if t["verdict"] == "differs" and not t.get("explained_by", "").strip():
            raise ValidationError(
                f"{where}.explained_by", "", "the stored run that explains a 'differs' verdict"
            )
        if not _CHECK.match(t["check"].replace("{", "").replace("}", "")):
            raise ValidationError(f"{where}.check", t["check"], "'A < v', 'A / B > v', 'A ≈ v'")
        each = t.get("each", {})
        if not isinstance(each, dict) or any(
            not isinstance(v, list) or not v for v in each.values()
        ):
            raise ValidationError(f"{where}.each", each, "a table of non-empty lists")
        claim = Claim(**t)
        try:
            claim.instances()
        except (KeyError, IndexError) as exc:
            raise ValidationError(f"{where}.check", t["check"], f"names only {list(each)}") from (
                exc
            )
        claims.append(claim)
    return claims


def _results(results_dir: Path, run: str, cache: dict) -> dict:
    if run not in cache:
        path = results_dir / run / "results.json"
        if not path.is_file():
            raise PhylocError(f"stored run {path} not found (the ledger's run = {run!r})")
        try:
            doc = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise PhylocError(f"stored run {path} cannot be read ({exc}); run it again") from None
        if not isinstance(doc, dict) or not isinstance(doc.get("figures"), dict):
            raise PhylocError(f"stored run {path} has no figures table; run it again")
        cache[run] = doc
    return cache[run]


def _figure(res: dict, name: str, run: str) -> float:
    f = res["figures"]
    if name not in f:
        raise PhylocError(f"figure {name!r} is not in the stored run {run!r}")
    x = f[name]
    return math.nan if x is None else float(x)


def evaluate_check(
    check: str, res: dict, *, run: str, paired=True, exact=False, tolerance=0.1
) -> Outcome:
    """The verdict of one filled-in check on the stored results ``res`` of ``run``."""
    m = _CHECK.match(check)
    if m is None:
        raise ValidationError("check", check, "'A < v', 'A / B > v' or 'A ≈ v'")
    a, b, op, value = m["a"], m["b"], m["op"], float(m["v"])
    claim = "=" if op == "≈" else op
    series, seed = res.get("series", {}), int(res.get("meta", {}).get("seed", 0))
    fa = _figure(res, a, run)
    if b is None:
        x = fa
        lo, hi = res["figures"].get(a + ".ci_low"), res["figures"].get(a + ".ci_high")
        lo = math.nan if lo is None else float(lo)
        hi = math.nan if hi is None else float(hi)
    else:
        fb = _figure(res, b, run)
        x = fa / fb if fb != 0 else math.nan
        ua, ub = units_of(series, a), units_of(series, b)
        if exact or ua is None or ub is None:
            lo = hi = math.nan
        else:
            lo, hi = ratio_interval(ua, ub, paired=paired, seed=seed, name=check)
    if exact:
        lo = hi = x
    out = verdict(lo, hi, claim=claim, value=value, tolerance=tolerance)
    return Outcome(check, x, lo, hi, out, exact)


def combine(verdicts) -> str:
    """Holds when all hold, differs when one differs, undecided otherwise."""
    verdicts = list(verdicts)
    if any(v == "differs" for v in verdicts):
        return "differs"
    return "holds" if all(v == "holds" for v in verdicts) else "undecided"


def check_ledger(ledger, results_dir) -> list[dict]:
    """Recompute every claim of ``ledger`` (a path) from the stored runs under
    ``results_dir``. One dict per claim: its fields, the recomputed ``verdict_now``, whether it
    ``matches`` the ledger, and the ``outcomes`` of its checks."""
    results_dir = Path(results_dir)
    cache: dict = {}
    report = []
    for c in load_ledger(ledger):
        res = _results(results_dir, c.run, cache)
        outs = [
            evaluate_check(i, res, run=c.run, paired=c.paired, exact=c.exact, tolerance=c.tolerance)
            for i in c.instances()
        ]
        now = combine(o.verdict for o in outs)
        report.append(
            {
                "id": c.id,
                "paper": c.paper,
                "where": c.where,
                "statement": c.statement,
                "run": c.run,
                "check": c.check,
                "verdict": c.verdict,
                "verdict_now": now,
                "matches": now == c.verdict,
                "explained_by": c.explained_by,
                "note": c.note,
                "outcomes": [o.__dict__ for o in outs],
            }
        )
    return report
