"""The ellipse outer-approximation of the feasible sets: the baseline of POA-NBP Fig. 9.

The paper compares POA (:func:`~phyloc.localization.static.poa_network.poa`) with the ellipses
of "distributed bounding of feasible sets" (its refs. [8], [10], [42]), which agents exchange
instead of polygons. :func:`ellipse_outer_approximation` keeps that information flow with the
tightest ellipse each step (a conservative baseline); :class:`EllipseRegion` makes an ellipse a
support region of the polygon proposal of POA-NBP eq. (21) (the 'NBP ell.' baseline). The
cited convex formulation itself (S-procedure discs, looser) is
:mod:`~phyloc.localization.static.bounding`.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.static import _polygon_kernels as K
from phyloc.localization.static.poa_network import _clip, _network_inputs, _region, _warmup
from phyloc.localization.static.polygons import _anchor_halfspaces, _points, _signed_area, _tol


class EllipseRegion:
    """An ellipse ``{x : (x − c)ᵀ Σ⁻¹ (x − c) <= 1}`` as a support region of the polygon
    proposal (``area``, ``contains``, ``sample_uniform``; the NBP of POA-NBP eq. (21) with an
    ellipse in place of the polygon: the 'NBP ell.' baseline).

    Parameters
    ----------
    center : [2] float64
        ``c`` [m].
    shape : [2, 2] float64
        ``Σ`` [m²], symmetric positive semi-definite; a singular ``Σ`` has area 0 (no density).

    Examples
    --------
    >>> E = EllipseRegion([0.0, 0.0], [[4.0, 0.0], [0.0, 1.0]])
    >>> round(E.area, 6), E.contains([[1.9, 0.0], [0.0, 1.1]]).tolist()
    (6.283185, [True, False])
    >>> bool(E.contains(E.sample_uniform(100, np.random.default_rng(0))).all())
    True
    """

    def __init__(self, center, shape):
        self.center = np.asarray(center, dtype=np.float64)
        self.shape = np.asarray(shape, dtype=np.float64)
        det = float(np.linalg.det(self.shape))
        self.area = math.pi * math.sqrt(det) if det > 0 else 0.0
        if self.area > 0:
            self._L = np.linalg.cholesky(self.shape)
            self._inv = np.linalg.inv(self.shape)

    def contains(self, points, tol=1e-9) -> np.ndarray:
        """Whether each of ``points [n, 2]`` lies in the ellipse (``≤ 1 + tol``)."""
        d = np.asarray(points, dtype=np.float64).reshape(-1, 2) - self.center
        if self.area == 0:
            return np.zeros(d.shape[0], bool)
        return np.einsum("ni,ij,nj->n", d, self._inv, d) <= 1.0 + tol

    def sample_uniform(self, n, rng) -> np.ndarray:
        """``n`` points uniform in the ellipse: ``c + L u``, ``u`` uniform in the unit disk
        (``√U`` radius, uniform angle; draws ``rng.uniform(size=n)`` twice), ``Σ = L Lᵀ``."""
        r = np.sqrt(rng.uniform(size=n))
        t = rng.uniform(0.0, 2.0 * np.pi, size=n)
        u = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
        return self.center + u @ self._L.T


@dataclass(frozen=True, eq=False)
class EllipseResult:
    """Output of :func:`ellipse_outer_approximation`.

    Ellipse ``j`` is ``E_j = {x : (x − c_j)ᵀ Σ_j⁻¹ (x − c_j) <= 1}``, area ``π √det Σ_j``
    (``Σ_j`` may be singular for a flat feasible set).

    Attributes
    ----------
    agents : [n_agents], int
        Node index of each agent, ascending.
    centers : [n_agents, 2], float
        Centers ``c_j`` [m] (zeros where unbounded).
    shapes : [n_agents, 2, 2], float
        Shape matrices ``Σ_j`` [m²] (zeros where unbounded).
    bounded : [n_agents], bool
        False where the agent has no ellipse (unbounded).
    area_history : [n_iterations, n_agents], float
        Ellipse area [m²] after each iteration (``inf`` while unbounded); comparable with
        :attr:`~phyloc.localization.static.poa_network.POAResult.area_history`.
    dropped : [k, 2], int
        Dropped measurements ``(i, j)`` (same rule as
        :func:`~phyloc.localization.static.poa_network.poa`).
    dropped_iteration : [k], int
        Iteration (1-based) of each drop.
    n_directions : int
        Number of tangent directions of the polygonal intermediate sets.
    """

    agents: np.ndarray
    centers: np.ndarray
    shapes: np.ndarray
    bounded: np.ndarray
    area_history: np.ndarray
    dropped: np.ndarray
    dropped_iteration: np.ndarray
    n_directions: int

    def contains(self, slot, points, tol: float = 1e-9) -> np.ndarray:
        """Whether ``points`` ``[n, 2]`` lie in the ellipse of agent ``slot`` (position in
        :attr:`agents`), tested against ``Σ + tol² I``; all True when unbounded."""
        a = v.integer("slot", slot, minimum=0)
        if a >= self.agents.size:
            raise ValidationError("slot", slot, f"must be < {self.agents.size}")
        p = _points("points", points)
        t = v.positive("tol", tol, allow_zero=True)
        if not self.bounded[a]:
            return np.ones(p.shape[0], dtype=bool)
        d = p - self.centers[a]
        S = self.shapes[a] + max(t * t, 1e-300) * np.eye(2)
        return np.einsum("ij,jk,ik->i", d, np.linalg.inv(S), d) <= 1.0

    def regions(self) -> list:
        """One :class:`EllipseRegion` per agent (``None`` where unbounded): the supports of
        the 'NBP ell.' proposal."""
        return [
            EllipseRegion(c, sh) if b else None
            for c, sh, b in zip(self.centers, self.shapes, self.bounded, strict=True)
        ]

    def mean_area(self) -> np.ndarray:
        """Mean area per iteration over the agents bounded from iteration 1 on (see
        :meth:`~phyloc.localization.static.poa_network.POAResult.mean_area`)."""
        ok = np.all(np.isfinite(self.area_history), axis=0)
        if not ok.any():
            return np.full(self.area_history.shape[0], np.inf)
        return self.area_history[:, ok].mean(axis=1)


def _ellipse_area(sig: np.ndarray) -> float:
    return math.pi * math.sqrt(max(float(np.linalg.det(sig)), 0.0))


def _outer_ellipse(w: np.ndarray, tol: float):
    """Minimum-area ellipse containing the convex polygon ``w`` (its vertices).

    Löwner–John ellipse by :func:`~phyloc.localization.static._polygon_kernels.mvee_kernel`; a flat
    polygon (point, segment, area below ``tol²``) gets the ellipse through the corners of its
    principal-axis bounding rectangle (``Σ = 2 Σ_k h_k² e_k e_kᵀ``, half-extents ``h_k``).
    """
    if w.shape[0] >= 3 and _signed_area(w) > tol * tol:
        c, sig, _ = K.mvee_kernel(w, 1e-7, 20_000)
        if np.linalg.det(sig) > 0.0 and np.all(np.isfinite(sig)):
            return c, sig
    if w.shape[0] == 1:
        return w[0].copy(), np.zeros((2, 2))
    d = w - w.mean(axis=0)
    _, vecs = np.linalg.eigh(d.T @ d)
    proj = w @ vecs
    lo, hi = proj.min(axis=0), proj.max(axis=0)
    h = 0.5 * (hi - lo)
    c = vecs @ (0.5 * (hi + lo))
    return c, 2.0 * (vecs * h**2) @ vecs.T


def _halfspace_vertices(A: np.ndarray, c: np.ndarray, tol: float) -> np.ndarray:
    """Vertices of ``{A x <= c}`` for normals sorted CCW with turns < π and support-function
    offsets: adjacent lines ``m − 1`` and ``m`` meet at vertex ``m`` (Cramer's rule)."""
    Ap, cp = np.roll(A, 1, axis=0), np.roll(c, 1)
    det = Ap[:, 0] * A[:, 1] - Ap[:, 1] * A[:, 0]
    x = (cp * A[:, 1] - c * Ap[:, 1]) / det
    y = (Ap[:, 0] * c - A[:, 0] * cp) / det
    w = np.column_stack([x, y])
    m = K.clean_kernel(w, w.shape[0], tol)
    return w[:m].copy()


def ellipse_outer_approximation(
    positions,
    ranges,
    anchors,
    *,
    n_iterations: int = 2,
    region=None,
    n_directions: int = 64,
) -> EllipseResult:
    """Ellipse outer-approximation of the feasible sets: the baseline of POA-NBP Fig. 9.

    The paper compares POA with the ellipses of "distributed bounding of feasible sets"
    (its refs. [8], [10], [42]), which agents exchange instead of polygons. This function keeps
    that information flow but computes each ellipse as tightly as possible, so the baseline is
    conservative (no looser than the original convex relaxation):

    * iteration 1: ``S_j = region ∩ ⋂_{anchors i} B(x_i, ẑ_{i→j})``;
    * iteration ``l >= 2`` (Jacobi): ``S_j = T(E_j) ∩ region ∩ ⋂_{anchors} B(x_i, ẑ_{i→j}) ∩
      ⋂_{agents i} T(E_i ⊕ ẑ_{i→j} B)`` with the neighbours' ellipses of iteration ``l − 1``;
    * ``E_j`` = the minimum-area (Löwner–John) ellipse of ``S_j``'s vertices, kept only if its
      area is below that of the previous ``E_j`` (both contain the feasible set).

    ``T(K)`` is the polygon of the ``n_directions`` supporting halfspaces of ``K`` at the
    normals ``2πk/n_directions``; for an ellipse grown by ``z`` their offsets are
    ``a·c + √(aᵀΣa) + z`` (exact support function). Each ``S_j`` is therefore an outer
    polygon of the true intersection, and each ellipse contains it: with errors ``ε >= 0``
    every ellipse contains its agent. Measurements are dropped exactly as in
    :func:`~phyloc.localization.static.poa_network.poa`.

    Parameters
    ----------
    positions, ranges, anchors, region
        As in :func:`~phyloc.localization.static.poa_network.poa`.
    n_iterations : int
        ``N_FS >= 1``.
    n_directions : int
        Number of tangent directions, ``>= 8`` (64 keeps ``T`` within 0.5 % of the disks).

    Returns
    -------
    EllipseResult
    """
    pos, z, is_anchor = _network_inputs(positions, ranges, anchors)
    n_iter = v.integer("n_iterations", n_iterations, minimum=1)
    nd = v.integer("n_directions", n_directions, minimum=8)
    R = _region(region)
    _warmup()
    agents = np.flatnonzero(~is_anchor)
    slot = np.full(pos.shape[0], -1, dtype=np.int64)
    slot[agents] = np.arange(agents.size)
    tol = _tol(pos[is_anchor], z[np.isfinite(z)], R.vertices if R is not None else np.empty(0))
    link = np.isfinite(z)
    half = -math.pi / nd  # anchor-polygon offset that puts the normals at 2πk/nd
    ang = 2.0 * math.pi * np.arange(nd) / nd
    D = np.column_stack([np.cos(ang), np.sin(ang)])

    ell: list[tuple[np.ndarray, np.ndarray] | None] = [None] * agents.size
    areas = np.empty((n_iter, agents.size))
    dropped: list[tuple[int, int, int]] = []
    bad = set()

    def ellipse_halfspaces(e, zz):
        c, sig = e
        return D, D @ c + np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", D, sig, D), 0.0)) + zz

    for it in range(n_iter):
        new = list(ell)
        for a, j in enumerate(agents):
            gA, gc, nb = [], [], []  # nb: (node, kind) with kind "prior" for non-measurements
            if R is not None:
                A, c = R.halfspaces()
                gA.append(A)
                gc.append(c)
                nb.append((-1, 0.0))
            if ell[a] is not None:
                A, c = ellipse_halfspaces(ell[a], 0.0)
                gA.insert(0, A)
                gc.insert(0, c)
                nb.insert(0, (-1, 0.0))
            for i in np.flatnonzero(link[j]):
                key = (int(i), int(j))
                if key in bad:
                    continue
                zz = float(z[j, i])
                if is_anchor[i]:
                    A, c = _anchor_halfspaces(pos[i], max(zz, 0.0), nd, half)
                elif it > 0 and ell[slot[i]] is not None:
                    A, c = ellipse_halfspaces(ell[slot[i]], zz)
                else:
                    continue
                if zz < 0.0:
                    dropped.append((*key, it + 1))
                    bad.add(key)
                    continue
                gA.append(A)
                gc.append(c)
                nb.append((int(i), zz))
            if not gA:
                areas[it, a] = math.inf
                continue
            subject = _halfspace_vertices(gA[0], gc[0], tol)
            out, drop, _ = _clip(subject, gA[1:], gc[1:], tol)
            for g in np.flatnonzero(drop):
                i = nb[g + 1][0]
                if i >= 0:
                    dropped.append((i, int(j), it + 1))
                    bad.add((i, int(j)))
            cand = _outer_ellipse(out, tol)
            if ell[a] is None or _ellipse_area(cand[1]) < _ellipse_area(ell[a][1]):
                new[a] = cand
            areas[it, a] = _ellipse_area(new[a][1])
        ell = new

    centers = np.zeros((agents.size, 2))
    shapes = np.zeros((agents.size, 2, 2))
    bounded = np.array([e is not None for e in ell], dtype=bool)
    for a, e in enumerate(ell):
        if e is not None:
            centers[a], shapes[a] = e
    return EllipseResult(
        agents=agents,
        centers=centers,
        shapes=shapes,
        bounded=bounded,
        area_history=areas,
        dropped=np.array([(i, j) for i, j, _ in dropped], dtype=np.int64).reshape(-1, 2),
        dropped_iteration=np.array([it for _, _, it in dropped], dtype=np.int64),
        n_directions=nd,
    )
