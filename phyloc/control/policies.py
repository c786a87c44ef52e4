"""Control policies of the mobile anchors: static, random, FIM-myopic, FIM receding horizon.

======================  ==============================================================
policy                  the next control of every mobile anchor
======================  ==============================================================
``static``              none: the anchors never move (baseline)
``random``              independent uniform draws from U (baseline)
``fim_myopic``          argmin of the next step's FIM cost, FIM [11] (exact search, T = 1)
``fim_rh``              receding horizon, FIM [12]–[16]: the first control of the best
                        sequence over ``horizon`` steps (``search``, ``discount``, ``beam``)
======================  ==============================================================

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys, check_types
from phyloc.control.search import SEARCHES, ControlProblem, search
from phyloc.errors import ValidationError

POLICIES = ("static", "random", "fim_myopic", "fim_rh")


@dataclass(frozen=True)
class PolicySpec:
    """A control policy and its search.

    Parameters
    ----------
    policy : {"static", "random", "fim_myopic", "fim_rh"}
    horizon : int
        T of ``fim_rh`` (3); ``fim_myopic`` is T = 1 whatever is given.
    search : {"exact", "vbest", "approx", "approx_parallel"}
        How ``fim_rh`` searches (``exact``); see :mod:`phyloc.control.search`.
    discount : float
        γ (0.9, FIM [12]).
    beam : int
        V of the ``vbest`` search (10).
    agent_terms : bool
        Agent–agent ranges in the FIM (False, as the paper).

    Examples
    --------
    >>> PolicySpec.from_dict({"policy": "fim_rh", "horizon": 5, "search": "vbest"}).beam
    10
    """

    policy: str = "fim_rh"
    horizon: int = 3
    search: str = "exact"
    discount: float = 0.9
    beam: int = 10
    agent_terms: bool = False

    def __post_init__(self):
        v.choice("policy", self.policy, POLICIES)
        v.choice("search", self.search, SEARCHES)
        horizon = v.integer("horizon", self.horizon, minimum=1)
        object.__setattr__(self, "horizon", 1 if self.policy == "fim_myopic" else horizon)
        d = v.positive("discount", self.discount)
        if d > 1.0:
            raise ValidationError("discount", self.discount, "must be in (0, 1]")
        object.__setattr__(self, "beam", v.integer("beam", self.beam, minimum=1))
        object.__setattr__(self, "agent_terms", v.boolean("agent_terms", self.agent_terms))

    @classmethod
    def from_dict(cls, d: dict, where: str = "policy") -> PolicySpec:
        """From a recipe table; unknown keys are errors naming the closest valid key."""
        check_keys(d, [f.name for f in dataclasses.fields(cls)], where)
        check_types(cls, d, where)
        try:
            return cls(**d)
        except ValidationError as exc:
            raise ValidationError(f"{where}.{exc.field}", exc.value, exc.allowed) from None


def decide(spec: PolicySpec, problem: ControlProblem, rng: np.random.Generator) -> np.ndarray:
    """The policy's next controls ``[M₁, dim]`` [m/s] for ``problem``.

    ``rng`` is used by ``random`` only (one index per mobile anchor per decision).

    Examples
    --------
    >>> from phyloc.control.search import ControlProblem
    >>> U = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    >>> p = ControlProblem(np.zeros((1, 2)), np.eye(2)[None], np.eye(2), np.zeros((2, 2)),
    ...                    np.array([[0.0, 5.0]]), np.array([[5.0, 0.0]]), U, 1.0, 1.0)
    >>> decide(PolicySpec("static"), p, np.random.default_rng(0)).tolist()
    [[0.0, 0.0]]
    """
    M1, dim = problem.mobile.shape
    if spec.policy == "static":
        return np.zeros((M1, dim))
    if spec.policy == "random":
        return problem.controls[rng.integers(problem.controls.shape[0], size=M1)]
    u, _ = search(
        problem,
        spec.horizon,
        method="exact" if spec.policy == "fim_myopic" else spec.search,
        discount=spec.discount,
        beam=spec.beam,
    )
    return u
