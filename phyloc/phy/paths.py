"""Ragged multipath path sets: what channel models emit and waveform synthesis consumes.

A batch of ``n_links`` links, each with its own number of paths, is stored flat: the paths of
link ``i`` are ``delays[offsets[i]:offsets[i+1]]`` and ``gains[offsets[i]:offsets[i+1]]``.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError


@dataclass(frozen=True, eq=False)
class PathSet:
    """Multipath components of a batch of links (DiPNet eq. (6)).

    Parameters
    ----------
    delays : [n_paths_total], float64
        Path delays ``τ_l`` [s], finite and >= 0. For a link u←v,
        ``τ_l = d_uv/c0 + b_uv + δ_l`` (the signal model of :doc:`/guide/design`).
    gains : [n_paths_total], complex128
        Complex path gains ``α_l`` [√W]: ``|α_l|²`` is the received power of path l.
    offsets : [n_links + 1], int64
        ``offsets[0] == 0``, non-decreasing, ``offsets[-1] == n_paths_total``. A link may have
        no path (``offsets[i] == offsets[i+1]``): it then receives noise only.

    Examples
    --------
    >>> ps = PathSet.from_lists([[1e-7, 2e-7], [3e-7]], [[1.0, 0.5j], [0.1]])
    >>> ps.n_links, ps.n_paths.tolist()
    (2, [2, 1])
    """

    delays: np.ndarray
    gains: np.ndarray
    offsets: np.ndarray

    def __post_init__(self):
        delays = v.finite_array("paths.delays", self.delays, ndim=1)
        gains = v.finite_array("paths.gains", self.gains, dtype=np.complex128, ndim=1)
        try:
            offsets = np.ascontiguousarray(self.offsets, dtype=np.int64)
        except (TypeError, ValueError):
            raise ValidationError("paths.offsets", self.offsets, "integer array required") from None
        if offsets.ndim != 1 or offsets.size < 1:
            raise ValidationError(
                "paths.offsets", f"shape {offsets.shape}", "must be 1-D with n_links + 1 entries"
            )
        if delays.size != gains.size:
            raise ValidationError(
                "paths.gains",
                f"{gains.size} gains",
                f"must have one gain per delay ({delays.size} delays)",
            )
        if offsets[0] != 0 or offsets[-1] != delays.size or np.any(np.diff(offsets) < 0):
            raise ValidationError(
                "paths.offsets",
                f"[{offsets[0]}, …, {offsets[-1]}]",
                f"must start at 0, never decrease and end at the path count {delays.size}",
            )
        if delays.size and delays.min() < 0:
            i = int(np.argmin(delays))
            raise ValidationError(
                "paths.delays",
                f"{float(delays[i])!r} at index {i}",
                "delays must be >= 0 s (causal)",
            )
        object.__setattr__(self, "delays", delays)
        object.__setattr__(self, "gains", gains)
        object.__setattr__(self, "offsets", offsets)

    @classmethod
    def from_lists(cls, delays, gains) -> PathSet:
        """Build from one sequence of delays and one of gains per link."""
        if len(delays) != len(gains):
            raise ValidationError(
                "paths.gains", f"{len(gains)} links", f"must match delays ({len(delays)} links)"
            )
        counts = [len(np.atleast_1d(d)) for d in delays]
        for i, (d, g) in enumerate(zip(delays, gains, strict=True)):
            if len(np.atleast_1d(g)) != len(np.atleast_1d(d)):
                raise ValidationError(
                    f"paths.gains[{i}]", f"{len(np.atleast_1d(g))} gains", "one gain per delay"
                )
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        flat_d = np.concatenate([np.atleast_1d(np.asarray(d, float)) for d in delays] or [[]])
        flat_g = np.concatenate([np.atleast_1d(np.asarray(g, complex)) for g in gains] or [[]])
        return cls(flat_d, flat_g, offsets)

    @classmethod
    def single_path(cls, delays, gains) -> PathSet:
        """One path per link (AWGN channel): ``delays`` of shape ``[n_links]``, ``gains`` of the
        same shape or one scalar gain for every link.

        Raises
        ------
        ValidationError
            ``delays`` not one-dimensional, or ``gains`` neither a scalar nor ``[n_links]``.
        """
        d = np.atleast_1d(np.asarray(delays, dtype=np.float64))
        if d.ndim != 1:
            raise ValidationError("delays", f"array of shape {d.shape}", "must be [n_links]")
        g = np.asarray(gains, dtype=np.complex128)
        if g.ndim != 0 and g.shape != d.shape:
            raise ValidationError(
                "gains",
                f"array of shape {g.shape}",
                f"must be a scalar or [n_links] = {d.shape} like delays",
            )
        g = np.broadcast_to(g, d.shape).copy()
        return cls(d, g, np.arange(d.size + 1, dtype=np.int64))

    @property
    def n_links(self) -> int:
        """Number of links in the batch."""
        return self.offsets.size - 1

    @property
    def n_paths(self) -> np.ndarray:
        """Paths per link, ``[n_links]`` int64."""
        return np.diff(self.offsets)

    def link(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """``(delays, gains)`` of link ``i``."""
        a, b = self.offsets[i], self.offsets[i + 1]
        return self.delays[a:b], self.gains[a:b]

    def link_index(self) -> np.ndarray:
        """The link each flat path belongs to, ``[n_paths_total]`` int64."""
        return np.repeat(np.arange(self.n_links, dtype=np.int64), self.n_paths)

    def total_power(self) -> np.ndarray:
        """Received power per link ``Σ_l |α_l|²`` [W], ``[n_links]``."""
        return np.bincount(
            self.link_index(), weights=np.abs(self.gains) ** 2, minlength=self.n_links
        )

    def first_delay(self) -> np.ndarray:
        """Earliest path delay per link [s] (``inf`` for a link without paths), ``[n_links]``."""
        out = np.full(self.n_links, np.inf)
        if self.delays.size:
            np.minimum.at(out, self.link_index(), self.delays)
        return out

    def select(self, links) -> PathSet:
        """The sub-batch of the given link indices (in that order)."""
        idx = np.asarray(links, dtype=np.int64)
        parts_d = [self.link(int(i))[0] for i in idx]
        parts_g = [self.link(int(i))[1] for i in idx]
        return PathSet.from_lists(parts_d, parts_g)

    @staticmethod
    def concatenate(sets) -> PathSet:
        """Join several batches into one (links in order)."""
        sets = list(sets)
        if not sets:
            return PathSet(np.zeros(0), np.zeros(0, complex), np.zeros(1, np.int64))
        offs = [sets[0].offsets]
        base = sets[0].offsets[-1]
        for s in sets[1:]:
            offs.append(s.offsets[1:] + base)
            base += s.offsets[-1]
        return PathSet(
            np.concatenate([s.delays for s in sets]),
            np.concatenate([s.gains for s in sets]),
            np.concatenate(offs),
        )
