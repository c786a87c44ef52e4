"""phyloc benchmarks, in the shape of an asv suite (classes with ``params``, ``setup`` and
``time_*`` methods) plus a ``report(quick)`` function per module that ``phyloc bench`` runs.

The build installs this folder as ``phyloc.benchmarks`` so the command finds it.
"""
