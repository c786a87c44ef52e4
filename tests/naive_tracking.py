"""Plain-NumPy twin of the trackers' bookkeeping kernel
(``phyloc.localization.tracking._kernels.mean_cov_kernel``)."""

import numpy as np


def mean_cov_numpy(X):
    """Per agent sample mean and (1/M) covariance of ``X [n_agents, M, n]``."""
    mean = X.mean(axis=1)
    dev = X - mean[:, None, :]
    return mean, np.einsum("ami,amj->aij", dev, dev) / X.shape[1]
