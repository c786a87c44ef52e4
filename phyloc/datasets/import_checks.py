"""The checks ``phyloc import`` applies to recorded arrays, as a table (:data:`CHECKS`).

Each input array of :data:`INPUTS` must have a shape, a dtype and values that fit the others
(``datasets/README.md``, "Importing recorded snapshots"). :data:`CHECKS` states them as rows
of :class:`~phyloc.datasets.array_checks.ArrayCheck`: one per input (its symbolic shapes such
as ``"K, L, N"``, the sizes it defines, the dtype kinds it accepts, its value rules, each with
its message), then rows that relate checked arrays (the recorded link rows against the nodes,
the samples of every recorded row, the pilots of every transmitter).
:func:`check_arrays` runs the table once, in order
(:func:`~phyloc.datasets.array_checks.run_checks`), so an array is checked only after every
size it refers to is known; the first failing rule raises a
:class:`~phyloc.errors.ValidationError` naming the array, what was seen (its shape, dtype,
value or the offending entry) and what is expected. It then brings the arrays into the stored
order (:class:`CheckedArrays`).

Sizes: ``R`` realizations (a leading axis every per-realization array carries if
``received`` does), ``K`` snapshots, ``L`` link rows, ``N`` subcarriers, ``n`` nodes,
``n_anchors`` anchors, ``D`` (2 or 3) coordinates.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
(The OFDM signal model of the received symbols, pilots and noise.)

NumPy, "Data type objects: ``dtype.kind``",
https://numpy.org/doc/stable/reference/generated/numpy.dtype.kind.html.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from phyloc.datasets.array_checks import (
    FLAGS,
    ArrayCheck,
    CheckContext,
    Defines,
    Exclusive,
    Requirement,
    Rule,
    run_checks,
)
from phyloc.errors import ValidationError
from phyloc.phy.system import K_BOLTZMANN, OFDMSystem

#: The arrays :func:`check_arrays` reads, by name: (shape without the realization axis,
#: meaning). ``K`` snapshots, ``L`` link rows, ``N`` subcarriers, ``n`` nodes, ``D`` 2 or 3.
INPUTS = {
    "received": ("[K, L, N] complex", "frequency-domain received symbols R_n [sqrt(W)]"),
    "links": ("[L, 2] or [K, L, 2] int", "link (u, v): node u receives from node v"),
    "link_mask": ("[K, L] bool", "1 for a recorded link row (default: every row)"),
    "link_count": ("[K] int", "the first link_count[t] rows of snapshot t are recorded"),
    "symbols": ("[n, N] complex", "pilot symbols S_n of each node as transmitter"),
    "is_anchor": ("[n] bool", "1 for anchors (known positions)"),
    "anchor_positions": ("[n_anchors, D] float", "anchor positions [m], in node order"),
    "positions": ("[K, n, D] float", "ground-truth positions of every node [m]"),
    "los": ("[K, L] bool", "ground truth: 1 for a line-of-sight link"),
    "subcarrier_spacing_hz": ("scalar", "subcarrier spacing f_sc [Hz]"),
    "n_subcarriers": ("scalar", "N (checked against received)"),
    "carrier_frequency_hz": ("scalar", "carrier frequency [Hz] (metadata)"),
    "tx_power_dbm": ("scalar", "transmit power [dBm] (metadata)"),
    "noise_variance_w": ("scalar", "noise variance sigma^2 of R_n per subcarrier [W]"),
    "temperature_k": ("scalar", "noise temperature [K] (with noise_figure_db)"),
    "noise_figure_db": ("scalar", "receiver noise figure [dB] (with temperature_k)"),
    "ways": ("scalar", "1 (one-way) or 2 (two-way ranging: delays are round trips)"),
    "dt_s": ("scalar", "time between snapshots [s]"),
    "dim": ("scalar", "2 or 3 (only needed without positions and anchors)"),
    "recipe": ("text", "TOML recipe: seed, name, [channel], [ranging], [localization], ..."),
}
REQUIRED = ("received", "links", "symbols", "is_anchor", "subcarrier_spacing_hz", "ways")


# -- what the checks know --------------------------------------------------------------------------
class _Context(CheckContext):
    """The check context with what the link checks and the stored order derive."""

    def where(self, r, t) -> str:
        """The place of snapshot t of realization r, as the errors name it."""
        return f"realization {r}, snapshot {t}" if self.lead else f"snapshot {t}"

    @cached_property
    def mask(self) -> np.ndarray:
        """[R, K, L] bool: the recorded link rows."""
        R, K, L = (self.sizes[s] for s in "RKL")
        if "link_mask" in self.arrays:
            return self.arrays["link_mask"]
        if "link_count" in self.arrays:
            return np.arange(L) < self.arrays["link_count"][..., None]
        return np.ones((R, K, L), bool)

    @cached_property
    def node_order(self) -> np.ndarray:
        """[R, n]: the input index of each stored node (agents first, anchors last; stable)."""
        an = self.arrays["is_anchor"]
        return np.stack([np.r_[np.flatnonzero(~a), np.flatnonzero(a)] for a in an])

    @cached_property
    def rows(self) -> dict:
        """(r, t) -> (recorded rows sorted by their stored (u, v), those stored pairs)."""
        links, out = self.arrays["links"], {}
        R, K, n = (self.sizes[s] for s in "RKn")
        for r in range(R):
            inv = np.empty(n, np.int64)
            inv[self.node_order[r]] = np.arange(n)
            for t in range(K):
                rows = np.flatnonzero(self.mask[r, t])
                new = inv[links[r, t, rows]]
                order = np.lexsort((new[:, 1], new[:, 0]))
                out[r, t] = rows[order], new[order]
        return out


# -- rules: each returns the offending value an error shows, or None -------------------------------
def _non_finite(a, c):
    return None if np.all(np.isfinite(a)) else "non-finite entries"


def _not_positive(x, c):
    return x if x <= 0 else None


def _negative(x, c):
    return x if x < 0 else None


def _one_of(*allowed):
    return lambda x, c: None if x in allowed else x


def _no_empty_axis(a, c):
    return f"array of shape {a.shape}" if min(c.sizes["K"], c.sizes["L"]) < 1 else None


def _odd_subcarriers(a, c):
    N = c.sizes["N"]
    return f"array of shape {c.inputs['received'].shape}" if N < 3 or N % 2 == 0 else None


def _count_in_range(a, c):
    L = c.sizes["L"]
    if a.min() < 0 or a.max() > L:
        return int(a.max()) if a.max() > L else int(a.min())
    return None


def _same_anchor_count(an, c):
    per = an.sum(axis=1)
    return f"{per.tolist()} anchors per realization" if np.any(per != per[0]) else None


def _enough_agents(an, c):
    n, n_anchors = an.shape[1], int(an[0].sum())
    n_agents = n - n_anchors
    if n_agents < 1 or n < 2 or (n_anchors == 0 and n_agents < 2):
        return f"{n_agents} agents, {n_anchors} anchors"
    return None


def _static_anchors(positions, c):
    an = c.arrays["is_anchor"]
    for r in range(c.sizes["R"]):
        ap = positions[r][:, an[r]]
        if np.any(ap != ap[:1]):
            return f"moving anchors in realization {r}"
    return None


def _anchors_match_positions(ap, c):
    if "positions" not in c.arrays:
        return None
    positions, an = c.arrays["positions"], c.arrays["is_anchor"]
    for r in range(c.sizes["R"]):
        if not np.allclose(positions[r][0, an[r]], ap[r], rtol=0.0, atol=1e-6):
            return f"realization {r}"
    return None


def _dim_known(_, c):
    return None if "D" in c.sizes else "missing"


def _some_link(_, c):
    return None if c.mask.any() else "no recorded link"


def _first_link(bad, c):
    """The first recorded row where ``bad`` [R, K, L] holds, as the links errors show it."""
    hit = np.argwhere(bad & c.mask)
    if not hit.size:
        return None
    r, t, row = hit[0]
    return f"{tuple(c.arrays['links'][r, t, row].tolist())} at {c.where(r, t)}, row {row}"


def _nodes_in_range(lk, c):
    return _first_link(((lk < 0) | (lk >= c.sizes["n"])).any(axis=-1), c)


def _no_self_link(lk, c):
    return _first_link(lk[..., 0] == lk[..., 1], c)


def _no_anchor_pair(lk, c):
    an = c.arrays["is_anchor"]
    safe = np.where(c.mask[..., None], lk, 0)
    r = np.arange(c.sizes["R"])[:, None, None]
    return _first_link(an[r, safe[..., 0]] & an[r, safe[..., 1]], c)


def _no_duplicate(lk, c):
    for (r, t), (rows, new) in c.rows.items():
        dup = np.flatnonzero((np.diff(new, axis=0) == 0).all(axis=1))
        if dup.size:
            return f"{tuple(lk[r, t, rows[dup[0]]].tolist())} twice at {c.where(r, t)}"
    return None


def _finite_recorded_rows(rx, c):
    for (r, t), (rows, _) in c.rows.items():
        data = rx[r, t, rows]
        if not np.all(np.isfinite(data)):
            k = int(np.flatnonzero(~np.isfinite(data).all(axis=1))[0])
            return f"non-finite values at {c.where(r, t)}, link row {rows[k]}"
    return None


def _transmitters_have_pilots(sym, c):
    lk = c.arrays["links"]
    for r in range(c.sizes["R"]):
        tx = sorted({v for t in range(c.sizes["K"]) for v in lk[r, t, c.rows[r, t][0], 1].tolist()})
        silent = [v for v in tx if not np.any(sym[r, v] != 0)]
        if silent:
            return f"all-zero pilots of node {silent[0]}" + (
                f" in realization {r}" if c.lead else ""
            )
    return None


# -- conversions to the checked form ---------------------------------------------------------------
def _links(a, c):
    lk = c.per_real(a).astype(np.int64)
    if lk.ndim == 3:  # [R, L, 2]: the same links in every snapshot
        lk = np.broadcast_to(lk[:, None], (c.sizes["R"], c.sizes["K"], *lk.shape[1:]))
    return lk


def _as(dtype):
    return lambda a, c: c.per_real(a).astype(dtype)


def _positions(a, c):
    positions = np.full(tuple(c.sizes[s] for s in ("R", "K", "n", "D")), np.nan)
    positions[:] = c.per_real(a)
    return positions


def _at_least_2d(c):  # positions define D from their last axis
    return range(2, 65)


_D = {"D": (2, 3)}  # the coordinates of a position
_NOISE = (
    "required: the noise variance sigma^2 [W] of R_n per subcarrier (noise_variance_w), or "
    "temperature_k and noise_figure_db"
)

#: The checks, in the order they run (a size must be defined before a row refers to it).
CHECKS: tuple[ArrayCheck, ...] = (
    # received defines the realization axis, K, L and N
    ArrayCheck(
        "received",
        shape=("K, L, N",),
        kinds="c",
        what="complex frequency-domain symbols R_n",
        defines=Defines(
            ("R", "K", "L", "N"),
            lambda c: (3, 4),
            "expected [K, L, N] (snapshot, link, subcarrier) or [R, K, L, N] with a leading "
            "realization axis",
        ),
        values=(
            Rule(_no_empty_axis, "K >= 1 and L >= 1"),
            Rule(
                _odd_subcarriers,
                "the last axis is N = {N} subcarriers; N must be odd and >= 3 (column j is "
                "subcarrier n = j - (N-1)/2)",
            ),
        ),
    ),
    ArrayCheck(
        "n_subcarriers",
        scalar="int",
        values=(
            Rule(lambda x, c: x if x != c.sizes["N"] else None, "received has N = {N} subcarriers"),
        ),
    ),
    ArrayCheck(
        "links",
        shape=("L, 2", "K, L, 2"),
        hint="(u, v) per row",
        kinds="iu",
        what="integer node indices",
        convert=_links,
    ),
    # which link rows are recorded: link_count or link_mask (default: all)
    ArrayCheck(
        "link_count",
        shape=("K",),
        kinds="iu",
        what="integer counts",
        excludes=Exclusive(("link_mask",), "give link_mask or link_count, not both"),
        convert=_as(np.int64),
        values=(Rule(_count_in_range, "every count must be in 0 … L = {L}"),),
    ),
    ArrayCheck("link_mask", shape=("K, L",), kinds=FLAGS),
    ArrayCheck("link_mask", values=(Rule(_some_link, "at least one link is required"),)),
    # the nodes: is_anchor defines n
    ArrayCheck(
        "is_anchor",
        shape=("n",),
        kinds=FLAGS,
        defines=Defines(("n",), lambda c: (1 + c.lead,), "expected [{shape}] (one flag per node)"),
        values=(
            Rule(_same_anchor_count, "every realization needs the same number of anchors"),
            Rule(_enough_agents, "at least one agent, and two agents without anchors"),
        ),
        fixes=lambda an, c: {"n_anchors": int(an[0].sum()), "last_node": c.sizes["n"] - 1},
    ),
    ArrayCheck(
        "symbols",
        shape=("n, N",),
        hint="pilots of every node",
        kinds="iufc",
        what="complex pilot symbols",
        convert=_as(np.complex128),
        values=(Rule(_non_finite, "every pilot must be finite"),),
    ),
    # geometry: D from dim, else from positions, else from anchor_positions
    ArrayCheck(
        "dim",
        scalar="int",
        values=(Rule(_one_of(2, 3), "2 or 3"),),
        fixes=lambda dim, c: {"D": dim},
    ),
    ArrayCheck(
        "positions",
        shape=("K, n, D",),
        hint="ground truth [m]",
        kinds="iuf",
        what="real numbers",
        defines=Defines(("D",), _at_least_2d, "expected [{shape}], D = 2 or 3", _D),
        convert=_positions,
        values=(
            Rule(_non_finite, "every ground-truth position must be finite"),
            Rule(_static_anchors, "anchors must be static"),
        ),
    ),
    ArrayCheck(
        "anchor_positions",
        shape=("n_anchors, D",),
        kinds="iuf",
        what="real numbers",
        defines=Defines(("D",), _at_least_2d, "expected [{shape}], D = 2 or 3", _D),
        required=Requirement(
            lambda c: c.sizes["n_anchors"] and "positions" not in c.inputs,
            "required with {n_anchors} anchors and no positions: [{prefix}n_anchors, D] [m]",
        ),
        convert=_as(np.float64),
        values=(
            Rule(_non_finite, "must be finite [m]"),
            Rule(
                _anchors_match_positions,
                "differs from the anchor rows of positions (by more than 1 µm)",
            ),
        ),
    ),
    ArrayCheck(
        "dim",
        values=(Rule(_dim_known, "required without positions and anchor_positions: 2 or 3"),),
    ),
    ArrayCheck("los", shape=("K, L",), hint="per link row, like received", kinds=FLAGS),
    # system and ranging
    ArrayCheck(
        "subcarrier_spacing_hz", scalar="real", values=(Rule(_not_positive, "must be > 0 Hz"),)
    ),
    ArrayCheck(
        "ways",
        scalar="int",
        values=(Rule(_one_of(1, 2), "1 (one-way) or 2 (two-way ranging)"),),
    ),
    ArrayCheck(
        "noise_variance_w",
        scalar="real",
        excludes=Exclusive(
            ("temperature_k", "noise_figure_db"),
            "give the measured noise variance or temperature_k and noise_figure_db",
        ),
        required=Requirement(
            lambda c: "temperature_k" not in c.inputs and "noise_figure_db" not in c.inputs,
            _NOISE,
        ),
        values=(Rule(_not_positive, "must be > 0 W"),),
    ),
    ArrayCheck(
        "temperature_k",
        scalar="real",
        required=Requirement(lambda c: "noise_variance_w" not in c.inputs, _NOISE),
        values=(Rule(_not_positive, "must be > 0 K"),),
    ),
    ArrayCheck(
        "noise_figure_db",
        scalar="real",
        required=Requirement(lambda c: "noise_variance_w" not in c.inputs, _NOISE),
        values=(Rule(_negative, "must be >= 0 dB"),),
    ),
    ArrayCheck(
        "carrier_frequency_hz", scalar="real", values=(Rule(_not_positive, "must be > 0 Hz"),)
    ),
    ArrayCheck("tx_power_dbm", scalar="real"),
    ArrayCheck("dt_s", scalar="real", values=(Rule(_not_positive, "must be > 0 s"),)),
    # the recorded link rows, on the input's node indices
    ArrayCheck(
        "links",
        values=(
            Rule(_nodes_in_range, "node indices must be in 0 … n - 1 = {last_node}"),
            Rule(_no_self_link, "a node does not receive from itself"),
            Rule(
                _no_anchor_pair,
                "anchor-anchor pairs are not links; leave them out with link_mask",
            ),
            Rule(_no_duplicate, "each directed link at most once per snapshot"),
        ),
    ),
    ArrayCheck(
        "received",
        values=(
            Rule(
                _finite_recorded_rows,
                "every recorded link needs finite symbols (mask missing rows out)",
            ),
        ),
    ),
    ArrayCheck(
        "symbols",
        values=(Rule(_transmitters_have_pilots, "every transmitting node needs pilot symbols"),),
    ),
)


# -- the stored order ------------------------------------------------------------------------------
@dataclass
class CheckedArrays:
    """The checked arrays in stored order (agents first, links sorted), realization axis first."""

    received: np.ndarray  # [R, K, Lmax, N] complex128, valid rows first
    counts: np.ndarray  # [R, K]
    pairs: np.ndarray  # [R, K, Lmax, 2] (-1 padding)
    symbols: np.ndarray  # [R, n, N] complex64
    is_anchor: np.ndarray  # [R, n] bool
    positions: np.ndarray  # [R, K, n, D] (NaN: unknown)
    los: np.ndarray | None  # [R, K, Lmax] bool
    node_order: np.ndarray  # [R, n] original index of each stored node
    system: OFDMSystem
    ways: int
    dt_s: float | None
    truth: tuple

    @property
    def shape(self):
        """(R, K, Lmax, N, n, D)."""
        R, K, L, N = self.received.shape
        return R, K, L, N, self.is_anchor.shape[1], self.positions.shape[-1]


def check_arrays(arrays: Mapping) -> CheckedArrays:
    """Check raw arrays (names of :data:`INPUTS`) and bring them into the stored order.

    Runs the rules of :data:`CHECKS` in order. Nodes are reordered agents first, anchors last
    (stable; ``node_order`` keeps the original index of each stored node), the recorded link
    rows of every snapshot are moved to the front and sorted by (u, v).

    Raises
    ------
    ValidationError
        Naming the array: missing, unknown name (with the closest valid one), wrong shape (the
        shape seen and the shape expected), wrong dtype, or inconsistent content (a node index
        out of range, a self-link, an anchor–anchor link, a duplicated link, non-finite
        samples or positions, moving anchors, contradicting noise parameters).
    """
    arrays = {k: np.asarray(val) for k, val in arrays.items()}
    for name in arrays:
        if name not in INPUTS:
            close = difflib.get_close_matches(name, list(INPUTS), n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ValidationError(name, "unknown array", f"{hint}valid names: {', '.join(INPUTS)}")
    for name in REQUIRED:
        if name not in arrays:
            shape, what = INPUTS[name]
            raise ValidationError(name, "missing", f"required: {shape}, {what}")
    c = _Context(arrays)
    run_checks(CHECKS, c)
    return _stored(c)


def _system(c: _Context) -> OFDMSystem:
    """The OFDM system the scalars describe; a noise variance becomes the noise temperature
    that gives it with a 0 dB noise figure (sigma^2 = k T B NF)."""
    got = c.arrays
    N, f_sc = c.sizes["N"], got["subcarrier_spacing_hz"]
    fields = {"n_subcarriers": N, "subcarrier_spacing_hz": f_sc, "oversampling": 1}
    if "noise_variance_w" in got:
        T = got["noise_variance_w"] / (K_BOLTZMANN * N * f_sc)
        fields.update(temperature_k=T, noise_figure_db=0.0)
    else:
        fields.update(temperature_k=got["temperature_k"], noise_figure_db=got["noise_figure_db"])
    for name in ("carrier_frequency_hz", "tx_power_dbm"):
        if name in got:
            fields[name] = got[name]
    return OFDMSystem(**fields)


def _stored(c: _Context) -> CheckedArrays:
    """The checked arrays in stored order: nodes agents first, recorded rows sorted."""
    got = c.arrays
    R, K, N, n = (c.sizes[s] for s in "RKNn")
    an, rx, sym = got["is_anchor"], got["received"], got["symbols"]
    positions = got.get("positions")
    if positions is None:
        positions = np.full((R, K, n, c.sizes["D"]), np.nan)
    if "anchor_positions" in got:
        for r in range(R):
            positions[r][:, an[r]] = got["anchor_positions"][r]
    system = _system(c)
    counts = c.mask.sum(axis=2)
    Lmax = max(1, int(counts.max()))
    received = np.zeros((R, K, Lmax, N), np.complex128)
    pairs = np.full((R, K, Lmax, 2), -1, np.int64)
    los = None if "los" not in got else np.zeros((R, K, Lmax), bool)
    symbols = np.zeros((R, n, N), np.complex64)
    is_anchor = np.zeros((R, n), bool)
    out_pos = np.empty_like(positions)
    for r in range(R):
        perm = c.node_order[r]
        is_anchor[r] = an[r][perm]
        out_pos[r] = positions[r][:, perm]
        for t in range(K):
            rows, new = c.rows[r, t]
            k = rows.size
            received[r, t, :k] = rx[r, t, rows]
            pairs[r, t, :k] = new
            if los is not None:
                los[r, t, :k] = got["los"][r, t, rows]
        symbols[r] = sym[r][perm]
    return CheckedArrays(
        received=received,
        counts=counts,
        pairs=pairs,
        symbols=symbols,
        is_anchor=is_anchor,
        positions=out_pos,
        los=los,
        node_order=c.node_order,
        system=system,
        ways=got["ways"],
        dt_s=got.get("dt_s"),
        truth=tuple(name for name in ("positions", "los") if name in got),
    )


__all__ = ["CHECKS", "INPUTS", "REQUIRED", "CheckedArrays", "check_arrays"]
