"""Recorded OFDM snapshots as phyloc datasets: ``phyloc import`` and ``phyloc export``.

:func:`import_arrays` reads plain arrays — an ``.npz`` file, a plain HDF5 file of arrays or a
mapping of names to arrays — checks every one of them, and writes a dataset of the schema in
``datasets/README.md`` (a master file and one shard) that ``phyloc evaluate``, ``phyloc info
--verify`` and :func:`phyloc.datasets.open` accept. The array names are the interface; the
section "Importing recorded snapshots" of ``datasets/README.md`` gives each one's shape, dtype
and units:

* required: ``received`` ``[K, L, N]`` complex (frequency-domain symbols ``R_n`` of every
  link and snapshot), ``links`` ``[L, 2]`` or ``[K, L, 2]`` (node u receives from node v),
  ``symbols`` ``[n, N]`` (pilots), ``is_anchor`` ``[n]``, ``subcarrier_spacing_hz``, ``ways``
  and the noise: ``noise_variance_w`` or ``temperature_k`` with ``noise_figure_db``;
* required with anchors unless ``positions`` is given: ``anchor_positions``
  ``[n_anchors, D]``;
* optional: ``link_mask`` ``[K, L]`` or ``link_count`` ``[K]`` (links that vary between
  snapshots), ground truth ``positions`` ``[K, n, D]`` and ``los`` ``[K, L]``,
  ``carrier_frequency_hz``, ``tx_power_dbm``, ``n_subcarriers``, ``dt_s``, ``dim`` and
  ``recipe`` (TOML text whose ``seed``, ``name``, ``[channel] scenario``, ``[ranging]``,
  ``[localization]`` and ``[experiment]`` the dataset keeps for ``phyloc evaluate``).

Every array may carry a leading realization axis ``R`` (then all per-realization arrays do).
A missing, mis-shaped or inconsistent array raises :class:`~phyloc.errors.ValidationError`
naming the array, the shape seen and the shape expected; nothing is written then.

:func:`export_arrays` writes a dataset back to such arrays (realization axis included), so
``import_arrays(export_arrays(ds))`` stores the same received samples, pilots, links and
truth, and ``phyloc evaluate`` gives identical results on both files.

References
----------
The HDF Group, *HDF5 User's Guide*, https://docs.hdfgroup.org/; the h5py documentation,
https://docs.h5py.org/; NumPy, "numpy.savez" (the ``.npz`` format),
https://numpy.org/doc/stable/reference/generated/numpy.savez.html.

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import contextlib
import difflib
import hashlib
import json
import math
import os
import re
import uuid
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from phyloc import _validate as v
from phyloc.channels import ChannelSpec
from phyloc.config import Recipe, dumps_toml, load_recipe
from phyloc.datasets import schema as sc
from phyloc.datasets.spec import DatasetSpec
from phyloc.datasets.writer import DatasetPlan, _fsync, _h5_attrs, _lock, write_master
from phyloc.errors import ValidationError
from phyloc.network import NetworkSpec
from phyloc.phy.system import K_BOLTZMANN, OFDMSystem
from phyloc.phy.waveform import from_time_domain, to_time_domain
from phyloc.reporting import OutputExistsError

#: The arrays :func:`import_arrays` reads, by name: (shape without the realization axis,
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
_SCALARS = tuple(k for k, (shape, _) in INPUTS.items() if shape == "scalar")
#: Default scenario label of an imported dataset (``[channel] scenario`` of its recipe): a
#: label in figure names only, nothing is simulated.
DEFAULT_SCENARIO = "awgn"


# -- reading the source ---------------------------------------------------------------------
def read_arrays(source) -> dict:
    """The arrays of ``source`` by name: an ``.npz`` file, a plain HDF5 file (datasets at the
    root; nested ones are named ``group/name``) or a mapping of names to array-likes.

    Raises
    ------
    DatasetError
        The file does not exist or is not readable as ``.npz`` or HDF5.
    ValidationError
        An array that cannot be read without pickling, or a phyloc dataset given as source.
    """
    if isinstance(source, Mapping):
        return {str(k): np.asarray(val) for k, val in source.items()}
    path = Path(source)
    why = v.unreadable_file(path)
    if why:
        raise sc.DatasetError(f"source {why} (give an .npz or an HDF5 file)")
    if h5py.is_hdf5(path):
        out = {}
        with h5py.File(path, "r") as f:
            if sc._text(f.attrs.get("format", "")).startswith(sc.MASTER_FORMAT):
                raise ValidationError(
                    "source",
                    str(path),
                    "is already a phyloc dataset: evaluate it directly, or export it first "
                    "(phyloc export) to get plain arrays",
                )

            def take(name, obj):
                if isinstance(obj, h5py.Dataset):
                    data = obj[()]
                    if isinstance(data, bytes):
                        data = data.decode()
                    out[name] = np.asarray(data)

            f.visititems(take)
        return out
    try:
        z = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise sc.DatasetError(
            f"cannot read {path} as .npz or HDF5 ({type(exc).__name__}: {exc})"
        ) from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise ValidationError("source", str(path), "an .npz file of named arrays, not one .npy")
    out = {}
    with z:
        for name in z.files:
            try:
                out[name] = z[name]
            except ValueError:
                raise ValidationError(
                    name, "object array", "plain numeric or text arrays (no pickled objects)"
                ) from None
    return out


# -- checks ---------------------------------------------------------------------------------
def _shape_error(name, a, options, what=None):
    expected = " or ".join(f"[{sym}] = {shape}" for sym, shape in options)
    extra = f"; {what}" if what else ""
    return ValidationError(name, f"array of shape {tuple(a.shape)}", f"expected {expected}{extra}")


def _match(name, a, options, what=None) -> int:
    """Index of the first (symbolic, concrete) shape option that ``a`` has; else an error."""
    for i, (_, shape) in enumerate(options):
        if tuple(a.shape) == tuple(shape):
            return i
    raise _shape_error(name, a, options, what)


def _scalar(arrays, name, *, required=False, kind="real"):
    if name not in arrays:
        if required:
            raise ValidationError(name, "missing", f"required: {INPUTS[name][1]}")
        return None
    a = np.asarray(arrays[name])
    if a.size != 1:
        raise ValidationError(name, f"array of shape {a.shape}", "expected a scalar, shape ()")
    x = a.reshape(()).item()
    if a.dtype.kind not in "iuf":
        raise ValidationError(name, x, "a real number is required")
    if kind == "int" and float(x) != int(x):
        raise ValidationError(name, x, "an integer is required")
    x = int(x) if kind == "int" else float(x)
    if not math.isfinite(x):
        raise ValidationError(name, x, "must be finite")
    return x


def _flags(name, a):
    """A 0/1 or bool array as bool."""
    if a.dtype.kind == "b":
        return a.astype(bool)
    if a.dtype.kind not in "iuf" or not np.all((a == 0) | (a == 1)):
        raise ValidationError(name, f"{a.dtype} array", "expected bool (or 0/1) values")
    return a.astype(bool)


def _numeric(name, a, kinds="iuf", what="real numbers"):
    if a.dtype.kind not in kinds:
        raise ValidationError(name, f"{a.dtype} array", f"expected {what}")
    return a


@dataclass
class _Data:
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
        R, K, L, N = self.received.shape
        return R, K, L, N, self.is_anchor.shape[1], self.positions.shape[-1]


def check_arrays(arrays: Mapping) -> _Data:
    """Check raw arrays (names of :data:`INPUTS`) and bring them into the stored order.

    Nodes are reordered agents first, anchors last (stable; ``node_order`` keeps the original
    index of each stored node), the recorded link rows of every snapshot are moved to the front
    and sorted by (u, v).

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

    # received: fixes R (optional), K, L, N
    rx = arrays["received"]
    if rx.ndim not in (3, 4):
        raise ValidationError(
            "received",
            f"array of shape {rx.shape}",
            "expected [K, L, N] (snapshot, link, subcarrier) or [R, K, L, N] with a leading "
            "realization axis",
        )
    if rx.dtype.kind != "c":
        raise ValidationError(
            "received", f"{rx.dtype} array", "expected complex frequency-domain symbols R_n"
        )
    lead = rx.ndim == 4
    rx = rx if lead else rx[None]
    R, K, L, N = rx.shape
    if min(K, L) < 1:
        raise ValidationError("received", f"array of shape {rx.shape}", "K >= 1 and L >= 1")
    if N < 3 or N % 2 == 0:
        raise ValidationError(
            "received",
            f"array of shape {arrays['received'].shape}",
            f"the last axis is N = {N} subcarriers; N must be odd and >= 3 (column j is "
            "subcarrier n = j - (N-1)/2)",
        )
    n_sc = _scalar(arrays, "n_subcarriers", kind="int")
    if n_sc is not None and n_sc != N:
        raise ValidationError("n_subcarriers", n_sc, f"received has N = {N} subcarriers")
    pre, prefix = ((R,), "R, ") if lead else ((), "")

    def opts(*pairs):
        return [(prefix + sym, (*pre, *shape)) for sym, shape in pairs]

    def per_real(a):
        return a if lead else a[None]

    # links
    lk = arrays["links"]
    i = _match("links", lk, opts(("L, 2", (L, 2)), ("K, L, 2", (K, L, 2))), "(u, v) per row")
    _numeric("links", lk, "iu", "integer node indices")
    lk = per_real(lk).astype(np.int64)
    if i == 0:
        lk = np.broadcast_to(lk[:, None], (R, K, L, 2))

    # which rows are recorded
    if "link_mask" in arrays and "link_count" in arrays:
        raise ValidationError(
            "link_count", "given with link_mask", "give link_mask or link_count, not both"
        )
    if "link_mask" in arrays:
        m = arrays["link_mask"]
        _match("link_mask", m, opts(("K, L", (K, L))))
        mask = per_real(_flags("link_mask", m))
    elif "link_count" in arrays:
        c = arrays["link_count"]
        _match("link_count", c, opts(("K", (K,))))
        _numeric("link_count", c, "iu", "integer counts")
        c = per_real(c).astype(np.int64)
        if c.min() < 0 or c.max() > L:
            bad = int(c.max()) if c.max() > L else int(c.min())
            raise ValidationError("link_count", bad, f"every count must be in 0 … L = {L}")
        mask = np.arange(L) < c[..., None]
    else:
        mask = np.ones((R, K, L), bool)
    if not mask.any():
        raise ValidationError("link_mask", "no recorded link", "at least one link is required")

    # nodes
    an = arrays["is_anchor"]
    if an.ndim != (2 if lead else 1):
        raise ValidationError(
            "is_anchor",
            f"array of shape {an.shape}",
            f"expected [{prefix}n] (one flag per node)",
        )
    an = per_real(_flags("is_anchor", an))
    n = an.shape[1]
    if an.shape[0] != R:
        raise _shape_error("is_anchor", arrays["is_anchor"], opts(("n", (n,))))
    n_anchors = int(an[0].sum())
    if np.any(an.sum(axis=1) != n_anchors):
        raise ValidationError(
            "is_anchor",
            f"{an.sum(axis=1).tolist()} anchors per realization",
            "every realization needs the same number of anchors",
        )
    n_agents = n - n_anchors
    if n_agents < 1 or n < 2 or (n_anchors == 0 and n_agents < 2):
        raise ValidationError(
            "is_anchor",
            f"{n_agents} agents, {n_anchors} anchors",
            "at least one agent, and two agents without anchors",
        )
    sym = arrays["symbols"]
    _match("symbols", sym, opts(("n, N", (n, N))), "pilots of every node")
    _numeric("symbols", sym, "iufc", "complex pilot symbols")
    sym = per_real(sym).astype(np.complex128)
    if not np.all(np.isfinite(sym)):
        raise ValidationError("symbols", "non-finite entries", "every pilot must be finite")

    # geometry: dimension, anchors, truth
    pos_in = arrays.get("positions")
    anc_in = arrays.get("anchor_positions")
    dim = _scalar(arrays, "dim", kind="int")
    for name, a in (("positions", pos_in), ("anchor_positions", anc_in)):
        if a is not None:
            if a.ndim < 2 or a.shape[-1] not in (2, 3):
                sym_shape = "K, n, D" if name == "positions" else "n_anchors, D"
                raise ValidationError(
                    name, f"array of shape {a.shape}", f"expected [{prefix}{sym_shape}], D = 2 or 3"
                )
            dim = dim if dim is not None else int(a.shape[-1])
    if dim is None:
        raise ValidationError(
            "dim", "missing", "required without positions and anchor_positions: 2 or 3"
        )
    if dim not in (2, 3):
        raise ValidationError("dim", dim, "2 or 3")
    positions = np.full((R, K, n, dim), np.nan)
    if pos_in is not None:
        _match("positions", pos_in, opts(("K, n, D", (K, n, dim))), "ground truth [m]")
        _numeric("positions", pos_in)
        positions[:] = per_real(pos_in)
        if not np.all(np.isfinite(positions)):
            raise ValidationError(
                "positions", "non-finite entries", "every ground-truth position must be finite"
            )
        for r in range(R):
            ap = positions[r][:, an[r]]
            if np.any(ap != ap[:1]):
                raise ValidationError(
                    "positions", f"moving anchors in realization {r}", "anchors must be static"
                )
    if anc_in is not None:
        _match("anchor_positions", anc_in, opts(("n_anchors, D", (n_anchors, dim))))
        _numeric("anchor_positions", anc_in)
        ap = per_real(anc_in).astype(np.float64)
        if not np.all(np.isfinite(ap)):
            raise ValidationError("anchor_positions", "non-finite entries", "must be finite [m]")
        for r in range(R):
            if pos_in is not None and not np.allclose(
                positions[r][0, an[r]], ap[r], rtol=0.0, atol=1e-6
            ):
                raise ValidationError(
                    "anchor_positions",
                    f"realization {r}",
                    "differs from the anchor rows of positions (by more than 1 µm)",
                )
            positions[r][:, an[r]] = ap[r]
    elif n_anchors and pos_in is None:
        raise ValidationError(
            "anchor_positions",
            "missing",
            f"required with {n_anchors} anchors and no positions: [{prefix}n_anchors, D] [m]",
        )
    los_in = arrays.get("los")
    if los_in is not None:
        _match("los", los_in, opts(("K, L", (K, L))), "per link row, like received")
        los_in = per_real(_flags("los", los_in))

    # system and ranging
    f_sc = _scalar(arrays, "subcarrier_spacing_hz", required=True)
    if f_sc <= 0:
        raise ValidationError("subcarrier_spacing_hz", f_sc, "must be > 0 Hz")
    ways = _scalar(arrays, "ways", required=True, kind="int")
    if ways not in (1, 2):
        raise ValidationError("ways", ways, "1 (one-way) or 2 (two-way ranging)")
    noise_var = _scalar(arrays, "noise_variance_w")
    temp = _scalar(arrays, "temperature_k")
    nf = _scalar(arrays, "noise_figure_db")
    fields = {"n_subcarriers": N, "subcarrier_spacing_hz": f_sc, "oversampling": 1}
    if noise_var is not None:
        if temp is not None or nf is not None:
            raise ValidationError(
                "noise_variance_w",
                "given with temperature_k/noise_figure_db",
                "give the measured noise variance or temperature_k and noise_figure_db",
            )
        if noise_var <= 0:
            raise ValidationError("noise_variance_w", noise_var, "must be > 0 W")
        # sigma^2 = k T B NF with NF = 0 dB: the noise temperature that gives sigma^2
        fields.update(temperature_k=noise_var / (K_BOLTZMANN * N * f_sc), noise_figure_db=0.0)
    else:
        for name, x in (("temperature_k", temp), ("noise_figure_db", nf)):
            if x is None:
                raise ValidationError(
                    "noise_variance_w" if temp is None and nf is None else name,
                    "missing",
                    "required: the noise variance sigma^2 [W] of R_n per subcarrier "
                    "(noise_variance_w), or temperature_k and noise_figure_db",
                )
        if temp <= 0:
            raise ValidationError("temperature_k", temp, "must be > 0 K")
        if nf < 0:
            raise ValidationError("noise_figure_db", nf, "must be >= 0 dB")
        fields.update(temperature_k=temp, noise_figure_db=nf)
    for name in ("carrier_frequency_hz", "tx_power_dbm"):
        x = _scalar(arrays, name)
        if x is not None:
            if name == "carrier_frequency_hz" and x <= 0:
                raise ValidationError(name, x, "must be > 0 Hz")
            fields[name] = x
    system = OFDMSystem(**fields)
    dt_s = _scalar(arrays, "dt_s")
    if dt_s is not None and dt_s <= 0:
        raise ValidationError("dt_s", dt_s, "must be > 0 s")

    # links: check on the user's indices, then reorder nodes and sort rows
    counts = mask.sum(axis=2)
    Lmax = max(1, int(counts.max()))
    received = np.zeros((R, K, Lmax, N), np.complex128)
    pairs = np.full((R, K, Lmax, 2), -1, np.int64)
    los = None if los_in is None else np.zeros((R, K, Lmax), bool)
    symbols = np.zeros((R, n, N), np.complex64)
    is_anchor = np.zeros((R, n), bool)
    node_order = np.zeros((R, n), np.int64)
    out_pos = np.empty_like(positions)
    for r in range(R):
        perm = np.r_[np.flatnonzero(~an[r]), np.flatnonzero(an[r])]
        inv = np.empty(n, np.int64)
        inv[perm] = np.arange(n)
        node_order[r] = perm
        is_anchor[r] = an[r][perm]
        out_pos[r] = positions[r][:, perm]
        transmitters = set()
        for t in range(K):
            rows = np.flatnonzero(mask[r, t])
            uv = lk[r, t, rows]
            where = f"realization {r}, snapshot {t}" if lead else f"snapshot {t}"
            bad = np.flatnonzero((uv < 0).any(axis=1) | (uv >= n).any(axis=1))
            if bad.size:
                raise ValidationError(
                    "links",
                    f"{tuple(uv[bad[0]].tolist())} at {where}, row {rows[bad[0]]}",
                    f"node indices must be in 0 … n - 1 = {n - 1}",
                )
            bad = np.flatnonzero(uv[:, 0] == uv[:, 1])
            if bad.size:
                raise ValidationError(
                    "links",
                    f"{tuple(uv[bad[0]].tolist())} at {where}, row {rows[bad[0]]}",
                    "a node does not receive from itself",
                )
            bad = np.flatnonzero(an[r][uv[:, 0]] & an[r][uv[:, 1]])
            if bad.size:
                raise ValidationError(
                    "links",
                    f"{tuple(uv[bad[0]].tolist())} at {where}, row {rows[bad[0]]}",
                    "anchor-anchor pairs are not links; leave them out with link_mask",
                )
            new = inv[uv]
            order = np.lexsort((new[:, 1], new[:, 0]))
            rows, new = rows[order], new[order]
            dup = np.flatnonzero((np.diff(new, axis=0) == 0).all(axis=1))
            if dup.size:
                raise ValidationError(
                    "links",
                    f"{tuple(lk[r, t, rows[dup[0]]].tolist())} twice at {where}",
                    "each directed link at most once per snapshot",
                )
            data = rx[r, t, rows]
            if not np.all(np.isfinite(data)):
                k = int(np.flatnonzero(~np.isfinite(data).all(axis=1))[0])
                raise ValidationError(
                    "received",
                    f"non-finite values at {where}, link row {rows[k]}",
                    "every recorded link needs finite symbols (mask missing rows out)",
                )
            c = rows.size
            received[r, t, :c] = data
            pairs[r, t, :c] = new
            if los is not None:
                los[r, t, :c] = los_in[r, t, rows]
            transmitters.update(uv[:, 1].tolist())
        silent = [v for v in sorted(transmitters) if not np.any(sym[r, v] != 0)]
        if silent:
            raise ValidationError(
                "symbols",
                f"all-zero pilots of node {silent[0]}" + (f" in realization {r}" if lead else ""),
                "every transmitting node needs pilot symbols",
            )
        symbols[r] = sym[r][perm]
    truth = tuple(name for name, a in (("positions", pos_in), ("los", los_in)) if a is not None)
    return _Data(
        received=received,
        counts=counts,
        pairs=pairs,
        symbols=symbols,
        is_anchor=is_anchor,
        positions=out_pos,
        los=los,
        node_order=node_order,
        system=system,
        ways=ways,
        dt_s=dt_s,
        truth=truth,
    )


# -- the stored recipe ------------------------------------------------------------------------
def _base_recipe(recipe, arrays) -> Recipe | None:
    if recipe is None and "recipe" in arrays:
        a = np.asarray(arrays["recipe"])
        if a.size != 1 or a.dtype.kind not in "US":
            raise ValidationError(
                "recipe", f"{a.dtype} array of shape {a.shape}", "expected TOML text (a string)"
            )
        recipe = a.reshape(()).item()
        recipe = recipe.decode() if isinstance(recipe, bytes) else recipe
        if "=" not in recipe:
            raise ValidationError("recipe", recipe, "expected the TOML text of a recipe")
    if recipe is None or isinstance(recipe, Recipe):
        return recipe
    return load_recipe(recipe)


def _safe_name(text: str) -> str:
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_.") or "imported"
    return name


def _recipe_doc(base: Recipe | None, data: _Data, out: Path, source_label: str) -> dict:
    """The stored recipe: the user's seed, name and evaluation sections; [system], [network],
    [channel] and [dataset] describe the imported arrays."""
    from phyloc.localization import METHODS
    from phyloc.ranging.estimators import ORACLES

    R, K, _, _, n, dim = data.shape
    n_anchors = int(data.is_anchor[0].sum())
    sections = {} if base is None else base.sections
    chan = dict(sections.get("channel", {}))
    scenario = chan.get("scenario", DEFAULT_SCENARIO)
    ranging = "two_way" if data.ways == 2 else "one_way"
    if "ranging" in chan and chan["ranging"] != ranging:
        raise ValidationError(
            "ways",
            data.ways,
            f"contradicts [channel] ranging = {chan['ranging']!r} of the recipe",
        )
    network = {"n_agents": n - n_anchors, "dim": dim, "on_isolated": "allow"}
    if n_anchors:
        network.update(anchors=n_anchors, anchor_layout="uniform")
    motion = {"n_snapshots": K}
    if data.dt_s is not None:
        motion["dt_s"] = data.dt_s
    network["motion"] = motion
    doc = {
        "kind": "dataset",
        "name": base.name if base is not None else _safe_name(out.stem),
        "seed": base.seed if base is not None else 0,
        "description": (base.description if base is not None else "")
        or f"recorded snapshots imported from {source_label}",
        "system": data.system.to_dict(),
        "network": network,
        "channel": {"scenario": scenario, "ranging": ranging},
        "dataset": {"realizations": R, "shard_size": R},
    }
    for s in ("ranging", "localization", "experiment"):
        if s in sections:
            doc[s] = dict(sections[s])
    # methods that need ground truth the arrays lack
    experiment = dict(doc.get("experiment", {}))
    oracle_inputs = {f"ranges:{o}" for o in ORACLES}
    direct = METHODS.family("direct")
    listed = experiment.get("methods")
    methods = list(listed) if listed is not None else list(direct)
    needs_los = [m for m in methods if m in METHODS and METHODS[m].inputs in oracle_inputs]
    if data.los is None and needs_los:
        if listed is not None:
            raise ValidationError(
                "los",
                "missing",
                f"[experiment] methods lists {needs_los[0]}, an oracle that needs the "
                "ground-truth LOS flags: supply los [K, L] (1 for LOS) or drop the method",
            )
        experiment["methods"] = [m for m in methods if m not in needs_los]
        doc["experiment"] = experiment
    inits = experiment.get("inits", ["truth_free"])
    if "positions" not in data.truth and "informed" in inits:
        raise ValidationError(
            "positions",
            "missing",
            "[experiment] inits lists 'informed', which starts from the ground truth",
        )
    return doc


def _recipe_text(doc: dict, source_label: str) -> str:
    head = (
        f"# Imported by phyloc import from {source_label}. [system], [network], [channel] and\n"
        "# [dataset] describe the imported arrays: nothing is simulated, and phyloc generate\n"
        "# cannot rebuild this dataset. [channel] scenario is a label in figure names.\n"
    )
    return head + dumps_toml(doc)


# -- writing --------------------------------------------------------------------------------
def _clear_output(out: Path, sdir: Path) -> None:
    """Remove an existing import output (``--force``): the master and the shard folder's own
    files; a folder holding anything else is left alone and refused."""
    if sdir.is_dir():
        ours = re.compile(r"^(shard-\d{5}\.h5|\.shard-\d{5}\.h5\.tmp-.*|\.lock)$")
        others = [p.name for p in sdir.iterdir() if not ours.match(p.name)]
        if others:
            raise OutputExistsError(
                f"{sdir} (it holds files phyloc did not write, e.g. {others[0]})"
            )
        for p in sdir.iterdir():
            p.unlink()
        sdir.rmdir()
    if out.exists():
        out.unlink()


def _write_shard(path: Path, data: _Data, fingerprint: str, seed: int) -> dict:
    """Write the one shard of an imported dataset atomically; return its shard-table row."""
    from phyloc import __version__

    R, K, L, N, n, dim = data.shape
    system = data.system
    M = system.n_samples
    arrays = sc.arrays_for({})
    dims = {
        "realization": R,
        "snapshot": K,
        "node": n,
        "coordinate": dim,
        "link": L,
        "end": 2,
        "subcarrier": N,
        "sample": M,
    }
    small = {
        a.name: np.full(a.shape(dims), a.fill, dtype=a.dtype)
        for a in arrays
        if a.role != "path" and a.name not in ("received", "symbols")
    }
    small["nodes/positions"][:] = data.positions
    small["nodes/is_anchor"][:] = data.is_anchor
    small["links/count"][:] = data.counts
    small["links/pairs"][:] = data.pairs
    small["links/valid"][:] = np.arange(L) < data.counts[..., None]
    if data.los is not None:
        small["channel/los"][:] = data.los
    small["channel/paths/start"][:] = 0
    small["channel/paths/count"][:] = 0
    small["channel/paths/base"][:] = 0
    if "positions" in data.truth:
        for r in range(R):
            for t in range(K):
                c = data.counts[r, t]
                u, v = data.pairs[r, t, :c].T
                diff = data.positions[r, t, u] - data.positions[r, t, v]
                small["channel/distance_m"][r, t, :c] = np.sqrt((diff**2).sum(axis=1))
    small["channel/paths/delays_s"] = np.zeros(0)
    small["channel/paths/gains"] = np.zeros(0, np.complex128)
    samples = np.zeros((R, K, L, M), np.complex64)
    for r in range(R):
        for t in range(K):
            c = data.counts[r, t]
            samples[r, t, :c] = to_time_domain(data.received[r, t, :c], system)
    small["received"] = samples
    small["symbols"] = data.symbols
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
    try:
        with h5py.File(tmp, "w") as f:
            for a in arrays:
                value = small[a.name]
                kw = {}
                if a.name == "received":
                    kw["chunks"] = (1, 1, L, M)
                elif a.name == "symbols":
                    kw["chunks"] = (1, n, N)
                d = f.create_dataset(a.name, data=value, **kw)
                d.attrs["sha256"] = sc.sha256_array(value)
                _h5_attrs(d, a)
            f.attrs.update(
                {
                    "format": sc.SHARD_FORMAT,
                    "schema_version": sc.SCHEMA_VERSION,
                    "phyloc_version": __version__,
                    "recipe_fingerprint": fingerprint,
                    "seed": seed,
                    "shard_index": 0,
                    "realization_start": 0,
                    "realization_stop": R,
                    "max_links": L,
                    "n_links": int(data.counts.sum()),
                    "n_paths": 0,
                }
            )
            f.attrs["complete"] = 1
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    with h5py.File(path, "r") as f:
        record = sc.shard_record(f, path, arrays)
    record["file_sha256"] = sc.sha256_file(path)
    return record


def import_arrays(source, out, *, recipe=None, force: bool = False) -> Path:
    """Write recorded OFDM snapshots (raw arrays) into a phyloc dataset (``phyloc import``).

    Parameters
    ----------
    source : str, Path or mapping
        An ``.npz`` file, a plain HDF5 file of arrays, or a mapping of names to arrays. The
        names and shapes are those of :data:`INPUTS` (``datasets/README.md``, "Importing
        recorded snapshots"); every array may carry a leading realization axis.
    out : str or Path
        The master file to write (``OUT.h5``); its shard goes to ``OUT.h5.shards/``.
    recipe : Recipe, path or TOML text, optional
        Supplies ``seed``, ``name``, ``description``, ``[channel] scenario`` (a label) and the
        ``[ranging]``, ``[localization]`` and ``[experiment]`` sections that ``phyloc
        evaluate`` reads from the dataset. Default: the source's ``recipe`` text if it has one,
        else seed 0, the output's stem as name and phyloc's defaults.
    force : bool
        Replace an existing output (the master and its shard folder). Without it an existing
        output is an error and is left untouched.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    ValidationError
        A missing, unknown, mis-shaped or inconsistent array (the message names it, with the
        shape seen and the shape expected), or a recipe whose methods need ground truth the
        arrays lack (the LOS oracle ``sage_los`` needs ``los``; the ``informed`` start needs
        ``positions``). Nothing is written.
    OutputExistsError
        ``out`` or its shard folder exists and ``force`` is False.
    DatasetError
        The source cannot be read.

    Notes
    -----
    The received symbols are stored as the schema's complex64 time samples with oversampling
    1 (``to_time_domain``); reading them back (``from_time_domain``) gives ``R_n`` to within
    complex64 rounding. Without ``positions`` the agents' positions are stored as NaN:
    ``phyloc info`` and :meth:`Dataset.snapshot` work, ``phyloc evaluate`` (which scores
    against the truth) refuses the file.

    Examples
    --------
    Two agents and one anchor, one snapshot, noise only (a smoke example; see
    ``tests/test_import.py`` for a round trip through :func:`export_arrays`):

    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import phyloc.datasets as pds
    >>> rng = np.random.default_rng(0)
    >>> N = 33
    >>> links = np.array([[0, 1], [1, 0], [0, 2], [1, 2]])   # (receiver, transmitter)
    >>> arrays = {
    ...     "received": (rng.normal(size=(1, 4, N)) + 1j * rng.normal(size=(1, 4, N))) * 1e-6,
    ...     "links": links,
    ...     "symbols": np.exp(2j * np.pi * rng.integers(4, size=(3, N)) / 4),
    ...     "is_anchor": np.array([0, 0, 1]),
    ...     "anchor_positions": np.array([[10.0, 5.0]]),
    ...     "subcarrier_spacing_hz": 1e6,
    ...     "noise_variance_w": 2e-12,
    ...     "ways": 1,
    ... }
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     out = pds.import_arrays(arrays, pathlib.Path(tmp) / "rec.h5")
    ...     with pds.open(out) as ds:
    ...         snap = ds.snapshot(0, 0)
    ...         sigma2 = ds.system.noise_power_w
    ...     ok = pds.verify(out)["ok"]
    >>> snap.links.tolist(), snap.received.shape, round(sigma2 / 2e-12, 12), ok
    ([[0, 1], [0, 2], [1, 0], [1, 2]], (4, 33), 1.0, True)
    """
    out = Path(out)
    label = "arrays" if isinstance(source, Mapping) else Path(source).name
    if not isinstance(source, Mapping) and out.resolve() == Path(source).resolve():
        raise ValidationError("out", str(out), "must differ from the source file")
    if out.is_dir():
        raise ValidationError("out", str(out), "is a folder; give the path of an .h5 file")
    sdir = sc.shard_dir(out)
    if (out.exists() or sdir.exists()) and not force:
        raise OutputExistsError(out)
    arrays = read_arrays(source)
    base = _base_recipe(recipe, arrays)
    arrays.pop("recipe", None)
    data = check_arrays(arrays)
    doc = _recipe_doc(base, data, out, label)
    text = _recipe_text(doc, label)
    stored = load_recipe(text)
    network = NetworkSpec.from_dict(doc["network"])
    channel = ChannelSpec.from_dict(doc["channel"])
    dspec = DatasetSpec.from_dict(doc["dataset"])
    h = hashlib.sha256(text.encode())
    for a in (data.received, data.pairs, data.symbols, data.positions, data.counts):
        h.update(sc.sha256_array(a).encode())
    canon = {"schema_major": sc.SCHEMA_MAJOR, "imported": h.hexdigest()}
    fingerprint = hashlib.sha256(
        json.dumps(canon, sort_keys=True, separators=(",", ":")).encode()
    ).hexdigest()
    plan = DatasetPlan(stored, data.system, network, channel, dspec, fingerprint, {})
    if force:
        _clear_output(out, sdir)
    elif out.exists() or sdir.exists():  # appeared while we checked
        raise OutputExistsError(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sdir.mkdir()
    with _lock(sdir, out):
        record = _write_shard(sdir / sc.shard_name(0), data, fingerprint, stored.seed)
        write_master(out, plan, [record])
        with h5py.File(out, "r+") as f:
            if data.dt_s is None:
                f.attrs["dt_s"] = math.nan
            f.attrs["source"] = "imported"
            f.attrs["imported_from"] = label
            f.attrs["truth"] = ",".join(data.truth)
            f.attrs["node_order"] = data.node_order
            f.attrs[sc.MASTER_DIGEST_ATTR] = sc.master_digest(f)  # with the attributes above
    return out


# -- export ---------------------------------------------------------------------------------
def export_arrays(dataset_path, out, *, force: bool = False) -> Path:
    """Write a dataset's waveforms and truth as the raw arrays :func:`import_arrays` reads.

    Every array carries the leading realization axis: ``received`` ``[R, K, L, N]``
    complex128 (``from_time_domain`` of the stored samples), ``links`` ``[R, K, L, 2]``,
    ``link_mask`` ``[R, K, L]``, ``symbols``, ``is_anchor``, ``anchor_positions`` (with
    anchors), ``positions`` and ``los`` (unless the dataset was imported without them), the
    system parameters (``n_subcarriers``, ``subcarrier_spacing_hz``, ``carrier_frequency_hz``,
    ``tx_power_dbm``, ``temperature_k``, ``noise_figure_db``), ``ways``, ``dt_s`` (several
    snapshots), ``dim`` and the stored ``recipe`` text.

    Parameters
    ----------
    dataset_path : str or Path
        A complete dataset (master file).
    out : str or Path
        ``.npz`` or ``.h5``/``.hdf5`` (a plain HDF5 file, one dataset per array).
    force : bool
        Replace an existing ``out``.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    OutputExistsError
        ``out`` exists and ``force`` is False.
    ValidationError
        ``out`` has another suffix.
    DatasetError
        The dataset is missing, unreadable or incomplete.
    """
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in (".npz", ".h5", ".hdf5"):
        raise ValidationError("out", str(out), "must end in .npz, .h5 or .hdf5")
    if out.exists() and not force:
        raise OutputExistsError(out)
    from phyloc.datasets.reader import open_dataset

    with open_dataset(dataset_path) as ds:
        for r in range(ds.n_realizations):
            ds._realization(r)  # a clear error for a realization that is not stored
        f = ds.file
        system = ds.system
        truth = sc._text(f.attrs.get("truth", "positions,los")).split(",")
        is_anchor = f["nodes/is_anchor"][...].astype(bool)
        positions = f["nodes/positions"][...]
        arrays = {
            "received": from_time_domain(f["received"][...], system),
            "links": f["links/pairs"][...].astype(np.int64),
            "link_mask": f["links/valid"][...].astype(bool),
            "symbols": f["symbols"][...],
            "is_anchor": is_anchor,
        }
        n_anchors = int(is_anchor[0].sum())
        if n_anchors:
            arrays["anchor_positions"] = np.stack(
                [positions[r, 0][is_anchor[r]] for r in range(ds.n_realizations)]
            )
        if "positions" in truth:
            arrays["positions"] = positions
        if "los" in truth:
            arrays["los"] = f["channel/los"][...].astype(bool)
        for k in (
            "n_subcarriers",
            "subcarrier_spacing_hz",
            "carrier_frequency_hz",
            "tx_power_dbm",
            "temperature_k",
            "noise_figure_db",
        ):
            arrays[k] = np.asarray(getattr(system, k))
        arrays["ways"] = np.asarray(ds.ways)
        arrays["dim"] = np.asarray(ds.dim)
        if ds.dt_s is not None:
            arrays["dt_s"] = np.asarray(ds.dt_s)
        arrays["recipe"] = np.asarray(ds.recipe)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
    try:
        if suffix == ".npz":
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
        else:
            with h5py.File(tmp, "w") as h:
                for k, a in arrays.items():
                    if a.dtype.kind == "U":
                        h.create_dataset(k, data=str(a), dtype=h5py.string_dtype())
                    else:
                        h.create_dataset(k, data=a)
        os.replace(tmp, out)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    return out


__all__ = [
    "DEFAULT_SCENARIO",
    "INPUTS",
    "REQUIRED",
    "check_arrays",
    "export_arrays",
    "import_arrays",
    "read_arrays",
]
