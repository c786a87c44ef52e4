"""The one bibliography of phyloc: the canonical reference of every source cited in several places.

A module's ``References`` section cites a source by copying its entry from here, unchanged:
``"<short name>: <text>"`` for the papers phyloc implements (their short names are the ones
equation citations use, e.g. "DiPNet eq. (26)"), the text alone for the other sources. The test
suite (``tests/test_references.py``) reads the ``References`` section of every module under
``phyloc/`` and ``benchmarks/`` and fails, naming every file at once, where an entry that
starts with a short name, or that names the title of a paper with a short name, differs from
its entry, or where an entry naming the title of another source listed here gives other
authors or another title (notes and links after the title may differ from module to module).
To correct a reference, correct it here and in the modules the test then names.

Examples
--------
>>> from phyloc.references import PAPERS, entry
>>> entry("DiPNet").startswith("DiPNet: S. Zhang")
True
>>> "Kay" in PAPERS and entry("Kay").startswith("S. M. Kay")
True

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."

POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."

FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.

SP-BP: F. Meyer, O. Hlinka and F. Hlawatsch, "Sigma point belief propagation," IEEE Signal
Processing Letters 21(2), pp. 145–149, 2014.

WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.

S. M. Kay, *Fundamentals of Statistical Signal Processing, Volume I: Estimation Theory*,
Prentice Hall, 1993 (the Cramér–Rao bound, ch. 3).

K. L. Bell, Y. Steinberg, Y. Ephraim and H. L. Van Trees, "Extended Ziv–Zakai lower bound for
vector parameter estimation," IEEE Trans. Information Theory 43(2), pp. 624–637, 1997.

D. Dardari, A. Conti, U. Ferner, A. Giorgetti and M. Z. Win, "Ranging with ultrawide
bandwidth signals in multipath environments," Proc. IEEE 97(2), pp. 404–426, 2009 (DiPNet
ref. [29]).

B. H. Fleury, M. Tschudin, R. Heddergott, D. Dahlhaus and K. I. Pedersen, "Channel parameter
estimation in mobile radio environments using the SAGE algorithm," IEEE J. Selected Areas in
Communications 17(3), pp. 434–450, 1999.

P. Tichavský, C. H. Muravchik and A. Nehorai, "Posterior Cramér–Rao bounds for discrete-time
nonlinear filtering," IEEE Trans. Signal Processing 46(5), pp. 1386–1396, 1998.

Y. Bar-Shalom, X. R. Li and T. Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, Wiley, 2001 (direct discrete-time kinematic models, §6.3).

W. Kabsch, "A solution for the best rotation to relate two sets of vectors," Acta Cryst. A32,
1976.

S. Umeyama, "Least-squares estimation of transformation parameters between two point
patterns," IEEE Trans. PAMI 13(4), 1991.

M. Rocklin, "Dask: Parallel computation with blocked algorithms and task scheduling," Proc.
14th Python in Science Conference (SciPy 2015), pp. 130–136, 2015.

NumPy, "Parallel random number generation" (``SeedSequence.spawn``),
https://numpy.org/doc/stable/reference/random/parallel.html.

The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS),
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.
"""

from __future__ import annotations

from phyloc import _validate as v

#: The canonical text of every source, by key. For the papers phyloc implements the key is the
#: short name that equation citations use; a ``References`` entry is then
#: ``"<key>: <text>"`` (:func:`entry`).
PAPERS: dict[str, str] = {
    "DiPNet": (
        "S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and "
        'P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE '
        "Trans. Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020."
    ),
    "PF-BP": (
        'L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D '
        'cooperative localization and navigation with embedded particle flow."'
    ),
    "POA-NBP": (
        'R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative '
        'indoor localization."'
    ),
    "FIM": (
        'W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information '
        'approach," arXiv:2212.14554, 2022.'
    ),
    "SP-BP": (
        'F. Meyer, O. Hlinka and F. Hlawatsch, "Sigma point belief propagation," IEEE Signal '
        "Processing Letters 21(2), pp. 145–149, 2014."
    ),
    "WINNER II": (
        "IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007, "
        "updated 2008; the table each value of the shipped channel files comes from is given "
        "in ``channels/PROVENANCE.md``."
    ),
    "Kay": (
        "S. M. Kay, *Fundamentals of Statistical Signal Processing, Volume I: Estimation "
        "Theory*, Prentice Hall, 1993 (the Cramér–Rao bound, ch. 3)."
    ),
    "Bell": (
        'K. L. Bell, Y. Steinberg, Y. Ephraim and H. L. Van Trees, "Extended Ziv–Zakai lower '
        'bound for vector parameter estimation," IEEE Trans. Information Theory 43(2), '
        "pp. 624–637, 1997."
    ),
    "Dardari": (
        'D. Dardari, A. Conti, U. Ferner, A. Giorgetti and M. Z. Win, "Ranging with ultrawide '
        'bandwidth signals in multipath environments," Proc. IEEE 97(2), pp. 404–426, 2009 '
        "(DiPNet ref. [29])."
    ),
    "Fleury": (
        "B. H. Fleury, M. Tschudin, R. Heddergott, D. Dahlhaus and K. I. Pedersen, "
        '"Channel parameter estimation in mobile radio environments using the SAGE '
        'algorithm," IEEE J. Selected Areas in Communications 17(3), pp. 434–450, 1999.'
    ),
    "Tichavský": (
        'P. Tichavský, C. H. Muravchik and A. Nehorai, "Posterior Cramér–Rao bounds for '
        'discrete-time nonlinear filtering," IEEE Trans. Signal Processing 46(5), '
        "pp. 1386–1396, 1998."
    ),
    "Bar-Shalom": (
        "Y. Bar-Shalom, X. R. Li and T. Kirubarajan, *Estimation with Applications to "
        "Tracking and Navigation*, Wiley, 2001 (direct discrete-time kinematic models, §6.3)."
    ),
    "Kabsch": (
        'W. Kabsch, "A solution for the best rotation to relate two sets of vectors," '
        "Acta Cryst. A32, 1976."
    ),
    "Umeyama": (
        'S. Umeyama, "Least-squares estimation of transformation parameters between two '
        'point patterns," IEEE Trans. PAMI 13(4), 1991.'
    ),
    "Dask": (
        'M. Rocklin, "Dask: Parallel computation with blocked algorithms and task '
        'scheduling," Proc. 14th Python in Science Conference (SciPy 2015), pp. 130–136, '
        "2015."
    ),
    "SeedSequence": (
        'NumPy, "Parallel random number generation" (``SeedSequence.spawn``), '
        "https://numpy.org/doc/stable/reference/random/parallel.html."
    ),
    "HDF5": (
        "The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS), "
        "https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/."
    ),
}

#: The sources cited with their short name in front (``"DiPNet: S. Zhang, …"``): the papers
#: phyloc implements and the WINNER II report.
SHORT_NAMES: tuple[str, ...] = ("DiPNet", "PF-BP", "POA-NBP", "FIM", "SP-BP", "WINNER II")

#: A phrase of each source's title (compared case-insensitively): an entry that contains it
#: cites that source (and must be its entry, or for a source without a short name begin with
#: its authors and title up to this phrase).
TITLES: dict[str, str] = {
    "DiPNet": "distributed direct localization suitable for dense networks",
    "PF-BP": "9-D cooperative localization and navigation",
    "POA-NBP": "position-constrained stochastic inference",
    "FIM": "a Fisher information approach",
    "SP-BP": "sigma point belief propagation",
    "WINNER II": "D1.1.2",
    "Kay": "Fundamentals of Statistical Signal Processing",
    "Bell": "Extended Ziv–Zakai lower bound",
    "Dardari": "Ranging with ultrawide bandwidth signals",
    "Fleury": "using the SAGE algorithm",
    "Tichavský": "Posterior Cramér–Rao bounds for discrete-time",
    "Bar-Shalom": "Estimation with Applications to Tracking and Navigation",
    "Kabsch": "best rotation to relate two sets of vectors",
    "Umeyama": "transformation parameters between two point patterns",
    "Dask": "Dask: Parallel computation",
    "SeedSequence": "Parallel random number generation",
    "HDF5": "HDF5 User's Guide",
}


def entry(key: str) -> str:
    """The ``References`` entry of source ``key``: ``"<key>: <text>"`` for a short name.

    Parameters
    ----------
    key : str
        A key of :data:`PAPERS`.

    Returns
    -------
    str
        The entry on one line (wrap it at will: the check compares whitespace-normalized text).

    Raises
    ------
    ValidationError
        If ``key`` is not a key of :data:`PAPERS`.
    """
    text = PAPERS[v.choice("key", key, PAPERS)]
    return f"{key}: {text}" if key in SHORT_NAMES else text
