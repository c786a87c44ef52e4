"""Plain-NumPy reference twins for the benchmarks' ratios.

The twins are test code (``tests/naive_*.py`` of a source checkout) and are not installed with
the package. A benchmark that compares a kernel with its twin loads it here: from the
``tests/`` folder beside this package's sources (editable install) or of the current directory
(run ``phyloc bench`` from the checkout). Without a checkout the ratio is not measured and the
benchmark says so.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType


def _candidates(name: str):
    here = Path(__file__).resolve().parent
    yield here.parent / "tests" / f"{name}.py"
    yield Path.cwd() / "tests" / f"{name}.py"


def naive(name: str) -> ModuleType | None:
    """The module ``tests/<name>.py`` of the source checkout, or None where there is none."""
    for path in _candidates(name):
        if path.is_file():
            spec = importlib.util.spec_from_file_location(f"_phyloc_reference_{name}", path)
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            return module
    return None


MISSING = "NumPy twin not found (run `phyloc bench` from a source checkout to measure the ratio)"
