"""PHY core: OFDM system, link budget, symbols and waveforms, multipath synthesis, correlation
tables and ranging bounds (DiPNet §II-B, §III-B).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

S. M. Kay, *Fundamentals of Statistical Signal Processing, Volume I: Estimation Theory*,
Prentice Hall, 1993 (the Cramér–Rao bound, ch. 3).
"""

from phyloc.phy.paths import PathSet
from phyloc.phy.system import (
    C0,
    K_BOLTZMANN,
    OFDMSystem,
    db_to_linear,
    dbm_to_watt,
    free_space_path_loss_db,
    linear_to_db,
    watt_to_dbm,
)

__all__ = [
    "C0",
    "K_BOLTZMANN",
    "OFDMSystem",
    "PathSet",
    "db_to_linear",
    "dbm_to_watt",
    "free_space_path_loss_db",
    "linear_to_db",
    "watt_to_dbm",
]
