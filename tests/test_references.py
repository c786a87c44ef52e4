"""One bibliography: every ``References`` entry of a source in :mod:`phyloc.references` is the
canonical one.

An entry that starts with a short name (``DiPNet:``, ``PF-BP:``, …) or that names the title of
a paper with a short name must be that paper's entry from :data:`phyloc.references.PAPERS`,
compared after whitespace normalization; an entry naming the title of another listed source
must give its authors and title as listed (notes and links after the title may differ). The
check reads the docstrings (modules, classes, functions) of every module under ``phyloc/`` and
``benchmarks/`` with ``ast`` and reports every mismatch at once, file by file. The README, the
paper pages of the documentation and ``CITATION.cff`` carry the same texts.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from phyloc.references import PAPERS, SHORT_NAMES, TITLES, entry

ROOT = Path(__file__).resolve().parents[1]

#: A numpydoc section header (a title line underlined by dashes) ends a ``References`` section.
_SECTION = re.compile(r"^References\n-{3,}\n(.*?)(?=^[^\n]+\n-{3,}\n|\Z)", re.M | re.S)
_SHORT = re.compile(r"^\s*(" + "|".join(re.escape(s) for s in SHORT_NAMES) + r"):", re.M)


def _norm(text: str) -> str:
    return " ".join(text.split())


def _docstrings(path: Path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node, clean=True)
            if doc:
                yield doc


def reference_blocks(text: str) -> list[str]:
    """The ``References`` sections of one docstring."""
    return [m.group(1) for m in _SECTION.finditer(text)]


def _covered(block: str, start: int, end: int, expected: str) -> bool:
    """Whether an occurrence of ``expected`` in ``block`` spans ``block[start:end]``."""
    i = block.find(expected)
    while i != -1:
        if i <= start and end <= i + len(expected):
            return True
        i = block.find(expected, i + 1)
    return False


def required(key: str) -> str:
    """What an entry citing ``key`` must contain: the whole entry of a paper with a short name;
    for another source its authors and title up to the title phrase (notes and links after the
    title may differ from module to module)."""
    if key in SHORT_NAMES:
        return entry(key)
    text = PAPERS[key]
    return text[: text.lower().index(TITLES[key].lower()) + len(TITLES[key])]


def mismatches(block: str) -> list[str]:
    """What in one ``References`` section differs from the canonical entries (empty: nothing).

    Each finding names the source and quotes the entry as written (up to 160 characters).
    """
    found = []
    # 1. an entry that starts with a short name must be that source's entry
    starts = [m.start() for m in _SHORT.finditer(block)] + [len(block)]
    for m, stop in zip(_SHORT.finditer(block), starts[1:], strict=True):
        key = m.group(1)
        written = _norm(block[m.start() :])
        if not written.startswith(entry(key)):
            found.append(f"{key}, written as: {_norm(block[m.start() : stop])[:160]}")
    # 2. an entry that names a listed title must be (inside) that source's entry
    flat = _norm(block)
    low = flat.lower()
    for key, title in TITLES.items():
        t = title.lower()
        i = low.find(t)
        while i != -1:
            if not _covered(flat, i, i + len(t), required(key)):
                head = max(0, flat.rfind(". ", 0, max(0, i - 120)))
                snippet = flat[head : head + 160].lstrip(". ")
                if not any(f.startswith(f"{key}, ") for f in found):
                    found.append(f"{key}, without its canonical entry: {snippet}")
            i = low.find(t, i + 1)
    return found


def _modules() -> list[Path]:
    return sorted([*(ROOT / "phyloc").rglob("*.py"), *(ROOT / "benchmarks").rglob("*.py")])


def test_references_of_every_module_are_canonical():
    report = []
    for path in _modules():
        bad = []
        for doc in _docstrings(path):
            for block in reference_blocks(doc):
                bad += [b for b in mismatches(block) if b not in bad]
        if bad:
            report.append(f"{path.relative_to(ROOT)}:\n    " + "\n    ".join(bad))
    assert not report, (
        f"{len(report)} files cite a source of phyloc/references.py in another wording; "
        "copy the entry from phyloc.references.PAPERS:\n" + "\n".join(report)
    )


def test_the_bibliography_is_consistent():
    assert set(SHORT_NAMES) <= set(PAPERS)
    assert set(TITLES) == set(PAPERS)
    for key, title in TITLES.items():
        assert title.lower() in PAPERS[key].lower(), key
        others = [k for k in PAPERS if k != key and title.lower() in PAPERS[k].lower()]
        assert not others, f"the title phrase of {key} also occurs in {others}"
    # the module's own References section lists every entry, in canonical form
    doc = ast.get_docstring(ast.parse((ROOT / "phyloc" / "references.py").read_text("utf-8")))
    (block,) = reference_blocks(doc)
    assert not mismatches(block)
    for key in PAPERS:
        assert entry(key) in _norm(block), key


@pytest.mark.parametrize(
    ("path", "keys"),
    [
        ("README.md", ["DiPNet", "PF-BP", "POA-NBP", "FIM"]),
        ("docs/papers/dipnet.rst", ["DiPNet"]),
        ("docs/papers/pfbp.rst", ["PF-BP"]),
        ("docs/papers/poa_nbp.rst", ["POA-NBP"]),
        ("docs/papers/fim_control.rst", ["FIM"]),
    ],
)
def test_readme_and_paper_pages_quote_the_bibliography(path, keys):
    text = _norm((ROOT / path).read_text(encoding="utf-8"))
    missing = [k for k in keys if PAPERS[k] not in text]
    assert not missing, f"{path} does not quote the canonical text of {missing}"


def test_citation_file_names_every_paper():
    text = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    for key in ("DiPNet", "PF-BP", "POA-NBP", "FIM"):
        title = re.search(r'"([^"]+?),?"', PAPERS[key]).group(1)
        assert title.rstrip(".,").lower() in text.lower(), key


# --- the matcher itself ------------------------------------------------------------------------
_DIPNET = entry("DiPNet")


def _wrap(text: str, width: int = 95) -> str:
    words, lines, line = text.split(), [], ""
    for w in words:
        if line and len(line) + 1 + len(w) > width:
            lines.append(line)
            line = w
        else:
            line = f"{line} {w}" if line else w
    return "\n".join([*lines, line])


def test_the_matcher_accepts_canonical_entries_wrapped_anywhere():
    block = _wrap(_DIPNET, 60) + "\n\n" + _wrap(entry("Kay"), 70) + "\n"
    assert mismatches(block) == []
    # two entries without a blank line between them
    assert mismatches(_wrap(_DIPNET) + "\n" + _wrap(entry("Bell")) + "\n") == []


@pytest.mark.parametrize(
    "variant",
    [
        # abbreviated authors and venue
        'DiPNet: S. Zhang, E. Staudinger, T. Jost et al., "Distributed Direct Localization '
        'Suitable for Dense Networks," IEEE Trans. Aerosp. Electron. Syst. 56(2), 2020.',
        # a note appended to the canonical text
        _DIPNET.rstrip(".") + " (§III-C, Table I).",
        # the paper without its short name
        _DIPNET.removeprefix("DiPNet: "),
        # a short name with another text
        "PF-BP: the particle-flow BP paper, eq. (32) (regularization by Gaussian jitter).",
        # the title in another wording of the authors
        'R. Mendrzik and G. Bauch, "Position-Constrained Stochastic Inference for Cooperative '
        'Indoor Localization." ("POA-NBP").',
    ],
)
def test_the_matcher_catches_a_variant(variant):
    assert mismatches(_wrap(variant) + "\n")


def test_other_sources_may_carry_their_own_notes():
    note = entry("HDF5").replace("including its virtual datasets (VDS)", "its dimension scales")
    assert mismatches(_wrap(note) + "\n") == []
    assert mismatches(_wrap("NIST FIPS 180-4. " + entry("SeedSequence")) + "\n") == []
    wrong = entry("Kay").replace("S. M. Kay", "S. Kay")
    assert mismatches(_wrap(wrong) + "\n")


def test_a_section_after_references_is_not_read():
    doc = f"Title.\n\nReferences\n----------\n{_DIPNET}\n\nExamples\n--------\nDiPNet: other\n"
    (block,) = reference_blocks(doc)
    assert "other" not in block
    assert mismatches(block) == []
