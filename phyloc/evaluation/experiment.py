"""One shape for every experiment: the :class:`Experiment` base, the runner and the registry.

Every recipe kind that ``phyloc evaluate`` runs is an :class:`Experiment`: a small object that
says what its recipe means and nothing about how work is scheduled. The runner
(:meth:`Experiment.run`) owns the rest, the same for every kind::

    recipe ──prepare──▶ plan ──tasks──▶ [(key, payload), …]
                                           │ run_tasks: Dask or in-process, one SeedSequence
                                           ▼ per task, kept in OUT/.tasks for --resume
    results.json ◀──meta── figures, series ◀──aggregate── [task result, …]

* :meth:`~Experiment.prepare` validates everything the run reads (both the full and the
  ``[experiment.fast]`` setting are prepared before any work) and returns the plan;
* :meth:`~Experiment.tasks` expands the plan into independent units of work, each a *key*
  (which realization / run / trial block it is) and a picklable *payload*;
* :attr:`~Experiment.task` is a module-level function ``(payload, seed_sequence) -> dict``
  that returns the unit's own values (per realization, per run, per trial) — never a pooled
  number, so that an aggregation can carry an uncertainty for every figure;
* :meth:`~Experiment.aggregate` pools them into flat ``figures`` and array ``series``; a figure
  pooled over units is given as a :class:`~phyloc.evaluation.statistics.Pooled` value (a
  comparison of two over the same units as a :class:`~phyloc.evaluation.statistics.Paired`
  one), and the runner adds its 95 % interval and keeps its per-unit values
  (:func:`~phyloc.evaluation.statistics.resolve`);
* :meth:`~Experiment.meta` adds what a reader needs to interpret them;
* :meth:`~Experiment.plot` and the ``summary_*`` methods only present ``results``.

:data:`phyloc.evaluation.kinds.EXPERIMENTS` is the one registry of kinds: the command line,
recipe validation and the docs read it.

References
----------
TOML v1.0.0, https://toml.io/en/v1.0.0 (the recipe format); Dask distributed,
https://distributed.dask.org (the task scheduler behind :func:`phyloc.parallel.run_tasks`).
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable
from typing import ClassVar

from phyloc._validate import check_keys, check_types
from phyloc.evaluation.statistics import resolve
from phyloc.parallel import run_tasks


@dataclasses.dataclass(frozen=True)
class RunContext:
    """How a run is scheduled, and what an aggregation may need beyond the task results (the
    seed, the setting; the scheduling options for a second, smaller batch of tasks such as a
    memory study)."""

    seed: int = 0
    fast: bool = False
    workers: int | None = None
    scheduler: str | None = None
    progress: bool = True

    def run_tasks(self, fn, payloads, *, desc: str) -> list:
        """``run_tasks(fn, payloads, seed)`` with this run's scheduling options."""
        return run_tasks(
            fn,
            payloads,
            self.seed,
            workers=self.workers,
            scheduler=self.scheduler,
            desc=desc,
            progress=self.progress,
        )


def experiment_from_dict(cls, table: dict, *, fast: bool = False):
    """Build an ``[experiment]`` spec ``cls``; with ``fast`` the ``[experiment.fast]`` values
    win (each table checked by :func:`phyloc._validate.from_table`)."""
    table = dict(table)
    fast_over = table.pop("fast", {})
    names = [f.name for f in dataclasses.fields(cls)]
    check_keys(table, [*names, "fast"], "experiment")
    check_keys(fast_over, names, "experiment.fast")
    check_types(cls, table, "experiment")
    check_types(cls, fast_over, "experiment.fast")
    if fast:
        table.update(fast_over)
    return cls(**table)


class Experiment(abc.ABC):
    """Base of every experiment kind (template method: :meth:`run` is the runner).

    A subclass sets :attr:`kind`, :attr:`title`, :attr:`unit`, :attr:`task` and implements
    :meth:`prepare`, :meth:`tasks`, :meth:`aggregate`, :meth:`meta` and :meth:`plot`; the
    summary methods have defaults.
    """

    #: The recipe ``kind`` it runs.
    kind: ClassVar[str] = ""
    #: One line: what it reproduces (command help and the docs list it).
    title: ClassVar[str] = ""
    #: What one task is ("realization", "run", "topology", …): the unit of its per-unit values.
    unit: ClassVar[str] = "task"
    #: ``(payload, seed_sequence) -> dict``: one unit of work (module-level: it must pickle).
    task: ClassVar[Callable | None] = None
    #: Headers of :meth:`summary_rows` when they do not depend on the results.
    headers: ClassVar[tuple] = ()
    #: The dataclass of its ``[experiment]`` section (:meth:`experiment_spec`).
    spec: ClassVar[type | None] = None

    def experiment_spec(self, recipe, *, fast: bool = False):
        """``[experiment]`` as :attr:`spec`; with ``fast`` the ``[experiment.fast]`` values win
        (unknown keys and wrong types are errors naming ``experiment.<key>``)."""
        return experiment_from_dict(self.spec, recipe.section("experiment"), fast=fast)

    @abc.abstractmethod
    def prepare(self, recipe, *, fast: bool = False):
        """Validate everything the run reads from ``recipe`` and return the plan; no work."""

    @abc.abstractmethod
    def tasks(self, plan) -> list[tuple]:
        """``[(key, payload), …]``: the units of work, in the order their seeds are spawned."""

    @abc.abstractmethod
    def aggregate(self, plan, keys: list, results: list, ctx: RunContext) -> tuple[dict, dict]:
        """``(figures, series)`` pooled from the task results (``keys[i]`` of ``results[i]``)."""

    def meta(self, plan, ctx: RunContext) -> dict:
        """What a reader needs to interpret the figures (beyond recipe, kind, seed, fast)."""
        return {}

    @abc.abstractmethod
    def plot(self, results: dict, path) -> None:
        """Write the experiment's figure(s) to ``path`` (a PNG; further figures beside it)."""

    def summary_rows(self, results: dict) -> list:
        """Rows of the table ``phyloc evaluate`` prints."""
        return [(k, x) for k, x in results["figures"].items()]

    def summary_headers(self, results: dict) -> tuple:
        """Column headers of :meth:`summary_rows`."""
        return self.headers or ("figure", "value")

    def summary_lines(self, results: dict) -> list[str]:
        """Lines printed under the table (what the columns mean, the setting)."""
        return []

    def run(self, recipe, *, fast=False, workers=None, scheduler=None, progress=True) -> dict:
        """Run ``recipe``: prepare → :meth:`execute`.

        Returns ``{"figures", "series", "meta"}``; ``meta`` starts with the recipe's name,
        kind and seed and the setting (``fast``).
        """
        plan = self.prepare(recipe, fast=fast)
        ctx = RunContext(recipe.seed, fast, workers, scheduler, progress)
        res = self.execute(plan, ctx)
        head = {"recipe": recipe.name, "kind": recipe.kind, "seed": recipe.seed, "fast": fast}
        res["meta"] = {**head, **res["meta"]}
        return res

    def execute(self, plan, ctx: RunContext) -> dict:
        """Run a prepared plan: tasks (Dask or in-process; ``--resume`` reads finished ones
        back) → aggregate → meta."""
        work = self.tasks(plan)
        results = (
            ctx.run_tasks(type(self).task, [p for _, p in work], desc=self.progress_label)
            if work
            else []
        )
        figures, series = self.aggregate(plan, [k for k, _ in work], results, ctx)
        # Pooled / Paired figures → value, 95 % interval, per-unit values (one place, every kind)
        figures, series = resolve(figures, series, seed=ctx.seed)
        return {"figures": figures, "series": series, "meta": self.meta(plan, ctx)}

    @property
    def progress_label(self) -> str:
        """The progress bar's label."""
        return self.kind.replace("_", " ")
