"""Plain-NumPy twins of the range flow kernels of ``phyloc.localization.tracking._flow``.

``range_flow_numpy`` is the dense exact Daum–Huang flow (PF-BP eqs. (13), (24), (25), (40)–(43))
with the dense range Jacobian: the generic :func:`~phyloc.localization.tracking._flow.edh_flow`
(tested against the Kalman posterior) on
:func:`~phyloc.localization.tracking._flow.range_linearization` (tested against finite
differences). The numba kernel ``range_flow_kernel`` forms nothing of size ``n × n`` and must
equal it to rounding. ``paired_range_loglik_numpy`` is the vectorized paired Gaussian range
log-likelihood of PF-BP eq. (22). ``benchmarks/bench_pfbp.py`` loads this module (through
``benchmarks/_reference.naive``) to time PF-BP with the NumPy flow.
"""

import numpy as np

from phyloc.localization.tracking._flow import edh_flow, range_linearization


def range_flow_numpy(X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps):
    """NumPy twin of ``range_flow_kernel`` (returns new arrays ``X1 [M, n]``, ``mean1 [n]``)."""
    return edh_flow(
        X,
        mean,
        P,
        lambda x: range_linearization(x, off_a, off_b, anchor_pos, dim),
        z,
        np.diag(r_var),
        lambdas,
        steps,
        n_flow,
    )


def paired_range_loglik_numpy(x, y, z, inv_var):
    """NumPy twin of ``paired_range_loglik_kernel`` (returns the increment ``[M]``)."""
    d = np.linalg.norm(x - y, axis=1)
    return -0.5 * (z - d) ** 2 * inv_var
