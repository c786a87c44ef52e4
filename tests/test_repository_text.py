"""The repository speaks of itself only: no tracked file points outside the repository or talks
about how the project is developed.

Every file ``git ls-files`` lists (except the stored run outputs under ``docs/results/`` and
this file) is read as text and searched for

* paths outside the repository: the folder of shared development material beside the
  checkout, absolute paths of a development tree, and design or style notes the repository
  does not have;
* development-process talk: numbered work items, their tracker, briefs, notes of working
  sessions, how the project is steered, the machine the project is developed on.

The patterns and the sample lines below are assembled from pieces, so that this file does not
itself contain the text it looks for.

A finding names ``file:line`` and the matched text; all findings are reported at once.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SELF = Path(__file__).resolve().relative_to(ROOT).as_posix()

#: Tracked folders whose files are not prose of the project (stored run outputs).
EXCLUDED_PREFIXES = ("docs/results/",)

SH = "sha" + "red"  # the folder of development material beside the checkout
WORK = "/wo" + "rk/"  # the development tree's absolute path
DESIGN, STYLE = "DESI" + "GN.md", "STY" + "LE.md"

#: (what is wrong, pattern). Patterns are case-insensitive.
OUTSIDE = [
    ("a path outside the repository", rf"\.\./{SH}\b"),
    ("a path outside the repository", rf"\b{SH}/(?:reference|papers)\b"),
    ("an absolute path of a development tree", rf"(?<![\w.~]){WORK}"),
]
#: Files the repository does not have but older text pointed to.
MISSING_FILES = (DESIGN, STYLE)
PROCESS = [
    ("development-process talk", r"\bissues?\s\d+"),
    ("development-process talk", r"\bissue\stracker"),
    ("development-process talk", r"\bthe\sbrief\b|\bbrief" r"'s\b"),
    ("development-process talk", r"\bsession\snotes\b"),
    ("development-process talk", r"\bsteer" r"ing\b(?! vector)"),
    ("development-process talk", r"\bdevelopment\smachine\b"),
]


def _patterns(root: Path = ROOT) -> list[tuple[str, re.Pattern]]:
    rules = [*OUTSIDE, *PROCESS]
    for name in MISSING_FILES:
        if not (root / name).exists():
            rules.append((f"{name}, a file the repository does not have", re.escape(name)))
    return [(why, re.compile(p, re.I)) for why, p in rules]


def findings(text: str, name: str, patterns=None) -> list[str]:
    """Every offending passage of ``text`` as ``name:line: what (matched text)``."""
    patterns = _patterns() if patterns is None else patterns
    out = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        for why, pattern in patterns:
            for m in pattern.finditer(line):
                out.append(f"{name}:{lineno}: {why} ({m.group(0)!r})")
    return out


def tracked_files() -> list[str]:
    """The repository's tracked files, or a skip naming why they cannot be listed."""
    git = shutil.which("git")
    if git is None:
        pytest.skip("git is not installed, so the tracked files cannot be listed")
    try:
        done = subprocess.run(
            [git, "-C", str(ROOT), "ls-files", "-z"],
            capture_output=True,
            timeout=60,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"git ls-files could not run: {exc}")
    if done.returncode != 0:
        pytest.skip(
            f"{ROOT} is not a git checkout (git ls-files: {done.stderr.decode().strip()}), "
            "so the tracked files cannot be listed"
        )
    return [p for p in done.stdout.decode().split("\0") if p]


def _text(path: Path) -> str | None:
    try:
        data = path.read_bytes()
    except OSError:  # listed but absent (e.g. deleted in the work tree)
        return None
    if b"\0" in data[:8192]:
        return None  # binary
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def test_no_tracked_file_points_outside_or_talks_process():
    patterns = _patterns()
    report = []
    for name in tracked_files():
        if name == SELF or name.startswith(EXCLUDED_PREFIXES):
            continue
        text = _text(ROOT / name)
        if text is not None:
            report += findings(text, name, patterns)
    assert not report, f"{len(report)} passages to rewrite:\n" + "\n".join(report)


# --- the matcher itself ------------------------------------------------------------------------
#: Lines of the repository's earlier text that the check must catch.
EARLIER = [
    f"to them); `../{SH}/{DESIGN}` describes the architecture.",
    "Wall time on the 2-core " + "development" + " machine with `--workers 2` and warm caches",
    f"The WINNER II files were written from `{SH}/reference/winner2/`, which gives the sources,",
    f"# Written for phyloc from {SH}/reference/winner2/c2_los.toml. Keys and formulas:",
    f"The package is layered (see ``{DESIGN}``): :mod:`phyloc.phy` and :mod:`phyloc.channels`",
    "    # " + "iss" + "ue 3: 66 % ± 1 % (C2) and 95 % ± 1 % (D1); DiPNet reports 65.6 %",
    f"#: Short names of the sources an equation number may refer to (papers in ../{SH}/papers,",
    "    exactly the " + "bri" + "ef's channel-estimate form ``y_n = R_n/S_n``",
    "the numbers come from the runs recorded in the " + "iss" + "ue tracker's closing notes",
    "the filter collapses (" + "iss" + "ue 5), so",
    f"see {WORK}{SH}/papers/dipnet-direct-localization.md",
    "as agreed in the " + "ses" + "sion notes",
    "the " + "steer" + "ing file asks for",
]

#: Lines of today's text that must pass.
LEGITIMATE = [
    "its target options (numba issue #6845). ``njit(cache=True)(kernel.py_func)`` shares",
    "phyloc generate datasets/quickstart_c2.toml -o /shared/qs.h5 --scheduler tcp://host:8786",
    "larger than the shared 32 MB L3 cache",
    "a shard beyond this machine's memory names the shard",
    "the beam's " + "steer" + "ing vector",
    "`channels/PROVENANCE.md` gives, for each WINNER II file and parameter group, the table",
    "the design page, ``docs/guide/design.rst``",
    f"phyloc: ~{WORK} is a folder of the user",
]


@pytest.mark.parametrize("line", EARLIER)
def test_the_matcher_catches_earlier_text(line):
    assert findings(line, "x", _patterns(Path("/nonexistent")))


@pytest.mark.parametrize("line", LEGITIMATE)
def test_the_matcher_passes_todays_text(line):
    assert findings(line, "x", _patterns(Path("/nonexistent"))) == []


def test_a_file_the_repository_has_may_be_named(tmp_path):
    (tmp_path / DESIGN).write_text("design")
    assert findings(f"see {DESIGN}", "x", _patterns(tmp_path)) == []
    assert findings(f"see {DESIGN}", "x", _patterns(tmp_path / "sub"))


def test_findings_name_file_and_line():
    text = f"fine\nsee ../{SH}/{DESIGN}\n"
    got = findings(text, "README.md", _patterns(Path("/nonexistent")))
    assert got and all(g.startswith("README.md:2: ") for g in got)
