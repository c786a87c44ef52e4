"""phyloc: signal-level PHY simulation and direct localization of wireless networks.

The package is layered (see ``DESIGN.md``): :mod:`phyloc.phy` and :mod:`phyloc.channels` at the
bottom, :mod:`phyloc.network` beside them, ranging and localization above, datasets and
evaluation on top, and the command line (:mod:`phyloc.cli`) last.
"""

from importlib.metadata import PackageNotFoundError, version

from phyloc.errors import PhylocError, ValidationError

try:
    __version__ = version("phyloc")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

__all__ = ["PhylocError", "ValidationError", "__version__"]
