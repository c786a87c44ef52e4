"""The claims ledger (phyloc.evaluation.claims) and ``phyloc claims``."""

import json
from pathlib import Path

import numpy as np
import pytest

from phyloc.cli import main
from phyloc.errors import PhylocError, ValidationError
from phyloc.evaluation.claims import check_ledger, combine, evaluate_check, load_ledger
from phyloc.evaluation.statistics import Paired, Pooled, resolve

ROOT = Path(__file__).resolve().parents[1]


def _store(tmp_path, run="r", seed=3):
    """A stored run: method a is 0.8 × method b on every realization (plus a little noise),
    at 12 agents; at 30 agents both halve."""
    rng = np.random.default_rng(0)
    figs = {}
    for n, scale in ((12, 1.0), (30, 0.5)):
        base = [scale * rng.normal(size=8) for _ in range(20)]
        a = Pooled.rmse([0.8 * e + 0.01 * rng.normal(size=8) for e in base])
        b = Pooled.rmse(base)
        figs[f"a.agents_{n}.rmse"] = a
        figs[f"b.agents_{n}.rmse"] = b
        figs[f"a_vs_b.agents_{n}.rmse"] = Paired(a, b)
    figs["exact.zeta"] = -0.3
    figures, series = resolve(figs, {}, seed=seed)
    d = tmp_path / "results" / run
    d.mkdir(parents=True)
    doc = {
        "figures": figures,
        "series": {
            k: {**v, "num": list(v["num"]), "den": list(v["den"])} for k, v in series.items()
        },
        "meta": {"seed": seed},
    }
    (d / "results.json").write_text(json.dumps(doc))
    return tmp_path / "results", figures


LEDGER = """
[[claim]]
id = "a-below-b"
paper = "P"
where = "Fig. 1"
statement = "a is below b."
run = "r"
check = "a.agents_{n}.rmse / b.agents_{n}.rmse < 1"
each = { n = [12, 30] }
verdict = "@V1@"

[[claim]]
id = "a-halves"
paper = "P"
where = "Fig. 1"
statement = "a halves from 12 to 30 agents."
run = "r"
check = "a.agents_30.rmse / a.agents_12.rmse ≈ 0.5"
paired = false
tolerance = 0.5
verdict = "holds"

[[claim]]
id = "zeta-negative"
paper = "P"
where = "Fig. 2"
statement = "zeta is negative."
run = "r"
check = "exact.zeta < 0"
exact = true
verdict = "holds"

[[claim]]
id = "a-above-b"
paper = "P"
where = "Fig. 1"
statement = "a is above b."
run = "r"
check = "a_vs_b.agents_12.rmse.ratio > 1"
verdict = "differs"
explained_by = "r"
"""


def test_verdicts_from_a_stored_run(tmp_path):
    results, figures = _store(tmp_path)
    ledger = tmp_path / "claims.toml"
    ledger.write_text(LEDGER.replace("@V1@", "holds"))
    report = {r["id"]: r for r in check_ledger(ledger, results)}
    assert all(r["matches"] for r in report.values())
    (o12, _o30) = report["a-below-b"]["outcomes"]
    assert o12["ci_high"] < 1 and o12["ci_low"] > 0.7  # ~0.8, paired: a narrow interval
    assert o12["value"] == pytest.approx(figures["a.agents_12.rmse"] / figures["b.agents_12.rmse"])
    # the paired interval recomputed from the stored units is the runner's own
    assert (
        report["a-above-b"]["outcomes"][0]["ci_high"]
        == figures["a_vs_b.agents_12.rmse.ratio.ci_high"]
    )
    assert report["zeta-negative"]["outcomes"][0]["exact"]


def test_a_monte_carlo_figure_without_interval_is_undecided(tmp_path):
    results, _ = _store(tmp_path)
    res = json.loads((results / "r" / "results.json").read_text())
    out = evaluate_check("exact.zeta < 0", res, run="r")  # not declared exact: no interval
    assert out.verdict == "undecided" and not out.exact
    res["series"].pop("a.agents_12.rmse.units")
    out = evaluate_check("a.agents_12.rmse / b.agents_12.rmse < 1", res, run="r")
    assert out.verdict == "undecided"


def test_a_flipped_verdict_fails_the_command(tmp_path, capsys):
    results, _ = _store(tmp_path)
    ledger = tmp_path / "claims.toml"
    ledger.write_text(LEDGER.replace("@V1@", "undecided"))
    rc = main(["claims", "--ledger", str(ledger), "--results", str(results)])
    out, err = capsys.readouterr()
    assert rc == 1 and "a-below-b" in err and "holds (ledger: undecided)" in out
    ledger.write_text(LEDGER.replace("@V1@", "holds"))
    js = tmp_path / "c.json"
    rc = main(["claims", "--ledger", str(ledger), "--results", str(results), "--json", str(js)])
    assert rc == 0 and json.loads(js.read_text())["meta"]["claims"][0]["verdict_now"] == "holds"


def test_combine():
    assert combine(["holds", "holds"]) == "holds"
    assert combine(["holds", "undecided"]) == "undecided"
    assert combine(["undecided", "differs"]) == "differs"


def test_unpaired_ratio_is_wider_than_paired(tmp_path):
    results, _ = _store(tmp_path)
    res = json.loads((results / "r" / "results.json").read_text())
    check = "a.agents_12.rmse / b.agents_12.rmse < 1"
    paired = evaluate_check(check, res, run="r", paired=True)
    free = evaluate_check(check, res, run="r", paired=False)
    assert free.ci_high - free.ci_low > 3 * (paired.ci_high - paired.ci_low)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (
            lambda t: t.replace('note = ""', "").replace(
                'verdict = "differs"', 'verdict = "wrong"'
            ),
            "verdict",
        ),
        (lambda t: t.replace('explained_by = "r"', ""), "explained_by"),
        (lambda t: t.replace("exact.zeta < 0", "exact.zeta << 0"), "check"),
        (
            lambda t: t.replace(
                'run = "r"\ncheck = "exact', 'run = "r"\ncolour = 1\ncheck = "exact'
            ),
            "colour",
        ),
        (lambda t: t.replace('id = "a-halves"', 'id = "a-below-b"'), "id"),
        (lambda t: t.replace("each = { n = [12, 30] }", "each = { m = [12, 30] }"), "check"),
    ],
)
def test_bad_ledgers_are_named(tmp_path, edit, match):
    ledger = tmp_path / "claims.toml"
    ledger.write_text(edit(LEDGER).replace("@V1@", "holds"))
    with pytest.raises(ValidationError, match=match):
        load_ledger(ledger)


def test_missing_files_are_one_line_errors(tmp_path, capsys):
    with pytest.raises(PhylocError, match="--ledger"):
        load_ledger(tmp_path / "nothing.toml")
    ledger = tmp_path / "claims.toml"
    ledger.write_text(LEDGER.replace("@V1@", "holds"))
    with pytest.raises(PhylocError, match="not found"):
        check_ledger(ledger, tmp_path / "empty")
    results, _ = _store(tmp_path)
    ledger.write_text(LEDGER.replace("@V1@", "holds").replace("exact.zeta", "exact.eta"))
    with pytest.raises(PhylocError, match=r"exact\.eta"):
        check_ledger(ledger, results)


@pytest.mark.skipif(not (ROOT / "docs" / "claims.toml").is_file(), reason="no source checkout")
def test_the_ledger_matches_the_stored_runs():
    """Every verdict of docs/claims.toml, recomputed from docs/results: a change that flips one
    fails here, so that it is seen and the ledger is updated deliberately."""
    report = check_ledger(ROOT / "docs" / "claims.toml", ROOT / "docs" / "results")
    flipped = [
        f"{r['id']}: ledger {r['verdict']}, now {r['verdict_now']}"
        for r in report
        if not r["matches"]
    ]
    assert not flipped, flipped


def test_a_damaged_stored_run_is_a_one_line_error(tmp_path, capsys):
    results, _ = _store(tmp_path)
    ledger = tmp_path / "claims.toml"
    ledger.write_text(LEDGER.replace("@V1@", "holds"))
    (results / "r" / "results.json").write_text('{"figures": [1, 2')
    assert main(["claims", "--ledger", str(ledger), "--results", str(results)]) != 0
    err = capsys.readouterr().err
    assert "cannot be read" in err and "Traceback" not in err
    (results / "r" / "results.json").write_text("[]")
    with pytest.raises(PhylocError, match="no figures table"):
        check_ledger(ledger, results)
