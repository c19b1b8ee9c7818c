"""An LVDT gain against a screw-lead error: the load cell separates them.

Both change the ratio of the LVDT's position to the motor's angle by the same factor, so
the kinematics of a log do not tell them apart. Only the lead changes the torque the
motor needs for an axial force: T = F lead / (2 pi eta) (the reaction lever of
eq. 5.10 and 5.15 at the lead, eq. 5.26), so the current a logged load-cell force
costs, the slope of the logged current on the load cell's force, moves with the lead by the lead's ratio and not
at all with an LVDT gain. `settle` compares that slope on the log with each candidate's
re-simulation: the candidate whose slope the log has is the verdict; where the log cannot
tell (no load cell, a load too small against the current's noise, or a slope between
the two) the verdict says "LVDT gain or screw lead: indistinguishable on this log".

The slope's standard error is heteroskedasticity-and-autocorrelation consistent (Newey
and West, `autocorr.long_run_cov`, the lag the residual's correlation length): closed
loop residuals are not independent samples.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.gap import effects as E
from bench.gap.autocorr import corr_length, long_run_cov

PAIR = ("lead", "lvdt_gain")
"""The two candidates the kinematics cannot tell apart."""
SEPARATION_Z = 6.0
"""The two candidates' slopes must differ by this many standard errors of the log's
slope for the log to tell them apart (a 6-sigma power: a 3-sigma distance from the wrong
one when the log sits on the right one)."""
NEAR_FRACTION = 1.0 / 3.0
"""... and the log's slope must lie within this fraction of that difference of the
candidate it is given to (not halfway between them, nor beyond both)."""
INDISTINGUISHABLE = "LVDT gain or screw lead: indistinguishable on this log"


def load_slope(current: np.ndarray, force: np.ndarray) -> tuple[float, float]:
    """The least-squares slope of `current` (A) on `force` (N), both demeaned, and its
    HAC standard error (A/N)."""
    f = np.asarray(force, float) - float(np.mean(force))
    y = np.asarray(current, float) - float(np.mean(current))
    sff = float(f @ f)
    if not sff > 0.0:
        return math.nan, math.inf
    b = float(f @ y) / sff
    e = y - b * f
    lag = int(math.ceil(corr_length(e)))
    lrv = float(long_run_cov((f * e)[:, None], lag)[0, 0])
    return b, math.sqrt(max(lrv, 0.0)) / sff


def decide(log_slope: float, se: float, slopes: dict[str, float]) -> tuple[str | None, str]:
    """The candidate whose re-simulated slope the log's slope has (`slopes`: name -> A/N),
    or None where the log cannot tell them apart, with the reason."""
    (a, sa), (b, sb) = slopes.items()
    gap = abs(sa - sb)
    if not (math.isfinite(log_slope) and math.isfinite(gap) and se > 0 and math.isfinite(se)):
        return None, "no load-cell force to compare the current with"
    if gap < SEPARATION_Z * se:
        return None, (f"the two slopes differ by {gap / se:.1f} standard errors of the log's "
                      f"(< {SEPARATION_Z:g}): the load is too small against the current's "
                      "noise")
    near, d = min(((a, abs(log_slope - sa)), (b, abs(log_slope - sb))), key=lambda x: x[1])
    if d > NEAR_FRACTION * gap:
        return None, ("the log's slope lies between or beyond the two candidates' "
                      f"(nearest {near}, {d / gap:.0%} of their difference away)")
    return near, f"the log's slope is that of {near} ({d / se:.1f} standard errors away)"


def load_force(p: Any) -> np.ndarray | None:
    """The load cell's force over the problem's `p.n` samples (N), or None where the log
    has none to compare the current with (no load cell, a non-finite sample, no change)."""
    load = p.drive.load_n
    if load is None:
        return None
    force = np.asarray(load[:p.n], float)
    return force if np.isfinite(force).all() and np.ptp(force) > 0 else None


def healthy_load_ratio(p: Any) -> float | None:
    """The log's slope of current on load-cell force over the model's on a healthy log
    (`p`: its problem, the calibrated model): what the calibrated model still misses of
    the current an axial force costs, which a later log's candidates are scaled by
    (None without a load cell)."""
    force = load_force(p)
    if force is None:
        return None
    n = p.n
    sim = np.asarray(p.simulate([], [], n)["current_a"], float)[:n]
    b_sim = load_slope(sim, force)[0]
    b_log = load_slope(np.asarray(p.meas["current_a"], float)[:n], force)[0]
    return float(b_log / b_sim) if math.isfinite(b_sim) and b_sim != 0.0 else None


def settle(p: Any, chosen: Any, singles: list[Any], ratio: float | None = None
           ) -> tuple[Any, dict[str, Any] | None]:
    """Between an LVDT gain and a lead error: the candidate the current's slope on the
    load-cell force points to (it may replace `chosen`), and the test's record (None when
    `chosen` holds neither or the other (`swap`) was not fitted). A pair holding one of
    them is tested against the same pair with the other (`swapped_pair`). `p`: the
    problem (logged current in `p.meas`, load cell in `p.drive.load_n`); the candidates:
    `diagnose.Candidate`; `ratio`: the calibration's healthy log's slope over its model's
    (`healthy_load_ratio`), the candidates' slopes scaled by it (1 without one)."""
    other_name = swap(chosen.fit.name) if chosen is not None else None
    if other_name is None:
        return chosen, None
    other = next((c for c in singles if c.fit.name == other_name
                  and math.isfinite(c.fit.rss)), None)
    if other is None:
        return chosen, None
    n = p.n
    cur = np.asarray(p.meas["current_a"], float)[:n]
    rec: dict[str, Any] = {"rule": (
        "an LVDT gain and a lead error move the LVDT per motor angle alike; only the lead "
        "moves the current an axial force costs (T = F lead / (2 pi eta)): the slope of the "
        "logged current on the load cell's force against each candidate's re-simulation")}
    force = load_force(p)
    if force is None:
        rec.update(separated=False, why="no load-cell force to compare the current with",
                   line=INDISTINGUISHABLE)
        return chosen, rec
    slopes, raw, resid = {}, {}, {}
    for c in (chosen, other):
        objs = c.fit.objs or [E.get(name) for name in c.fit.effects]
        sim = np.asarray(p.simulate(objs, c.fit.theta, n)["current_a"], float)[:n]
        raw[c.fit.name] = load_slope(sim, force)[0]
        slopes[c.fit.name] = raw[c.fit.name] * (ratio or 1.0)
        resid[c.fit.name] = cur - sim
    # the log's slope as the chosen candidate's plus its residual's: the residual, not the
    # whole current (the manoeuvre's own currents), sets the standard error
    b_r, se = load_slope(resid[chosen.fit.name], force)
    log_b = raw[chosen.fit.name] + b_r
    pick, why = decide(log_b, se, slopes)
    rec.update(healthy_ratio=ratio, log_slope_a_per_n=log_b, se_a_per_n=se, candidate_slopes_a_per_n=slopes,
               separated=pick is not None, why=why, chosen=pick)
    if pick is None:
        rec["line"] = INDISTINGUISHABLE
        return chosen, rec
    return (chosen if pick == chosen.fit.name else other), rec


def plausible_best(best: Any, singles: list[Any], margin: float) -> Any:
    """`best`, or where it is suspect the plausible single of lowest BIC within `margin`
    of it: an alias as good takes its place (`diagnose.Candidate`s)."""
    if getattr(best, "suspect", None):
        ok = [c for c in singles if not getattr(c, "suspect", None)
              and math.isfinite(c.bic) and c.bic <= best.bic + margin]
        if ok:
            return min(ok, key=lambda c: c.bic)
    return best


def base_single(p: Any, best: Any, singles: list[Any], ratio: float | None = None) -> Any:
    """The single a pair extends: of an LVDT gain and a lead, the one the load cell points
    to (`settle`), else `best`. A pair built on the wrong one of the two holds the right
    second effect beside the wrong first: an LVDT gain with a worn winding read as a lead
    error plus the winding, a verdict the load-cell test of a single never sees."""
    new, rec = settle(p, best, singles, ratio)
    return new if rec is not None and rec["separated"] else best


def swap(name: str) -> str | None:
    """Candidate `name` with its LVDT gain or lead replaced by the other ("lead+resistance"
    -> "lvdt_gain+resistance"); None when it holds neither or both."""
    parts = name.split("+")
    if sum(x in PAIR for x in parts) != 1:
        return None
    return "+".join(PAIR[1 - PAIR.index(x)] if x in PAIR else x for x in parts)


def swapped_pair(chosen: Any, singles: list[Any], fit: Any, fitted: Any = ()) -> Any:
    """A chosen pair holding an LVDT gain or a lead, with the other in its place: the one
    among `fitted` (the forward selection tried both beside another best single), else
    fitted (`fit(names, start)` -> a candidate; started from the other's single fit and
    the pair's second member): the forward selection extends one of the two only, and a
    log that cannot tell them apart alone cannot within a pair either. None for a single,
    a pair holding neither, or the other not fitted alone."""
    if chosen is None or len(chosen.fit.effects) != 2 or swap(chosen.fit.name) is None:
        return None
    names = tuple(swap(n) or n for n in chosen.fit.effects)
    done = next((c for c in fitted if set(c.fit.effects) == set(names)), None)
    if done is not None:
        return done
    alias = next(n for n in names if n in PAIR)
    single = next((c for c in singles if c.fit.name == alias and math.isfinite(c.fit.rss)),
                  None)
    if single is None:
        return None
    start = [single.fit.theta[0] if n == alias else th
             for n, th in zip(names, chosen.fit.theta, strict=True)]
    return fit(names, start)
