"""Rigid alignment of point sets (Kabsch/Umeyama without scale).

One implementation serves the evaluation metrics (:func:`phyloc.evaluation.metrics.rigid_align`)
and the truth-free initialization (anchoring a coarse solution's frame,
:func:`phyloc.localization.initialization.coarse_positions`).

References
----------
W. Kabsch, "A solution for the best rotation to relate two sets of vectors," Acta Cryst. A32,
1976. S. Umeyama, "Least-squares estimation of transformation parameters between two point
patterns," IEEE Trans. PAMI 13(4), 1991.
"""

from __future__ import annotations

import numpy as np


def orthogonal_fit(a: np.ndarray, b: np.ndarray, reflection: bool = True) -> np.ndarray:
    """Orthogonal ``W`` minimising ``Σ‖W a_i − b_i‖²`` (Kabsch/Umeyama without scale).

    With ``H = aᵀ b = U S Vᵀ``, ``W = V D Uᵀ``, ``D = I`` or ``diag(1, …, 1, det(V Uᵀ))``:
    ``det W = +1`` unless ``reflection``. Rank-deficient ``a``/``b`` give one of the minimisers.

    Parameters
    ----------
    a, b : [n, dim] float64
        Centred point sets.
    reflection : bool
        Allow ``det W = −1``.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]])
    >>> rot = np.array([[0.0, -1.0], [1.0, 0.0]])
    >>> bool(np.allclose(orthogonal_fit(a, a @ rot.T), rot))
    True
    """
    h = a.T @ b
    u, _, vt = np.linalg.svd(h)
    w = vt.T @ u.T
    if not reflection and np.linalg.det(w) < 0:
        d = np.ones(h.shape[0])
        d[-1] = -1.0
        w = vt.T @ (d[:, None] * u.T)
    return w


def kabsch(
    src: np.ndarray, dst: np.ndarray, reflection: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` with R orthogonal minimising ``Σ‖R s_i + t − d_i‖²``.

    Parameters
    ----------
    src, dst : [n, dim] float64
        Corresponding points.
    reflection : bool
        Allow ``det R = −1`` (default True).

    Returns
    -------
    R : [dim, dim] float64
    t : [dim] float64

    Examples
    --------
    >>> import numpy as np
    >>> src = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    >>> R, t = kabsch(src, src + [3.0, -1.0])
    >>> bool(np.allclose(R, np.eye(2))), np.round(t, 12).tolist()
    (True, [3.0, -1.0])
    """
    sm, dm = src.mean(axis=0), dst.mean(axis=0)
    R = orthogonal_fit(src - sm, dst - dm, reflection)
    return R, dm - R @ sm
