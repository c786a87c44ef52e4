"""Sphinx configuration of the phyloc documentation.

Build: ``python -m sphinx -W --keep-going -b html docs docs/_build/html`` (zero warnings in CI).
Generated sources (``_autosummary/``, ``_generated/``) are written next to this file at build
time and are not versioned.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import runpy
from pathlib import Path

# The package must not start work at import (autosummary imports every public module); set
# before importing phyloc.
os.environ.setdefault("PHYLOC_NO_PROGRESS", "1")

import phyloc

HERE = Path(__file__).resolve().parent

project = "phyloc"
author = "phyloc developers"
copyright = "2026, phyloc developers"
version = release = phyloc.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "examples", "_generated"]
root_doc = "index"

# API reference: one page per public module, generated from the docstrings.
templates_path = ["_templates"]
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()
numpydoc_xref_param_type = False

myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

html_theme = "pydata_sphinx_theme"
html_title = "phyloc"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}


def _dataset_layout() -> None:
    """Write ``_generated/dataset_layout.txt``: the layout of a tiny dataset written now."""
    buf = io.StringIO()
    script = runpy.run_path(str(HERE / "examples" / "dataset_layout.py"), run_name="layout")
    with contextlib.redirect_stdout(buf):
        script["main"]()
    _write("dataset_layout.txt", buf.getvalue())


def _write(name: str, text: str) -> None:
    out = HERE / "_generated" / name
    out.parent.mkdir(exist_ok=True)
    if not out.exists() or out.read_text() != text:
        out.write_text(text)


def _methods_table() -> None:
    """Write ``_generated/methods.rst``: every registered method, read from the registry now."""
    from phyloc.localization import METHODS

    rows = [
        ".. list-table::",
        "   :header-rows: 1",
        "   :widths: 14 8 34 14 30",
        "",
        "   * - name",
        "     - family",
        "     - label: description",
        "     - inputs",
        "     - options (defaults of the named variant)",
    ]
    for name in METHODS:
        m = METHODS[name]
        defaults = ", ".join(f"``{k} = {v!r}``" for k, v in m.defaults.items())
        options = f":class:`~{m.options.__module__}.{m.options.__qualname__}`"
        rows += [
            f"   * - ``{name}``",
            f"     - {m.family}",
            f"     - {m.label}: {m.description}" if m.description else f"     - {m.label}",
            f"     - ``{m.inputs}``" if m.inputs else "     -",
            f"     - {options}" + (f"; {defaults}" if defaults else ""),
        ]
    _write("methods.rst", "\n".join(rows) + "\n")


def _rst(text: str) -> str:
    """Plain text safe in a reST table cell (``|`` and ``*`` are markup)."""
    return text.replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*")


def _claims_rows(paper: str, report: list) -> list:
    """The reST list-table of one paper's claims in ``report``."""
    rows = [
        f".. list-table:: {paper}",
        "   :header-rows: 1",
        "   :widths: 22 40 10 16 12",
        "",
        "   * - claim (where)",
        "     - statement (our words); check",
        "     - verdict",
        "     - value [95 % interval]",
        "     - stored run",
    ]
    for r in (r for r in report if r["paper"] == paper):
        cells = []
        for o in r["outcomes"]:
            if o["exact"]:
                cells.append(f"{o['value']:.3g} (exact)")
            else:
                cells.append(f"{o['value']:.3g} [{o['ci_low']:.3g}, {o['ci_high']:.3g}]")
        verdict = f"**{r['verdict_now']}**"
        if not r["matches"]:
            verdict += f" (ledger: {r['verdict']})"
        note = f" {_rst(r['note'])}" if r["note"] else ""
        why = f" Explained by ``{r['explained_by']}``." if r["explained_by"] else ""
        rows += [
            f"   * - ``{r['id']}`` ({r['where']})",
            f"     - {_rst(r['statement'])} ``{r['check']}``.{note}{why}",
            f"     - {verdict}",
            f"     - {'; '.join(cells)}",
            f"     - ``{r['run']}``",
        ]
    return [*rows, ""]


def _claims_table() -> None:
    """Write ``_generated/claims.rst`` (the whole claims ledger) and one
    ``_generated/claims_<paper>.rst`` per paper (included by its page), every verdict
    recomputed now from the stored runs (:func:`phyloc.evaluation.claims.check_ledger`)."""
    from phyloc.evaluation.claims import check_ledger

    report = check_ledger(HERE / "claims.toml", HERE / "results")
    rows = []
    for paper in dict.fromkeys(r["paper"] for r in report):
        table = _claims_rows(paper, report)
        rows += table
        slug = re.sub(r"[^a-z0-9]+", "_", paper.lower()).strip("_")
        _write(f"claims_{slug}.rst", "\n".join(table) + "\n")
    _write("claims.rst", "\n".join(rows) + "\n")


_dataset_layout()
_methods_table()
_claims_table()
