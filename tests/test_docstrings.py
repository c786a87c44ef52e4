"""Documentation conventions (``docs/guide/design.rst``): every equation citation names its
paper and every public module has a ``References`` section."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "phyloc"

#: Short names of the sources an equation number may refer to (the papers of
#: ``phyloc/references.py``, the WINNER II report and textbooks).
SOURCES = (
    r"DiPNet|PF-BP|POA-NBP|WINNER|Kay|Ziv|Zakai|Tichavsk|Silverman|Umeyama|Kabsch|Daum|Julier"
    r"|Ihler|Sudderth|Van Trees|Bellini|Weiss|Tipping"
)
CITATION = re.compile(r"\b[Ee]qs?\.\s*\(?\d")


def _modules():
    return sorted(ROOT.rglob("*.py"))


def test_every_equation_citation_names_its_source():
    bad = []
    for path in _modules():
        text = path.read_text(encoding="utf-8")
        for m in CITATION.finditer(text):
            before = text[max(0, m.start() - 60) : m.start()]
            if not re.search(SOURCES, before):
                line = text.count("\n", 0, m.start()) + 1
                snippet = text[max(0, m.start() - 30) : m.end() + 4].replace("\n", " ")
                bad.append(f"{path.relative_to(ROOT.parent)}:{line}: …{snippet}")
    assert not bad, "equation citations without a paper name:\n" + "\n".join(bad)


def test_every_public_module_has_references():
    missing = []
    for path in _modules():
        if path.name.startswith("_") and path.name != "__init__.py":
            continue
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
        if not re.search(r"^References\n-{10}", doc, flags=re.M):
            missing.append(str(path.relative_to(ROOT.parent)))
    assert not missing, "modules without a References section:\n" + "\n".join(missing)


def test_the_checks_catch_a_bare_citation(tmp_path):
    text = "the ranging CRB of eq. (24) and DiPNet eq. (25)"
    hits = [m for m in CITATION.finditer(text)]
    named = [bool(re.search(SOURCES, text[max(0, m.start() - 60) : m.start()])) for m in hits]
    assert named == [False, True]
