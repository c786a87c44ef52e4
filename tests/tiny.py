"""The small recipe many tests run, written once: 4 agents in 60 m × 60 m over WINNER II C2, an
OFDM system of N = 257 subcarriers at 146.5 kHz (37.6 MHz) and a 200 m ranging window."""

from __future__ import annotations

import copy

from phyloc.config import dumps_toml

BASE = {
    "system": {"n_subcarriers": 257, "subcarrier_spacing_hz": 146.5e3},
    "network": {"n_agents": 4, "region_m": [60.0, 60.0]},
    "channel": {"scenario": "winner2_c2"},
    "ranging": {"window_m": [0.0, 200.0]},
}


def tiny_recipe(kind: str | None = None, name: str | None = None, seed: int = 5, **sections):
    """TOML text of the tiny recipe: :data:`BASE` updated section by section (key by key) by
    ``sections``; a section given as None is left out, and ``kind`` / ``name`` when None.

    >>> "n_agents = 4" in tiny_recipe("dataset", "t", dataset={"realizations": 2})
    True
    """
    doc = {"kind": kind, "name": name, "seed": seed, **copy.deepcopy(BASE)}
    for section, table in sections.items():
        if table is None:
            doc.pop(section, None)
        else:
            doc[section] = {**doc.get(section, {}), **table}
    return "\n" + dumps_toml(doc)
