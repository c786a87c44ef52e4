"""Active anchors: Fisher-information control of mobile anchors (myopic and receding horizon).

After W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach" (arXiv:2212.14554; "FIM [n]" cites its equation n). Two layers:

* estimation: Gaussian beliefs of the agents from a step-by-step tracker of the tracking family
  (:class:`~phyloc.localization.tracking.spbp.SPBPTracker`, the paper's SP-BP, or
  :class:`~phyloc.localization.tracking.pfbp.PFBPTracker`);
* control: each mobile anchor's next velocity from a finite set U, minimizing the sum over
  agents of the traces of the inverse approximate Bayesian FIMs of their next positions
  (:mod:`~phyloc.control.fim`), myopically or over a receding horizon
  (:mod:`~phyloc.control.search`, :mod:`~phyloc.control.policies`).

:mod:`~phyloc.control.loop` closes the loop for one Monte Carlo trial; the experiment
``kind = "control"`` (:mod:`phyloc.evaluation.control_experiment`) runs many.

Examples
--------
>>> import numpy as np
>>> from phyloc.control import ControlProblem, control_set, search
>>> p = ControlProblem(np.zeros((1, 3)), np.eye(3)[None] * 100.0, np.eye(3), np.zeros((3, 3)),
...                    np.array([[0.0, 50.0, 0.0]]), np.array([[50.0, 0.0, 0.0]]),
...                    control_set(), 1.0, 0.1)
>>> u, cost = search(p, 2, method="exact")
>>> u.shape, bool(cost > 0)
((1, 3), True)

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from phyloc.control.fim import control_set, position_cost, range_information, update_covariance
from phyloc.control.loop import (
    ControlScenario,
    draw_trial,
    make_estimator,
    realized_network,
    run_policy,
)
from phyloc.control.policies import POLICIES, PolicySpec, decide
from phyloc.control.search import SEARCHES, ControlProblem, joint_controls, search

__all__ = [
    "POLICIES",
    "SEARCHES",
    "ControlProblem",
    "ControlScenario",
    "PolicySpec",
    "control_set",
    "decide",
    "draw_trial",
    "joint_controls",
    "make_estimator",
    "position_cost",
    "range_information",
    "realized_network",
    "run_policy",
    "search",
    "update_covariance",
]
