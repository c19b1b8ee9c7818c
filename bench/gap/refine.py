"""The verdict's fit corrected for the fast model's own error (output space mapping).

Every candidate is fitted in the plant's fast mode (averaged PWM, massless balls): ~240x
real time, and the only way to fit some 40 candidates in seconds. Its error against the
model at the fidelity it was given (switching PWM, dynamic balls) is small, a few per
cent of the floor on most signals, but it is systematic, and a fit absorbs it into its
parameters: on the bench's own worn logs (backlash 50 um, friction x2.5, seeds 100-113)
the fast fit put the friction scale at 2.37 on average, 0.13 below the truth, whatever
the noise. The floor already holds the fast model's error (`Problem.model_floor`), which
widens the tolerance, but a bias is not removed by a tolerance.

`corrected` removes it for the candidate the diagnosis reports: the difference between
the model at its own fidelity and the fast model, both at the fitted values, is taken
off the log, and the candidate refitted (fast) from its fitted values on that corrected
log: y_log - (y_full(theta) - y_fast(theta)) ~ y_fast(theta*). One full-fidelity
re-simulation of the fit part; the difference moves slowly with the parameters, and a
second pass changed no fitted value in the third significant figure on those logs.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from bench.gap import resim as R
from bench.gap.fit import Fit, fit
from bench.gap.problem import Problem


def corrected_problem(p: Problem, effects: Sequence[Any], thetas: Sequence[dict[str, float]]
                      ) -> Problem | None:
    """`p` with the fast model's error at `thetas` taken off its logged signals over the
    fit part (the model at its own fidelity minus the fast model, both with `effects`);
    None when the problem has no other fidelity (`Problem.full_base`)."""
    if p.full_base is None:
        return None
    full = dataclasses.replace(p, base=p.full_base, _cache={})
    hi = full.simulate(effects, thetas, p.n_fit)
    lo = p.simulate(effects, thetas, p.n_fit)
    meas = dict(p.meas)
    for s in R.SIGNALS:
        y = meas[s].copy()
        y[:p.n_fit] = y[:p.n_fit] - (hi[s][:p.n_fit] - lo[s][:p.n_fit])
        meas[s] = y
    return dataclasses.replace(p, meas=meas)


def refine(p: Problem, f: Fit) -> tuple[Fit, dict[str, Any]]:
    """The fit `f` redone on the log corrected for the fast model's error at `f`'s values
    (`corrected_problem`), and what moved; `f` itself when there is nothing to correct
    against or the refit is not finite."""
    objs = f.objs or None
    if objs is None or not all(len(t) for t in f.theta):
        return f, {"applied": False, "why": "no fitted values"}
    q = corrected_problem(p, objs, f.theta)
    if q is None:
        return f, {"applied": False, "why": "the model has no other fidelity than the fit's"}
    g = fit(q, objs, start=[dict(t) for t in f.theta])
    if not all(all(map(_finite, t.values())) for t in g.theta):
        return f, {"applied": False, "why": "the corrected refit did not converge"}
    moved = {k: {"fast": f.theta[i][k], "corrected": g.theta[i][k]}
             for i in range(len(g.theta)) for k in g.theta[i]}
    return g, {"applied": True, "against": "the model at its own fidelity (switching PWM, "
               "dynamic balls, as given)", "values": moved}


def _finite(v: float) -> bool:
    return v == v and abs(v) != float("inf")
