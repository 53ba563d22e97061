"""The estimator's one forward selection: which effects a model gains, whatever the problem.

A problem poses what is fitted and on which data (:class:`Problem`: one sheet's marks with
the base parameters free, :mod:`vision_cal.estimate.select`; several placements with the
shared robot and a pose per placement free, :mod:`vision_cal.estimate.placements`); the
rule is this module's (:func:`forward_select`). Each round fits the current model plus each
candidate left:

- a candidate is significant when the F-test of the drop in the weighted residual sum of
  squares passes at ``alpha_each`` (the caller's share of alpha: clean data claims
  nothing) and the BIC drops;
- the significant ones are scored by the problem's held-out error (validation marks,
  cross-validation) and ranked, lowest first, among those below the current model's;
- the best is added unless the problem vetoes it (a placement's better joint-term
  alternative), then the next; a round adding nothing ends the selection, as does
  ``max_effects``.

Each round is returned whole (:class:`Round`): every trial with its figures, the held-out
errors scored, what was vetoed and why, what was chosen; each problem writes its own log
from them.

    rounds, fit, held = forward_select(problem, start, candidates, alpha_each=0.05 / 42,
                                       max_effects=4)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Trial:
    """One candidate tried in a round: its fit, the weighted residual sums of squares
    before and after, the F statistic with its p value and the BIC change."""

    candidate: object
    fit: object
    rss0: float
    rss1: float
    F: float
    p: float
    dbic: float


@dataclass(frozen=True)
class Round:
    """One round: the model's held-out error before it (``held``), every candidate fitted
    (``trials``, in the problem's order), the held-out error of each significant one
    (``scored``: id(trial) -> error), the ranked ones the problem vetoed with its reason
    (``vetoed``: (trial, error, reason)) and the one added (``chosen``: (trial, error) or
    None: the selection ends)."""

    held: float
    trials: tuple[Trial, ...]
    scored: dict = field(default_factory=dict)
    vetoed: tuple = ()
    chosen: tuple | None = None

    def held_of(self, t: Trial) -> float:
        """The held-out error of trial ``t`` (NaN when it was not scored)."""
        return self.scored.get(id(t), float("nan"))


class Problem:
    """What a selection asks of a problem (override what differs): ``fit_with(current,
    candidate)`` (the fit, or a falsy failure with its ``reason``), ``rss``, ``n_params``
    and ``dof`` of a fit, ``n_obs``, ``held(fit)`` (the held-out error), and optionally
    ``order(trials)``, ``too_small(trial)``, ``veto(current, trial)`` (None, or why not),
    ``failed(candidate, failure)`` and ``excludes(chosen, candidate)``."""

    n_obs: int

    def order(self, trials: list) -> list:
        return trials

    def too_small(self, trial: Trial) -> bool:
        return False

    def veto(self, current, trial: Trial):
        return None

    def failed(self, candidate, failure) -> None:
        return None

    def excludes(self, chosen, candidate) -> bool:
        """Whether adding ``chosen`` takes ``candidate`` out of the later rounds."""
        return candidate is chosen


def f_test(rss0: float, rss1: float, k: int, dof1: int, n_obs: int
           ) -> tuple[float, float, float]:
    """(F, p, delta BIC) of a model with ``k`` more parameters lowering the weighted residual
    sum of squares from ``rss0`` to ``rss1`` with ``dof1`` degrees of freedom left, over
    ``n_obs`` observations."""
    F = ((rss0 - rss1) / k) / (rss1 / dof1) if rss1 > 0 else float("inf")
    p = float(stats.f.sf(F, k, dof1)) if np.isfinite(F) else 0.0
    dbic = n_obs * np.log(max(rss1, 1e-300) / max(rss0, 1e-300)) + k * np.log(n_obs)
    return float(F), p, float(dbic)


def forward_select(problem: Problem, current, candidates, *, alpha_each: float,
                   max_effects: int) -> tuple[list[Round], object, float]:
    """(the rounds, the final fit, its held-out error): forward selection from ``current``
    over ``candidates`` by the rule of the module docstring."""
    held = problem.held(current)
    rounds: list[Round] = []
    left, added = list(candidates), 0
    while left and added < max_effects:
        trials = []
        for c in left:
            f = problem.fit_with(current, c)
            if not f:
                problem.failed(c, f)
                continue
            rss0, rss1 = problem.rss(current), problem.rss(f)
            k = problem.n_params(f) - problem.n_params(current)
            trials.append(Trial(c, f, rss0, rss1, *f_test(rss0, rss1, k, problem.dof(f),
                                                           problem.n_obs)))
        if not trials:
            break
        trials = problem.order(trials)
        scored = {id(t): problem.held(t.fit) for t in trials
                  if t.p < alpha_each and t.dbic < 0 and not problem.too_small(t)}
        ranked = sorted((t for t in trials if id(t) in scored and scored[id(t)] < held),
                        key=lambda t: scored[id(t)])
        vetoed, chosen = [], None
        for t in ranked:
            why = problem.veto(current, t)
            if why is None:
                chosen = (t, scored[id(t)])
                break
            vetoed.append((t, scored[id(t)], why))
        rounds.append(Round(held, tuple(trials), scored, tuple(vetoed), chosen))
        if chosen is None:
            break
        current, held = chosen[0].fit, chosen[1]
        left = [c for c in left if not problem.excludes(chosen[0].candidate, c)]
        added += 1
    return rounds, current, held
