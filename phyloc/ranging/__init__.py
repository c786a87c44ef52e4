"""Two-step range estimators and the Gaussian ranging model (DiPNet §V-A, Fig. 4).

Each estimator turns the correlation tables of a batch of links
(:func:`phyloc.phy.correlation.correlation_tables`) into :class:`RangeEstimates`: a range, a
bias-corrected per-sample SNR estimate, the ranging variance (one-path ZZB at that SNR, or the
CRB) and a validity flag.

``corr``        :func:`correlation_peak`: strongest correlation peak, Newton-refined (ML for one
                path).
``first_peak``  :func:`first_peak`: earliest local maximum above thresholds relative to the
                strongest peak and to the noise floor.
``sage``        :func:`sage`: SAGE estimates of L+1 paths; LOS = earliest path above a power
                threshold.
``sage_los``    NLOS-rejected SAGE (:func:`nlos_rejected`): an **oracle** that drops NLOS
                links by ground truth; ``oracle=True`` on its results.

:func:`estimate` dispatches by name; :func:`ranging_variance` gives the model's variance.
:func:`energy_concentration` is a truth-free NLOS identification from the waveform (the share of
a link's correlation energy in its strongest peak, 1 for one path; :mod:`phyloc.ranging.nlos`).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

D. Dardari, A. Conti, U. Ferner, A. Giorgetti and M. Z. Win, "Ranging with ultrawide
bandwidth signals in multipath environments," Proc. IEEE 97(2), pp. 404–426, 2009 (DiPNet
ref. [29]).

B. H. Fleury, M. Tschudin, R. Heddergott, D. Dahlhaus and K. I. Pedersen, "Channel parameter
estimation in mobile radio environments using the SAGE algorithm," IEEE J. Selected Areas in
Communications 17(3), pp. 434–450, 1999.
"""

from phyloc.ranging.estimators import (
    ESTIMATORS,
    METHODS,
    ORACLES,
    correlation_peak,
    estimate,
    first_peak,
    nlos_rejected,
)
from phyloc.ranging.nlos import energy_concentration
from phyloc.ranging.results import RangeEstimates
from phyloc.ranging.sage import sage
from phyloc.ranging.variance import ranging_variance

__all__ = [
    "ESTIMATORS",
    "METHODS",
    "ORACLES",
    "RangeEstimates",
    "correlation_peak",
    "energy_concentration",
    "estimate",
    "first_peak",
    "nlos_rejected",
    "ranging_variance",
    "sage",
]
