"""phyloc: signal-level PHY simulation and direct localization of wireless networks.

The package is layered (see :doc:`/guide/design`): :mod:`phyloc.phy` and :mod:`phyloc.channels`
at the bottom, :mod:`phyloc.network` beside them, ranging and localization above, datasets and
evaluation on top, and the command line (:mod:`phyloc.cli`) last.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."

POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."

WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.
"""

import os
from importlib.metadata import PackageNotFoundError, version

from phyloc.errors import PhylocError, ValidationError

#: Spin count of idle OpenMP threads (GNU libgomp, Numba's ``omp`` threading layer) before they
#: sleep. libgomp's default, 300 000 pause loops, keeps a thread spinning for milliseconds after
#: every parallel kernel; on 2 cores that thread takes a core from the FFTW threads of the
#: correlation tables that follow (measured 2026-11-26: tables 109 µs per link after the
#: parallel synthesis kernel, 75 µs with 10 000; DiPNet per agent-iteration unchanged). Read by
#: libgomp when Numba first starts its threads, so it is set here, before any kernel runs; a
#: value set by the user (``GOMP_SPINCOUNT`` or ``OMP_WAIT_POLICY``) is kept.
GOMP_SPINCOUNT = "10000"
if "GOMP_SPINCOUNT" not in os.environ and "OMP_WAIT_POLICY" not in os.environ:
    os.environ["GOMP_SPINCOUNT"] = GOMP_SPINCOUNT

try:
    __version__ = version("phyloc")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

__all__ = ["PhylocError", "ValidationError", "__version__"]
