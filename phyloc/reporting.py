"""Machine-readable results (``--json PATH``) and plain-text tables for the command line.

Every command that reports numbers writes a JSON object (see :doc:`/guide/design`)::

    {"figures": {"name": number, ...},   # flat, documented, stable names
     "meta": {"phyloc_version": ..., "command": ..., "seed": ..., "machine": {...}},
     "series": {"name": [numbers...], ...}}   # optional: arrays behind a plot

Files are written atomically and an existing file is never replaced unless asked (``force``).

References
----------
T. Bray (ed.), "The JavaScript Object Notation (JSON) data interchange format," RFC 8259,
2017.
"""

from __future__ import annotations

import json
import math
import os
import platform
import re
from pathlib import Path

import numpy as np

from phyloc._files import write_atomic
from phyloc.errors import PhylocError


class OutputExistsError(PhylocError, FileExistsError):
    """An output file exists and overwriting it was not requested."""

    def __init__(self, path):
        super().__init__(f"{path} exists; choose another path or pass --force to replace it")


def machine_meta() -> dict:
    """Versions and hardware facts that a benchmark or result depends on."""
    import numba
    import scipy

    from phyloc import __version__
    from phyloc.phy import fft as phyfft

    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover
        cpus = os.cpu_count()
    return {
        "phyloc_version": __version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": cpus,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "numba_threads": numba.get_num_threads(),
        "fft_backend": phyfft.backend(),
        "fft_threads": phyfft.threads(),
    }


def _clean(x):
    """JSON-safe numbers: NumPy scalars to Python, NaN/inf to None (JSON has neither)."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return [_clean(v) for v in x.tolist()]
    if isinstance(x, (np.floating, float)):
        f = float(x)
        return f if math.isfinite(f) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


MEASUREMENT_SUFFIXES = ("_s", "_mb", "_exponent")
"""Endings of figure names that measure the machine (wall times, memory, fitted cost
exponents): they differ between runs of the same recipe; every other figure is a result of
the recipe and its seed alone."""

RESULT_SUFFIXES = ("_m_s",)
"""Endings that look like a time but are results: speeds in m/s (``rmse_v_m_s``)."""


#: Endings the runner appends to a figure's name for its interval and per-unit values
#: (:func:`phyloc.evaluation.statistics.resolve`).
INTERVAL_SUFFIXES = (".ci_low", ".ci_high", ".units")


def base_figure(name: str) -> str:
    """The figure an interval bound or a per-unit series belongs to.

    >>> base_figure("pfbp.s1_r18.step_s.ci_low"), base_figure("x.rmse_m")
    ('pfbp.s1_r18.step_s', 'x.rmse_m')
    """
    for suffix in INTERVAL_SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def is_measurement(name: str) -> bool:
    """Whether figure ``name`` measures the machine rather than the recipe (a wall time, a
    memory peak, a cost exponent: :data:`MEASUREMENT_SUFFIXES`; a ``runtime`` figure; a
    quantity whose last name part starts with ``time_``, such as a ratio of two wall times),
    also for its interval bounds and per-unit series (:func:`base_figure`).

    A speed in m/s (:data:`RESULT_SUFFIXES`) is a result, not a wall time:

    >>> is_measurement("dipnet.c2.agents_30.iteration_s"), is_measurement("c2.los_fraction")
    (True, False)
    >>> is_measurement("edh.scenario1.rmse_v_m_s"), is_measurement("pfbp.s1.step_s.ci_high")
    (False, True)
    >>> is_measurement("poa_nbp_vs_pbp.time_to_convergence_ratio")
    True
    """
    name = base_figure(name)
    if name.endswith(RESULT_SUFFIXES):
        return False
    last = name.rsplit(".", 1)[-1]
    return "runtime" in name or name.endswith(MEASUREMENT_SUFFIXES) or last.startswith("time_")


#: A JSON list of numbers (no nested list or object) as ``json.dumps(indent=2)`` writes it.
_FLAT_LIST = re.compile(r"\[(?:\s*(?:-?(?:\d|Infinity|NaN)[^,\]\s]*|null|true|false),?)+\s*\]")


def dumps_results(doc: dict) -> str:
    """``doc`` as indented JSON with every list of numbers on one line (a series of per-unit
    values is one line, not one line per number); ``json.loads`` gives ``doc`` back.

    >>> print(dumps_results({"a": [1, 2.5, None], "b": {"c": [[0, 1], [2, 3]]}}))
    {
      "a": [1, 2.5, null],
      "b": {
        "c": [
          [0, 1],
          [2, 3]
        ]
      }
    }
    """
    text = json.dumps(doc, indent=2, sort_keys=False)
    return _FLAT_LIST.sub(
        lambda m: "[" + ", ".join(m.group(0)[1:-1].split()).replace(",,", ",") + "]", text
    )


def write_json(path, figures: dict, meta: dict, series: dict | None = None, *, force=False):
    """Write the results object to ``path`` atomically; refuse to replace a file unless
    ``force``. Returns the path."""
    path = Path(path)
    if path.exists() and not force:
        raise OutputExistsError(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"figures": _clean(figures), "meta": _clean(meta)}
    if series:
        doc["series"] = _clean(series)
    return write_atomic(path, (dumps_results(doc) + "\n").encode())


def format_table(rows, headers) -> str:
    """A plain-text table: ``rows`` are sequences of cells (numbers get 4 significant digits)."""

    def cell(x):
        if x is None:
            return ""
        if isinstance(x, (float, np.floating)):
            x = float(x)
            if x != 0 and (abs(x) >= 1e5 or abs(x) < 1e-3):
                return f"{x:.4g}"
            return f"{x:.4g}" if abs(x) < 1e4 else f"{x:,.0f}"
        return str(x)

    cells = [[cell(c) for c in r] for r in rows]
    widths = [
        max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)
    ]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True))
    out = [line, "  ".join("-" * w for w in widths)]
    for r in cells:
        out.append(
            "  ".join(
                c.rjust(w) if i else c.ljust(w)
                for i, (c, w) in enumerate(zip(r, widths, strict=True))
            )
        )
    return "\n".join(out)


def with_interval(figures: dict, name: str):
    """The figure ``name`` with its 95 % interval as one table cell, ``"0.463 [0.41, 0.52]"``
    (3 significant digits), or the bare number when the run has no finite interval for it
    (a single unit, or a figure without one); None when the figure is missing.

    >>> with_interval({"a": 0.4631, "a.ci_low": 0.41, "a.ci_high": 0.5249}, "a")
    '0.463 [0.41, 0.525]'
    """
    x = figures.get(name)
    lo, hi = figures.get(name + ".ci_low"), figures.get(name + ".ci_high")
    if x is None or lo is None or hi is None or not (np.isfinite(lo) and np.isfinite(hi)):
        return x
    return f"{x:.3g} [{lo:.3g}, {hi:.3g}]"


def draw_interval(ax, x, figures: dict, names, color, *, alpha: float = 0.15) -> bool:
    """Shade the 95 % intervals of the figures ``names`` (one per ``x``) on ``ax``; returns
    whether there was one to draw (runs of a single unit have none)."""
    lo = np.array([_finite(figures.get(n + ".ci_low")) for n in names])
    hi = np.array([_finite(figures.get(n + ".ci_high")) for n in names])
    ok = np.isfinite(lo) & np.isfinite(hi)
    if not ok.any():
        return False
    ax.fill_between(np.asarray(x, dtype=float)[ok], lo[ok], hi[ok], color=color, alpha=alpha, lw=0)
    return True


def _finite(x) -> float:
    return math.nan if x is None else float(x)


#: One resolution for every figure phyloc writes [dots per inch].
FIGURE_DPI = 110


def new_figure(rows: int = 1, cols: int = 1, *, size=(6.4, 4.8), **subplots):
    """A matplotlib ``Figure`` (constrained layout) on its own Agg canvas and its axes
    (``Figure.subplots`` arguments; ``rows = 0``: no axes, the caller adds its own). No global
    backend is chosen, so a user's own plotting is untouched."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    if rows == 0 or cols == 0:  # no grid: the caller adds its own axes
        return fig, None
    return fig, fig.subplots(rows, cols, **subplots)


def save_figure(fig, path) -> None:
    """Write ``fig`` to ``path`` (PNG by its suffix) at :data:`FIGURE_DPI`, whole or not at
    all (:func:`phyloc._files.write_atomic`: a full disk names the path, the old file stays)."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, dpi=FIGURE_DPI, format=Path(path).suffix.lstrip(".").lower() or "png")
    write_atomic(path, buf.getvalue())


def grouped_bars(ax, labels, groups: dict, *, fontsize: int = 8) -> None:
    """Bars of ``groups`` (``{legend label: one value per x label}``) side by side per label."""
    import numpy as np

    x = np.arange(len(labels))
    width = 0.8 / len(groups)
    for j, (name, values) in enumerate(groups.items()):
        ax.bar(x + j * width, values, width, label=name)
    ax.set_xticks(x + 0.4 - width / 2, labels, rotation=20, fontsize=fontsize)
    ax.legend(fontsize=fontsize)
