"""PHY core: OFDM system, link budget, symbols and waveforms, multipath synthesis, correlation
tables and ranging bounds (DiPNet paper §II-B, §III-B)."""

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
