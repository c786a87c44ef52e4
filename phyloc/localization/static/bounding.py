"""Distributed bounding of feasible sets: the ellipse baseline of POA-NBP as the paper cites it.

POA-NBP §III-C and §V-B compare POA with "distributed bounding of feasible sets" (Gholami et al.,
its refs. [8], [10], [42]; used for 'NBP ell.' in its ref. [39]): each agent confines its
position to an ellipse that outer-approximates its feasible set, "determined efficiently" by "a
convex problem formulation [that] guarantees convexity but [...] comes at the expense of
unnecessarily loose outer-approximations", iterated over the network like POA. phyloc's
:func:`~phyloc.localization.static.ellipses.ellipse_outer_approximation` instead takes the
exact minimum-area ellipse of the constraint set (tighter than the cited one); this module
implements the convex formulation.

**The convex formulation** (the S-procedure; S. Boyd, L. El Ghaoui, E. Feron and
V. Balakrishnan, *Linear Matrix Inequalities in System and Control Theory*, SIAM 1994, §3.7.3,
"outer approximation of the intersection of ellipsoids" — the relaxation Gholami et al. build
on). With the feasible set ``S = ⋂_i {f_i(x) <= 0} ∩ ⋂_k {h_k(x) <= 0}``, discs
``f_i(x) = ‖x − a_i‖² − r_i²`` and halfspaces ``h_k(x) = n_kᵀx − c_k``, an ellipse
``E = {f_0 <= 0}`` contains ``S`` if multipliers ``w_i, μ_k >= 0`` exist with

.. math::  f_0(x) \\le \\sum_i w_i f_i(x) + \\sum_k \\mu_k h_k(x) \\quad \\forall x      \\tag{B1}

(a linear matrix inequality in the ellipse's parameters and the multipliers; the SDP minimizes
``log det`` of the shape matrix — the area — or its trace over them). (B1) is sufficient, not
necessary: the relaxation is what makes the ellipses loose. **For discs and halfspaces it has a
closed form.** With ``Σ w_i = 1`` (the set ``{Σ w f + Σ μ h <= 0}`` does not change when the
multipliers are scaled) the right-hand side of (B1) is the *pencil disc*

.. math::  \\sum_i w_i f_i + \\sum_k \\mu_k h_k = \\lVert x - \\bar a \\rVert^2 - \\rho^2,
    \\quad \\bar a = \\sum_i w_i a_i - \\tfrac12 \\sum_k \\mu_k n_k,
    \\quad \\rho^2 = \\lVert \\bar a \\rVert^2 - \\sum_i w_i (\\lVert a_i \\rVert^2 - r_i^2)
    + \\sum_k \\mu_k c_k,                                                                 \\tag{B2}

and by the S-lemma (one constraint: lossless) an ellipse satisfies (B1) for some multipliers iff
it contains some pencil disc ``D(ā, ρ)``. The smallest such ellipse — by area and by trace — is
therefore the smallest pencil disc: minimize the convex quadratic ``ρ²(w, μ)`` of (B2) over
``w`` in the simplex and ``μ >= 0`` (the Lagrange dual of ``min_{h(x) <= 0} max_i f_i(x)``:
``ā`` is the point of least power distance ``max_i (‖x − a_i‖² − r_i²)`` in the halfspaces and
``ρ²`` minus that distance). In 2-D the optimum is supported on at most three constraints
(Carathéodory for the cone of ``(a_i, 1)``, ``(−n_k/2, 0)``):
:func:`bounding_disc` solves the KKT system of every support of one to three constraints with
at least one disc and keeps the smallest ``ρ²`` of the clipped, rescaled multipliers. Every
candidate is a feasible multiplier set, so every candidate disc contains ``S`` (B1), and the
minimum is the optimum of the relaxation (exact, no iterations, no solver; no SDP solver is
installed). The "ellipses" of the cited algorithm are therefore discs here: the S-procedure
cannot use the shape of a lens between two anchor circles, it can only take a disc through its
tips. Two equal circles at distance ``2d`` (radius ``r > d``) give the disc of radius
``√(r² − d²)`` through the lens tips, where the minimum-area ellipse has the lens width
``2(r − d)`` as its minor axis.

**Distributed iteration** (as POA-NBP Algorithm 1 and
:func:`~phyloc.localization.static.ellipses.ellipse_outer_approximation`, Jacobi): in iteration
1 each agent ``j`` bounds ``S_j = R ∩ ⋂_{anchors i} B(x_i, ẑ_{i→j})``; in iteration ``l >= 2``
it adds its own disc of iteration ``l − 1`` and every agent neighbour's disc ``D(c_i, ρ_i)``
grown by the range, ``D(c_i, ρ_i + ẑ_{i→j})`` — exactly the set of points within ``ẑ`` of
the neighbour's disc, so a disc stays a disc and cooperation adds no further approximation. The
region ``R`` enters as its halfspaces and as the disc around its vertices (the minimum-area
ellipse of a square is that disc, so an agent without anchors starts from the same set as in
the exact baseline). The own disc is in the pencil, so a disc never grows. Agents broadcast 3
floats per disc (centre, radius).

This is our reading of the cited algorithm: its papers were not available to us; the
formulation is the standard convex (S-procedure) outer approximation the POA-NBP paper
describes, for the discs of non-negative ranging errors.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization." (Cited here: §III-C, §V-B, Fig. 9; its refs. [8], [10], [39], [42].)
M. R. Gholami, H. Wymeersch, E. G. Ström and M. Rydström, "Wireless network positioning as a
convex feasibility problem", EURASIP J. Wireless Commun. Netw. 2011:161 (outer approximation of
the feasible set, cooperative outer-approximation algorithm); M. R. Gholami, H. Wymeersch and
S. Gezici, "Distributed bounding of feasible sets in cooperative wireless network positioning",
IEEE Commun. Lett. 17, 2013.
S. Boyd, L. El Ghaoui, E. Feron and V. Balakrishnan, *Linear Matrix Inequalities in System and
Control Theory*, SIAM 1994, §2.6.3 (S-procedure), §3.7.3.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import time
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.results import Result
from phyloc.localization.static.ellipses import EllipseResult
from phyloc.localization.static.nbp import NBPOptions, run_nbp
from phyloc.localization.static.poa_network import _network_inputs, _region
from phyloc.localization.static.static_ranges import StaticMeasurements, StaticPrior, check_inputs

#: Floats an agent broadcasts per disc: centre (2) and radius (1).
FLOATS_PER_DISC = 3.0


def bounding_disc(centers, radii, normals=None, offsets=None):
    """The S-procedure bound of ``⋂_i B(a_i, r_i) ∩ ⋂_k {n_kᵀx <= c_k}``: the smallest pencil
    disc (module docstring, eqs. (B1), (B2)).

    Parameters
    ----------
    centers : [m, 2] float64
        Disc centres ``a_i`` [m], ``m >= 1``.
    radii : [m] float64
        Disc radii ``r_i >= 0`` [m].
    normals, offsets : [p, 2], [p] float64, optional
        Halfspaces ``n_kᵀx <= c_k``.

    Returns
    -------
    center : [2] float64
        ``ā`` [m].
    radius2 : float
        ``ρ²`` [m²]; ``<= 0`` when the constraints have no common interior point (the set is
        empty or a point).
    weights : [m] float64
        The disc multipliers ``w`` (sum 1).
    mu : [p] float64
        The halfspace multipliers ``μ >= 0``.

    Examples
    --------
    Two unit circles 1 m apart: the disc through the tips of their lens.

    >>> c, r2, w, _ = bounding_disc([[0.0, 0.0], [1.0, 0.0]], [1.0, 1.0])
    >>> c.round(12).tolist(), round(r2, 12), w.round(12).tolist()
    ([0.5, 0.0], 0.75, [0.5, 0.5])
    """
    a = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    m = a.shape[0]
    if m < 1 or r.shape != (m,):
        raise ValidationError("centers, radii", (a.shape, r.shape), "m >= 1 discs, m radii")
    if normals is None:
        nvec, cvec = np.empty((0, 2)), np.empty(0)
    else:
        nvec = np.asarray(normals, dtype=np.float64).reshape(-1, 2)
        cvec = np.asarray(offsets, dtype=np.float64).reshape(-1)
        if cvec.shape != (nvec.shape[0],):
            raise ValidationError("offsets", cvec.shape, f"must be ({nvec.shape[0]},)")
    origin = a.mean(axis=0)  # translate: keeps ‖a‖² and the offsets small
    a0 = a - origin
    b = np.einsum("ij,ij->i", a0, a0) - r * r  # f_i(x) = ‖x‖² − 2a_iᵀx + b_i
    c0 = cvec - nvec @ origin
    rho2, abar, mult = _smallest_pencil_disc(a0, b, nvec, c0)
    return abar + origin, rho2, mult[:m], mult[m:]


def _smallest_pencil_disc(a, b, normals, offsets):
    """``(ρ², ā, multipliers)`` of the smallest pencil disc of the discs ``‖x‖² − 2aᵀx + b <= 0``
    and halfspaces ``nᵀx <= c`` (:func:`bounding_disc`).

    For every support of 1–3 constraints whose first is a disc ``i``, the KKT system of
    ``min_{h <= 0} max_j f_j`` in ``(x, λ_2 … λ_q)``: the other constraints active
    (``f_j − f_i = −2(a_j − a_i)ᵀx + b_j − b_i = 0``, ``n_kᵀx = c_k``) and stationarity
    ``x = a_i + Σ λ_j D_j`` (``D_j = a_j − a_i`` for a disc, ``−n_j/2`` for a halfspace; the
    disc weights sum to 1). Its multipliers, clipped at 0 and rescaled to ``Σ w = 1``, are a
    feasible point of (B1) whatever the support, so its disc (B2) contains the set; the smallest
    over all supports is the optimum. The supports of three are skipped when the best of one
    and two closes the duality gap (``max_j f_j(ā) = −ρ²`` at a feasible ``ā``)."""
    m, p = a.shape[0], normals.shape[0]
    n_tot = m + p
    is_disc = np.arange(n_tot) < m
    g = np.vstack([a, -0.5 * normals])  # ā = Σ λ_j g_j
    s = np.concatenate([-b, offsets])  # ρ² = ‖ā‖² + Σ λ_j s_j
    L_hs = np.vstack([np.zeros((m, 2)), normals])  # activity rows of the halfspaces
    R_hs = np.concatenate([np.zeros(m), offsets])
    b_all = np.concatenate([b, np.zeros(p)])
    scale2 = 1.0 + float(np.max(np.abs(b))) + float(np.max(np.abs(offsets), initial=0.0)) ** 2
    best_rho2, best_abar, best_mult = math.inf, None, None
    for size in (1, 2, 3):
        if size == 3 and best_abar is not None:
            x = best_abar
            primal = float(np.max(x @ x - 2.0 * a @ x + b))
            if np.all(normals @ x <= offsets + 1e-12 * math.sqrt(scale2)) and (
                primal + best_rho2 <= 1e-12 * scale2
            ):
                break
        sup = _supports(m, n_tot, size)
        if sup.shape[0] == 0:
            continue
        lam = np.ones((sup.shape[0], 1))
        if size > 1:
            i, rest = sup[:, 0], sup[:, 1:]
            disc = is_disc[rest]
            D = np.where(disc[..., None], g[rest] - g[i][:, None], g[rest])  # [K, q, 2]
            L = np.where(disc[..., None], -2.0 * D, L_hs[rest])
            R = np.where(disc, b[i][:, None] - b_all[rest], R_hs[rest])
            K, q = rest.shape
            M = np.zeros((K, q + 2, q + 2))
            rhs = np.zeros((K, q + 2))
            M[:, :q, :2] = L
            rhs[:, :q] = R
            M[:, q:, :2] = np.eye(2)
            M[:, q:, 2:] = -np.swapaxes(D, 1, 2)
            rhs[:, q:] = g[i]
            det = np.linalg.det(M)
            ok = np.abs(det) > 1e-10 * np.prod(np.linalg.norm(M, axis=2), axis=1)
            sol = np.linalg.solve(M[ok], rhs[ok][..., None])[..., 0]
            rest_lam = sol[:, 2:]
            first = 1.0 - np.where(disc[ok], rest_lam, 0.0).sum(axis=1)
            lam = np.column_stack([first, rest_lam])
            sup = sup[ok]
            fine = np.all(np.isfinite(lam) & (np.abs(lam) < 1e9), axis=1)
            lam, sup = lam[fine], sup[fine]
        lam = np.maximum(lam, 0.0)  # feasible multipliers: w, μ >= 0 ...
        total = np.where(is_disc[sup], lam, 0.0).sum(axis=1)
        keep = total > 1e-12
        lam, sup = lam[keep] / total[keep, None], sup[keep]  # ... scaled to Σ w = 1
        if lam.shape[0] == 0:
            continue
        abar = np.einsum("kq,kqd->kd", lam, g[sup])
        rho2 = np.einsum("kd,kd->k", abar, abar) + np.einsum("kq,kq->k", lam, s[sup])
        k = int(np.argmin(rho2))
        if rho2[k] < best_rho2:
            best_rho2, best_abar = float(rho2[k]), abar[k]
            best_mult = np.zeros(n_tot)
            np.add.at(best_mult, sup[k], lam[k])
    return best_rho2, best_abar, best_mult


@functools.lru_cache(maxsize=256)
def _supports(n_discs: int, n_total: int, size: int) -> np.ndarray:
    """Sorted index tuples of ``size`` of the ``n_total`` constraints whose first (smallest)
    one is a disc (discs are ``0 … n_discs − 1``); read-only (cached)."""
    rows = [c for c in itertools.combinations(range(n_total), size) if c[0] < n_discs]
    out = np.array(rows, dtype=np.int64).reshape(-1, size)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class BoundingResult(EllipseResult):
    """Output of :func:`feasible_set_bounding`: an
    :class:`~phyloc.localization.static.ellipses.EllipseResult` whose ellipses are discs
    (``shapes[a] = ρ_a² I``; ``n_directions`` 0: no polygonal intermediate sets).

    Attributes
    ----------
    radii : [n_agents] float64
        ``ρ_a`` [m] (0 where unbounded).
    """

    radii: np.ndarray = None


def _region_parts(R):
    """Halfspaces ``(A, c)`` of the region polygon and its enclosing disc (centre of its
    bounding box, radius to the farthest vertex; for a box the circumscribed circle, which is
    also its minimum-area ellipse)."""
    if R is None:
        return np.empty((0, 2)), np.empty(0), None
    A, c = R.halfspaces()
    w = R.vertices
    centre = 0.5 * (w.min(axis=0) + w.max(axis=0))
    return A, c, (centre, float(np.max(np.linalg.norm(w - centre, axis=1))))


def _consistent(fixed, measured, normals, offsets):
    """The measured discs kept: all of them when ``fixed`` and they have a common interior
    point (``ρ² > 0``, the usual case), else in their order each one that keeps the set of
    those before it non-empty (:func:`~phyloc.localization.static.poa_network.poa`'s rule)."""

    def nonempty(parts):
        return bounding_disc([c for c, _ in parts], [r for _, r in parts], normals, offsets)[1] > 0

    if not measured:
        return []
    if nonempty(fixed + [(c, r) for _, c, r in measured]):
        return list(measured)
    kept = []
    for item in measured:
        trial = fixed + [(c, r) for _, c, r in kept] + [item[1:]]
        if nonempty(trial):
            kept.append(item)
    return kept


def feasible_set_bounding(
    positions, ranges, anchors, *, n_iterations: int = 2, region=None
) -> BoundingResult:
    """Distributed bounding of feasible sets (the cited ellipse baseline of POA-NBP Fig. 9 and
    'NBP ell.'; module docstring): every agent's S-procedure disc, iterated over the network.

    * iteration 1: ``D_j`` bounds ``R ∩ ⋂_{anchors i} B(x_i, ẑ_{i→j})``;
    * iteration ``l >= 2`` (Jacobi): ``D_j`` bounds ``D_j^{(l−1)} ∩ R ∩ ⋂_{anchors}
      B(x_i, ẑ_{i→j}) ∩ ⋂_{agents i} B(c_i, ρ_i + ẑ_{i→j})`` with the neighbours' discs of
      iteration ``l − 1``;

    each by :func:`bounding_disc`, the region ``R`` as its halfspaces and its enclosing disc.
    Every disc contains its feasible set (eq. (B1)), so with errors ``ε >= 0`` every disc
    contains its agent, and no disc grows. Measurements are dropped as in
    :func:`~phyloc.localization.static.poa_network.poa`: a negative range, and — only where
    the constraints have no common interior point (``ρ² <= 0``, possible only with negative
    errors) — in the order anchors, then agent neighbours by node index, each measurement that
    empties the set of the region, the own disc and the measurements kept before it; a dropped
    measurement stays dropped in later iterations.

    Parameters
    ----------
    positions, ranges, anchors, region
        As in :func:`~phyloc.localization.static.poa_network.poa` (``ranges[j, i] = ẑ_{i→j}``,
        the other direction where it is missing).
    n_iterations : int
        ``N_FS >= 1``.

    Returns
    -------
    BoundingResult
        ``area_history [n_iterations, n_agents]``: ``π ρ²`` after each iteration (``inf``
        while unbounded: no region and no anchor yet).

    Examples
    --------
    >>> pos = np.array([[0.0, 0.0], [20.0, 0.0], [10.0, 5.0]])
    >>> z = np.full((3, 3), np.nan); z[2, :2] = [11.2, 11.2]   # agent 2, two anchors
    >>> b = feasible_set_bounding(pos, z, [0, 1], n_iterations=1)
    >>> b.centers[0].round(6).tolist(), round(float(b.radii[0]), 6)
    ([10.0, 0.0], 5.043808)
    """
    pos, z, is_anchor = _network_inputs(positions, ranges, anchors)
    n_iter = v.integer("n_iterations", n_iterations, minimum=1)
    R = _region(region)
    region_A, region_c, region_disc = _region_parts(R)
    agents = np.flatnonzero(~is_anchor)
    slot = np.full(pos.shape[0], -1, dtype=np.int64)
    slot[agents] = np.arange(agents.size)
    link = np.isfinite(z)
    discs: list[tuple[np.ndarray, float] | None] = [None] * agents.size
    areas = np.empty((n_iter, agents.size))
    dropped: list[tuple[int, int, int]] = []
    bad = set()
    for it in range(n_iter):
        new = list(discs)
        for a, j in enumerate(agents):
            fixed = []  # (centre, radius) of the region's disc and the agent's own disc
            if region_disc is not None:
                fixed.append(region_disc)
            if discs[a] is not None:
                fixed.append(discs[a])
            measured = []  # (node i, centre, radius): anchors first, then agents by index
            for i in sorted(np.flatnonzero(link[j]), key=lambda i: (not is_anchor[i], i)):
                key = (int(i), int(j))
                if key in bad or i == j:
                    continue
                if not is_anchor[i] and (it == 0 or discs[slot[i]] is None):
                    continue
                zz = float(z[j, i])
                if zz < 0.0:
                    dropped.append((*key, it + 1))
                    bad.add(key)
                elif is_anchor[i]:
                    measured.append((int(i), pos[i], zz))
                else:
                    c_i, r_i = discs[slot[i]]
                    measured.append((int(i), c_i, r_i + zz))
            kept = _consistent(fixed, measured, region_A, region_c)
            for i in sorted({i for i, _, _ in measured} - {i for i, _, _ in kept}):
                dropped.append((i, int(j), it + 1))
                bad.add((i, int(j)))
            parts = fixed + [(c, r) for _, c, r in kept]
            if parts:
                centres = [c for c, _ in parts]
                c, rho2, _, _ = bounding_disc(centres, [r for _, r in parts], region_A, region_c)
                if rho2 > 0.0:
                    new[a] = (c, math.sqrt(rho2))
            areas[it, a] = math.pi * new[a][1] ** 2 if new[a] is not None else math.inf
        discs = new
    centers = np.zeros((agents.size, 2))
    radii_out = np.zeros(agents.size)
    for a, d in enumerate(discs):
        if d is not None:
            centers[a], radii_out[a] = d
    return BoundingResult(
        agents=agents,
        centers=centers,
        shapes=radii_out[:, None, None] ** 2 * np.eye(2),
        bounded=np.array([d is not None for d in discs], dtype=bool),
        area_history=areas,
        dropped=np.array([(i, j) for i, j, _ in dropped], dtype=np.int64).reshape(-1, 2),
        dropped_iteration=np.array([it for _, _, it in dropped], dtype=np.int64),
        n_directions=0,
        radii=radii_out,
    )


def run_nbp_bounding(
    measurements: StaticMeasurements,
    prior: StaticPrior,
    rng: np.random.Generator,
    options: NBPOptions | None = None,
) -> Result:
    """NBP with the uniform proposal in each agent's bounding disc (:func:`feasible_set_bounding`
    over ``options.poa_n_fs`` iterations): 'NBP ell.' of POA-NBP (its ref. [39]) with the
    ellipses it cites. Registered as ``nbp_bounding``.

    As :func:`~phyloc.localization.static.nbp.run_nbp` with ``proposal="polygon"``; the discs
    are computed here (no random draws) unless ``prior.polygons`` brings support regions. The
    diagnostics add ``support = "bounding"``, ``bounding_area_m2 [N_FS, n_agents]``,
    ``setup_time_per_node_s`` (the bounding, per agent) and
    ``support_floats_per_link_iteration`` = 3 (centre and radius per broadcast; NaN for
    ``N_FS = 1``); the bounding's operations are not counted (0), as the exact ellipses'.

    Examples
    --------
    >>> anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
    >>> z = np.full((5, 5), np.nan)
    >>> z[4, :4] = [13.2, 17.2, 11.6, 16.0]
    >>> meas, prior = StaticMeasurements(z, [0, 1, 2, 3], anchors), StaticPrior((0, 0, 20, 20))
    >>> res = run_nbp_bounding(meas, prior, np.random.default_rng(3),
    ...                        NBPOptions(n_samples=50, n_iterations=2, proposal="polygon"))
    >>> res.estimates.shape, res.diagnostics["support"]
    ((2, 1, 2), 'bounding')
    """
    opt = options if options is not None else NBPOptions(proposal="polygon")
    if not isinstance(opt, NBPOptions):
        raise ValidationError("options", type(opt).__name__, "must be NBPOptions")
    if opt.proposal != "polygon":
        raise ValidationError("options.proposal", opt.proposal, "'polygon' (the disc proposal)")
    meas, prior = check_inputs(measurements, prior, rng)
    areas = None
    if prior.polygons is None:
        t0 = time.perf_counter()
        b = feasible_set_bounding(
            meas.positions,
            meas.ranges,
            meas.is_anchor,
            n_iterations=opt.poa_n_fs,
            region=prior.region,
        )
        t = (time.perf_counter() - t0) / max(meas.n_agents, 1)
        areas = b.area_history
        prior = dataclasses.replace(
            prior,
            polygons=b.regions(),
            polygon_time_per_node_s=t,
            polygon_operations_per_node=0.0,  # not counted
            polygon_floats_per_link_iteration=FLOATS_PER_DISC if opt.poa_n_fs > 1 else math.nan,
        )
    res = run_nbp(meas, prior, rng, opt)
    if areas is not None:
        res.diagnostics["support"] = "bounding"
        res.diagnostics["bounding_area_m2"] = areas
    return res
