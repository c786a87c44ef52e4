"""Which distances of a network the measured links determine (generic infinitesimal rigidity).

A framework distance ``‖p_u − p_v‖`` can only be estimated when the links that carry
information fix it: three agents with two detected links can flex about their common node, and
the third distance is then arbitrary for every method, the oracle included. The test here is
the classical one for bar frameworks: build the rigidity matrix of the link graph at *generic*
positions (random ones; the rank is the same for almost every placement), and call the pair
``(u, v)`` *determined* when its own row ``∂‖p_u − p_v‖/∂p`` lies in the row space of the
links' rows, i.e. when adding the pair as a link would not raise the rank. Anchors are fixed:
their coordinates are not variables.

This is infinitesimal rigidity, a property of the graph alone (it does not use where the
nodes really are). It does not exclude discrete ambiguities (a flip of a node linked to only
``dim`` others), which a filter may still resolve wrongly; those count as determined.

References
----------
B. Roth, "Rigid and flexible frameworks," The American Mathematical Monthly 88(1), pp. 6–21,
1981.
L. Asimow and B. Roth, "The rigidity of graphs," Trans. Amer. Math. Soc. 245, pp. 279–289, 1978.
G. Laman, "On graphs and rigidity of plane skeletal structures," J. Engineering Mathematics
4(4), pp. 331–340, 1970.
"""

from __future__ import annotations

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError


def _rows(pos, pairs, free):
    """Rigidity-matrix rows of ``pairs`` at ``pos``, restricted to the free coordinates."""
    n, dim = pos.shape
    R = np.zeros((len(pairs), n * dim))
    for r, (a, b) in enumerate(pairs):
        d = pos[a] - pos[b]
        d = d / np.linalg.norm(d)
        R[r, a * dim : (a + 1) * dim] = d
        R[r, b * dim : (b + 1) * dim] = -d
    return R[:, free]


def determined_pairs(n_nodes, edges, pairs, dim, rng, *, fixed=None, tol=1e-8) -> np.ndarray:
    """For each pair of ``pairs``, whether the links ``edges`` determine its distance.

    Parameters
    ----------
    n_nodes : int
        Number of nodes.
    edges : [n_edges, 2] int
        The links that carry information (either direction; duplicates are fine).
    pairs : [n_pairs, 2] int
        The distances asked about (``u != v``).
    dim : int
        2 or 3.
    rng : numpy.random.Generator
        Draws the generic positions (the answer does not depend on them, almost surely).
    fixed : [n_nodes] bool, optional
        Anchors: nodes whose positions are known.
    tol : float
        Relative tolerance of the row-space test.

    Returns
    -------
    [n_pairs] bool
        True where the distance is (infinitesimally) fixed by the links. A pair of two fixed
        nodes is always determined.

    Examples
    --------
    A triangle missing one side flexes; the complete graph on four nodes minus one side does
    not (in the plane):

    >>> rng = np.random.default_rng(0)
    >>> determined_pairs(3, [[0, 1], [1, 2]], [[0, 2]], 2, rng).tolist()
    [False]
    >>> k4_minus = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3]]
    >>> determined_pairs(4, k4_minus, [[2, 3]], 2, rng).tolist()
    [True]
    """
    n = v.integer("n_nodes", n_nodes, minimum=1)
    dim = v.integer("dim", dim, minimum=1)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    for name, arr in (("edges", edges), ("pairs", pairs)):
        if arr.size and (arr.min() < 0 or arr.max() >= n):
            raise ValidationError(name, f"node {int(arr.max())}", f"node indices in [0, {n})")
        if arr.size and np.any(arr[:, 0] == arr[:, 1]):
            raise ValidationError(name, "a pair (u, u)", "two different nodes per row")
    fixed = np.zeros(n, bool) if fixed is None else np.asarray(fixed, dtype=bool)
    if fixed.shape != (n,):
        raise ValidationError("fixed", f"shape {fixed.shape}", f"[n_nodes] = [{n}]")
    pos = rng.standard_normal((n, dim))
    free = np.repeat(~fixed, dim)
    out = np.ones(len(pairs), bool)
    if not free.any() or not len(pairs):
        return out
    asked = _rows(pos, pairs, free)
    if not len(edges):
        return ~np.any(np.abs(asked) > 0, axis=1)
    R = _rows(pos, edges, free)
    # null space of R: the infinitesimal motions the links allow
    _, s, vt = np.linalg.svd(R, full_matrices=True)
    rank = int(np.sum(s > tol * max(s[0], 1.0))) if s.size else 0
    null = vt[rank:]
    if not null.size:
        return out
    return np.max(np.abs(asked @ null.T), axis=1) <= np.sqrt(tol)
