"""Every stored run under ``docs/results/`` reads back as a user would read it: its figures
draw again and its table prints from the ``results.json`` alone (JSON keeps no ``inf``: an
infinite range comes back as ``null``)."""

import json
from pathlib import Path

import pytest

from phyloc.evaluation.kinds import EXPERIMENTS

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"
RUNS = sorted(
    p.parent.name
    for p in RESULTS.glob("*/results.json")
    # a channel-compare run has no experiment: tests/test_sionna_compare.py reads it back
    if json.loads(p.read_text())["meta"].get("command") != "channel-compare"
)


def test_the_stored_runs_are_found():
    assert len(RUNS) >= 15


@pytest.mark.parametrize("run", RUNS)
def test_a_stored_run_draws_and_prints_from_its_json(run, tmp_path):
    results = json.loads((RESULTS / run / "results.json").read_text())
    experiment = EXPERIMENTS[results["meta"]["kind"]]
    experiment.plot(results, tmp_path / f"{run}.png")
    pngs = list(tmp_path.glob("*.png"))
    assert pngs and all(p.stat().st_size > 1000 for p in pngs)
    rows = experiment.summary_rows(results)
    headers = experiment.summary_headers(results)
    assert rows and all(len(r) == len(headers) for r in rows if not isinstance(r, str))
