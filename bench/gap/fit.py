"""Fitting candidate effects to a log: bounded least squares, BIC/AIC, confidence intervals.

Each candidate (one effect or a combination) is fitted with `scipy.optimize.
least_squares` on the normalised closed-loop residuals of the fit part of the log, in
[0, 1] coordinates per parameter (logarithmic where the parameter spans decades), from
a few starting points (the best is kept). Parameters that only take whole SYNC periods
(delays) are grid-searched. Confidence intervals are the sandwich (Huber-White) form
around the Jacobian at the optimum with a long-run (Newey-West) covariance of each
signal's score: the residuals of a closed loop are correlated, and by signal very
differently (the encoder's travel over tens of samples, the current's hardly at all), so
one correlation length for all of them gives intervals too narrow for the parameters the
slow signals carry (`intervals`). A parameter that ends on a bound that is not its
no-effect value is flagged (`Fit.at_bound`): its interval is open on that side.

Scores (lower is better), with n_eff = n / L the effective number of samples:
    BIC = n_eff ln(RSS / n) + k ln(n_eff),   AIC = n_eff ln(RSS / n) + 2 k
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from bench.gap import effects as E
from bench.gap.autocorr import corr_length, long_run_cov
from bench.gap.library import with_nut_share
from bench.gap.problem import Problem

DIFF_STEP = 0.01     # finite-difference step in [0, 1] coordinates
MAX_NFEV = 40        # residual evaluations per least-squares run (per start)
FTOL = 1e-5          # relative change of the normalised RSS that ends the fit (it is
                     # ~ samples x signals, so 1e-5 is far below one unit of BIC)
XTOL = 1e-4          # step in [0, 1] coordinates that ends the fit


@dataclass
class Fit:
    """A fitted candidate: effect names, values, intervals and its scores."""
    effects: tuple[str, ...]
    theta: list[dict[str, float]]            # one dict per effect
    ci95: list[dict[str, tuple[float, float]]]
    rss: float                               # normalised residual sum of squares (fit part)
    n: int                                   # residuals in the fit
    k: int                                   # fitted parameters
    nfev: int
    corr_len: float = 1.0
    ok: bool = True
    message: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    objs: list[E.Effect] = field(default_factory=list)
    at_bound: list[dict[str, str]] = field(default_factory=list)   # per effect: param ->
                                             # "lower" | "upper" (a bound not its nominal)
    cov_u: np.ndarray | None = None          # covariance of the free parameters in [0, 1]
                                             # coordinates (order `free`)
    free: list[tuple[int, str]] = field(default_factory=list)   # (effect index, param)

    @property
    def name(self) -> str:
        return "+".join(self.effects)

    def bic(self, corr_len: float) -> float:
        neff = max(self.n / corr_len, self.k + 2.0)
        return neff * math.log(max(self.rss, 1e-300) / self.n) + self.k * math.log(neff)

    def aic(self, corr_len: float) -> float:
        neff = max(self.n / corr_len, self.k + 2.0)
        return neff * math.log(max(self.rss, 1e-300) / self.n) + 2.0 * self.k

    def params_dict(self) -> dict[str, dict[str, Any]]:
        """{param: {value, ci95, unit[, at_bound]}} over all effects (JSON-ready); a
        parameter on a bound that is not its no-effect value has ``at_bound`` ("lower" or
        "upper") and no interval on that side (None: the effect may be larger)."""
        out: dict[str, dict[str, Any]] = {}
        objs = self.objs or [E.get(n) for n in self.effects]
        flags = self.at_bound or [{} for _ in objs]
        for eff, th, ci, fl in zip(objs, self.theta, self.ci95, flags, strict=True):
            for p in eff.params:
                lo, hi = ci.get(p.name, (float("nan"), float("nan")))
                d: dict[str, Any] = {"value": th[p.name], "ci95": [lo, hi], "unit": p.unit}
                side = fl.get(p.name)
                if side is not None:
                    d["at_bound"] = side
                    d["ci95"] = [None, hi] if side == "lower" else [lo, None]
                out[p.name] = d
        return out

    def bounded(self) -> list[str]:
        """The parameters at a bound that is not their no-effect value."""
        return [k for fl in self.at_bound for k in fl]


def residual_corr_length(p: Problem, sim: dict[str, np.ndarray], lo: int, hi: int) -> float:
    """Energy-weighted mean correlation length of the signals' residuals over [lo, hi)."""
    num = den = 0.0
    for s in p.sigma:
        r = (p.meas[s][lo:hi] - sim[s][lo:hi]) / p.sigma[s]
        e = float(np.mean(r ** 2))
        num += e * corr_length(r)
        den += e
    return num / den if den > 0 else 1.0


def resolve(names: Sequence[str | E.Effect]) -> list[E.Effect]:
    """Effect objects for names (registry) or objects (passed through)."""
    return [E.get(n) if isinstance(n, str) else n for n in names]


class Objective:
    """Residual function of a candidate set in [0, 1] coordinates (continuous params).

    `prior`: optional {param name: (value, sd in [0, 1] coordinates)}: Gaussian prior
    residuals (u - u_prior) / sd appended (calibration's regularisation)."""

    def __init__(self, problem: Problem, names: Sequence[str | E.Effect],
                 fixed: list[dict[str, float]] | None = None,
                 prior: dict[str, tuple[float, float]] | None = None) -> None:
        self.p = problem
        self.effects = resolve(names)
        self.names = tuple(e.name for e in self.effects)
        self.fixed = fixed or [{} for _ in self.effects]
        # free continuous parameters: (effect index, Param)
        self.free = [(i, prm) for i, eff in enumerate(self.effects) for prm in eff.params
                     if prm.integer_step <= 0 and prm.name not in self.fixed[i]]
        self.prior = prior or {}
        self.nfev = 0

    def thetas(self, u: Sequence[float] | np.ndarray) -> list[dict[str, float]]:
        th = [dict(f) for f in self.fixed]
        for (i, prm), ui in zip(self.free, u, strict=True):
            th[i][prm.name] = prm.from_unit(ui)
        return th

    def simulate(self, th: list[dict[str, float]], n: int | None = None) -> dict[str, np.ndarray]:
        self.nfev += 1
        return self.p.simulate(self.effects, th, self.p.n_fit if n is None else n)

    def prior_residual(self, u: np.ndarray) -> np.ndarray:
        out = [(ui - prm.to_unit(self.prior[prm.name][0])) / self.prior[prm.name][1]
               for (_, prm), ui in zip(self.free, u, strict=True) if prm.name in self.prior]
        return np.array(out, float)

    def __call__(self, u: np.ndarray) -> np.ndarray:
        sim = self.simulate(self.thetas(u))
        r = self.p.residual(sim, 0, self.p.n_fit)
        if self.prior:
            r = np.concatenate([r, self.prior_residual(u)])
        return r


def _discrete_grid(problem: Problem, names: Sequence[str | E.Effect],
                   start: list[dict[str, float]]) -> list[dict[str, float]]:
    """Grid-search discrete parameters with continuous ones held at `start`."""
    effs = resolve(names)
    th = [dict(s) for s in start]
    for i, eff in enumerate(effs):
        for prm in eff.params:
            if prm.integer_step <= 0:
                continue
            best, best_v = math.inf, th[i][prm.name]
            for v in prm.grid():
                trial = [dict(t) for t in th]
                trial[i][prm.name] = v
                sim = problem.simulate(effs, trial, problem.n_fit)
                cost = float(np.sum(problem.residual(sim, 0, problem.n_fit) ** 2))
                if cost < best:
                    best, best_v = cost, v
            th[i][prm.name] = best_v
    return th


def shared_once(effs: Sequence[E.Effect]) -> list[E.Effect]:
    """A parameter that several effects of a candidate carry under one name (the nut
    friction share, `bench.gap.library.NUT_SHARE`) is fitted once, by the last of them,
    whose plant overrides are applied last; the others get a copy without it."""
    out = []
    for i, e in enumerate(effs):
        later = {p.name for f in effs[i + 1:] for p in f.params}
        if any(p.name in later for p in e.params):
            e = copy.copy(e)
            e.params = tuple(p for p in e.params if p.name not in later)  # type: ignore[misc]
        out.append(e)
    return out


def for_problem(problem: Problem, names: Sequence[str | E.Effect]) -> list[E.Effect]:
    """The effects as fitted on `problem`: bounds for its model (`Effect.for_model`); where
    the problem declares the model's friction split unknown, the effects that show it fit
    the nut friction share too, once per candidate (`with_nut_share`, `shared_once`)."""
    effs = [e.for_model(problem.base) for e in resolve(names)]
    if problem.friction_split == "unknown":
        effs = shared_once([with_nut_share(e) for e in effs])
    return effs


def _starts(problem: Problem, effs: Sequence[E.Effect], nom: list[dict[str, float]],
            start: list[dict[str, float]] | None) -> list[list[dict[str, float]]]:
    """Candidate starting points: every effect's own start points, in step; with `start`
    (a pair grown from a single), `start` itself and `start` with each added effect (all
    but the first) moved to its own start points (its value fitted alone can be far off
    once paired). Each carries its effect's own parameters only (a single's fit grown to
    a pair may carry one that the pair fits once, with its other effect), inside the
    bounds, discrete ones on their grid."""
    own = [e.start_points(problem.base) for e in effs]
    m = max(len(s) for s in own)
    starts = [[own[i][min(j, len(own[i]) - 1)] for i in range(len(effs))] for j in range(m)]
    if start is not None:
        grown = [[dict(s) for s in start]]
        for i in range(1, len(effs)):
            for sp in own[i]:
                st = [dict(s) for s in start]
                st[i] = dict(sp)
                grown.append(st)
        starts = grown
    for st in starts:
        for i, e in enumerate(effs):
            st[i] = {k: v for k, v in st[i].items() if any(k == q.name for q in e.params)}
            for prm in e.params:
                v = st[i].get(prm.name, nom[i][prm.name])
                if prm.integer_step > 0:
                    v = prm.lo + round((v - prm.lo) / prm.integer_step) * prm.integer_step
                st[i][prm.name] = min(max(v, prm.lo), prm.hi)
    return starts


def fit(problem: Problem, names: Sequence[str | E.Effect],
        start: list[dict[str, float]] | None = None, max_nfev: int = MAX_NFEV,
        prior: dict[str, tuple[float, float]] | None = None,
        diff_step: float = DIFF_STEP) -> Fit:
    """Fit the candidate set `names` (registry names or Effect objects) to the fit part
    of `problem`.

    `start`: starting values per effect (e.g. a single effect's fit when it is extended
    to a pair); otherwise each effect's own start points are tried. `prior`: see
    `Objective`.
    """
    effs = for_problem(problem, names)
    effect_names = tuple(e.name for e in effs)
    k = sum(len(e.params) for e in effs)
    nom = [e.nominal(problem.base) for e in effs]
    starts = _starts(problem, effs, nom, start)
    # the best start by cost (one simulation each)
    effs_obj = list(effs)
    nfev0 = 0
    best_st, best_cost = starts[0], math.inf
    for st in starts:
        sim = problem.simulate(effs_obj, st, problem.n_fit)
        nfev0 += 1
        r = problem.residual(sim, 0, problem.n_fit)
        c = float(r @ r)
        if c < best_cost:
            best_st, best_cost = st, c
    # discrete parameters: grid search with the continuous ones at the best start
    if any(prm.integer_step > 0 for e in effs for prm in e.params):
        disc = _discrete_grid(problem, effs_obj, best_st)
        fixed = [{prm.name: disc[i][prm.name] for prm in e.params if prm.integer_step > 0}
                 for i, e in enumerate(effs)]
        nfev0 += sum(len(prm.grid()) for e in effs for prm in e.params if prm.integer_step > 0)
    else:
        fixed = [{} for _ in effs]
    obj = Objective(problem, effs, fixed, prior)
    obj.nfev = nfev0
    if not obj.free:
        th = [dict(f) for f in fixed]
        sim = obj.simulate(th)
        r = problem.residual(sim, 0, problem.n_fit)
        return Fit(effect_names, th, [dict(_exact(f)) for f in fixed], float(r @ r), len(r),
                   k, obj.nfev, residual_corr_length(problem, sim, 0, problem.n_fit),
                   extra={"discrete_only": True}, objs=list(effs),
                   at_bound=at_bounds(effs, nom, obj, np.zeros(0), fixed))
    best_u = np.clip(np.array([prm.to_unit(best_st[i][prm.name]) for i, prm in obj.free]),
                     0.0, 1.0)
    best_cost = float(np.sum(obj(best_u) ** 2))
    with np.errstate(over="ignore", invalid="ignore"):
        res = least_squares(obj, best_u, bounds=(0.0, 1.0), diff_step=diff_step,
                            x_scale=1.0, max_nfev=max_nfev, method="trf",
                            ftol=FTOL, xtol=XTOL)
    u = res.x if 0.5 * float(res.fun @ res.fun) <= 0.5 * best_cost else best_u
    th = obj.thetas(u)
    sim = obj.simulate(th)
    r = problem.residual(sim, 0, problem.n_fit)
    rss = float(r @ r)
    L = residual_corr_length(problem, sim, 0, problem.n_fit)
    cov = intervals_cov(res.jac, r, len(problem.sigma))
    ci = _intervals(obj, u, cov, res.jac, fixed)
    flags = at_bounds(effs, nom, obj, u, fixed)
    return Fit(effect_names, th, ci, rss, len(r), k, obj.nfev, L, bool(res.success),
               str(res.message), objs=list(effs), at_bound=flags, cov_u=cov,
               free=[(i, prm.name) for i, prm in obj.free])


def _exact(fixed: dict[str, float]) -> dict[str, tuple[float, float]]:
    return {k: (v, v) for k, v in fixed.items()}


EDGE = 1e-3
"""A parameter within this of a bound in [0, 1] coordinates is on it."""


def at_bounds(effs: Sequence[E.Effect], nom: list[dict[str, float]], obj: Objective,
              u: np.ndarray, fixed: list[dict[str, float]]) -> list[dict[str, str]]:
    """Per effect, its parameters that ended on a bound which is not their no-effect
    value (`nom`): "lower" or "upper". A fit on such a bound says only that the effect
    is at least that large, or of another form than the family's (docs/gap.md, "Selection")."""
    out: list[dict[str, str]] = [{} for _ in effs]
    pos = {(i, prm.name): float(ui) for (i, prm), ui in zip(obj.free, u, strict=True)}
    for i, e in enumerate(effs):
        for prm in e.params:
            if prm.physical_bounds:
                continue
            if prm.name in fixed[i]:                       # a grid: its end points
                v = fixed[i][prm.name]
                ui = prm.to_unit(v) if prm.hi > prm.lo else 0.5
            else:
                ui = pos.get((i, prm.name), 0.5)
            un = prm.to_unit(min(max(nom[i][prm.name], prm.lo), prm.hi))
            for side, edge in (("lower", 0.0), ("upper", 1.0)):
                if abs(ui - edge) <= EDGE and abs(un - edge) > EDGE:
                    out[i][prm.name] = side
    return out


def intervals_cov(jac: np.ndarray, r: np.ndarray, n_signals: int) -> np.ndarray:
    """Covariance of the fitted [0, 1] coordinates: the sandwich H^-1 Omega H^-1 with
    H = J^T J (data and prior rows) and Omega the long-run covariance of the data score
    J_s^T r_s of each signal s (Bartlett lags up to 4 of its residual's correlation
    lengths, `autocorr.long_run_cov`) plus the prior rows' J_p^T J_p (unit-variance
    pseudo-observations). Data rows are `n_signals` blocks of equal length, in the
    residual's order; rows after them are the prior's."""
    n = len(r)
    jd, jp = jac[:n], jac[n:]
    k = jac.shape[1]
    omega = jp.T @ jp
    m = n // max(n_signals, 1)
    for s in range(n_signals):
        rs, js = r[s * m:(s + 1) * m], jd[s * m:(s + 1) * m]
        if not np.any(rs):
            continue
        lag = int(min(math.ceil(4.0 * corr_length(rs)), max(len(rs) // 4, 1)))
        omega = omega + long_run_cov(js * rs[:, None], lag)
    try:
        hinv = np.linalg.pinv(jac.T @ jac)
        return hinv @ omega @ hinv
    except (np.linalg.LinAlgError, ValueError):
        return np.full((k, k), np.inf)


def _intervals(obj: Objective, u: np.ndarray, cov: np.ndarray, jac: np.ndarray,
               fixed: list[dict[str, float]]) -> list[dict[str, tuple[float, float]]]:
    """95 % intervals of the free parameters from `cov` (`intervals_cov`), mapped through
    each parameter's scale (asymmetric for logarithmic ones); a parameter the log does
    not move (a zero Jacobian column) gets its whole range; grid-searched ones are exact
    on their grid."""
    out: list[dict[str, tuple[float, float]]] = [dict() for _ in obj.effects]
    with np.errstate(invalid="ignore"):
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    for j, (i, prm) in enumerate(obj.free):
        if not np.isfinite(sd[j]) or sd[j] == 0.0 and not np.any(jac[:, j]):
            out[i][prm.name] = (prm.lo, prm.hi)      # not identifiable from this log
            continue
        lo = prm.from_unit(u[j] - 1.96 * sd[j])
        hi = prm.from_unit(u[j] + 1.96 * sd[j])
        out[i][prm.name] = (lo, hi)
    for i, fx in enumerate(fixed):
        for name, v in fx.items():
            out[i][name] = (v, v)                    # grid-searched: exact on its grid
    return out
