"""The optimiser of a design search: an Optuna study in memory, seeded, asked and told in batches.

One objective (the robust share) is searched with TPE (multivariate, a constant liar for the
designs of a batch still running); a trade-off with NSGA-II, one generation per batch. Infeasible
designs are told through Optuna's constraints (a constraint above 0) with the worst values, so the
sampler learns to avoid them. A design halved before the last rung is told (one objective) as a
pruned trial with its robust share at each rung it reached; with a trade-off, as a complete trial
with its shares on the objects it was judged on (NSGA-II takes no pruned trials).

The study lives in memory: a resumed search rebuilds it by asking and telling again, in the same
order, from the stored trials (:mod:`somo_sweep.design.search`). Its storage is the results folder.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from somo_sweep.design.designs import Design
from somo_sweep.design.study import DesignStudy

__all__ = ["CONSTRAINT", "Optimiser", "Verdict", "optuna_version"]

#: The name of the constraint an infeasible design violates.
CONSTRAINT = "feasible"


def optuna_version() -> str:
    """The version of Optuna (its asks depend on it)."""
    import optuna

    return str(optuna.__version__)


@dataclass(frozen=True)
class Verdict:
    """What a feasible design did in its batch.

    Attributes:
        shares: Its robust share at each rung it reached, first rung first.
        sizes: The objects of those rungs.
        complete: It reached the last rung (its last share is over every object).
        trade: Its trade-off's value on the objects of its last rung (None: none yet).
    """

    shares: tuple[float, ...]
    sizes: tuple[int, ...]
    complete: bool
    trade: float | None = None


class Optimiser:
    """The Optuna study of a search.

    Args:
        study: The design study (its variables, seed, batch and objectives).
    """

    def __init__(self, study: DesignStudy):
        import optuna

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
        trade = study.trade_off
        self.distributions = {v.key: v.distribution() for v in study.variables}
        seed = study.base.seed
        if trade is None:
            sampler: Any = optuna.samplers.TPESampler(seed=seed, multivariate=True, constant_liar=True)
            directions: list[Any] = ["maximize"]
        else:
            sampler = optuna.samplers.NSGAIISampler(seed=seed, population_size=study.batch)
            directions = ["maximize", trade.direction]
        self.study = optuna.create_study(directions=directions, sampler=sampler)
        self.trade_off = trade is not None
        #: The worst trade-off value (told for a design without one).
        self.worst = 0.0 if trade is None else (-math.inf if trade.direction == "maximize" else math.inf)

    def ask(self, n: int, design_of: Callable[[dict[str, Any]], Design]) -> list[tuple[Any, Design]]:
        """``n`` trials of the optimiser and the design of each (``design_of`` its values)."""
        asked = []
        for _ in range(n):
            trial = self.study.ask(self.distributions)
            asked.append((trial, design_of(dict(trial.params))))
        return asked

    def tell(self, trial: Any, verdict: Verdict | None) -> None:
        """Tell a trial what its design did (``None``: the design is infeasible)."""
        import optuna

        trial.set_constraint(CONSTRAINT, 0.0 if verdict is not None else 1.0)
        if verdict is None:
            self.study.tell(trial, [0.0, self.worst] if self.trade_off else 0.0)
            return
        share = verdict.shares[-1]
        if self.trade_off:
            self.study.tell(trial, [share, self.worst if verdict.trade is None else verdict.trade])
        elif verdict.complete:
            self.study.tell(trial, share)
        else:
            for value, size in zip(verdict.shares, verdict.sizes, strict=True):
                trial.report(value, step=size)
            self.study.tell(trial, state=optuna.trial.TrialState.PRUNED)
