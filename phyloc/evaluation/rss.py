"""Resident memory of this process: the current and peak RSS, and a reset of the peak so a
task can measure its own (the tracking memory study, the localization experiment's
``peak_rss_mb`` per network size).

References
----------
Linux ``proc(5)``: ``/proc/self/status`` (``VmRSS``, ``VmHWM``) and ``/proc/self/clear_refs``
(writing 5 resets the peak RSS, Linux >= 4.0); POSIX ``getrusage`` (``ru_maxrss``).
"""

from __future__ import annotations

import math


def status_mb(field: str) -> float:
    """A ``/proc/self/status`` memory field (``VmRSS``, ``VmHWM``) [MB]; NaN where absent."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return float(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    return math.nan


def reset_peak_rss() -> bool:
    """Reset this process's peak RSS (``VmHWM``) to its current RSS (Linux >= 4.0:
    ``echo 5 > /proc/self/clear_refs``); False where that is not possible."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def peak_rss_mb() -> float:
    """This process's peak resident set size so far [MB] (``ru_maxrss``: KiB on Linux)."""
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0**2 if sys.platform == "darwin" else 1024.0)  # bytes on macOS
