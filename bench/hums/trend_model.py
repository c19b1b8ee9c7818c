"""The degradation model of a rig's own trend, fitted by Bayes on a grid.

The index is turned into a degradation level u: 0 at the healthy level h0 (the mean of
the healthy tests), 1 at the failure threshold F the user states,
u = s (y - h0) / (F - h0) with s = +-1 the direction of wear.

**The model** (`CurveModel`, a progpy `PrognosticsModel`): healthy, then from a change
time t_c a level that grows with an exponential rate (an exponential with a random
rate; g = 0 is a straight line, g < 0 a rate that settles):

    u(t) = a                              t <= t_c
    u(t) = a + c psi(t),  psi(t) = phi_g(t - t_c) / phi_g(t_now - t_c),
           phi_g(x) = (exp(g x) - 1) / g  (x for g = 0)

so that c is the degradation reached at the present test t_now and a the healthy
level's own offset; du/dt = r, dr/dt = g r in state form. The tests are u(t_i) plus
Gaussian noise of sd sigma.

**Fit** (`fit`): the exact posterior on a grid of the two nonlinear parameters, the
change time (`N_CHANGE` candidates from the first test to three tests before now) and
kappa = g (t_now - t_0) (`KAPPA`: how many e-folds the rate grows over the time the
tests span, from the first t_0 to now
change; no more than a few e-folds over as long as the whole test has run, so that a
change seen on the last few tests is not extrapolated as a steep exponential), with a
flat prior over the grid; given them the model is linear in (a, c),
with the priors a ~ N(0, sigma^2 / N) (the healthy mean's standard error, N healthy
tests) and c ~ N(0, 1) truncated to c > 0 (degradation goes toward the threshold,
reaching somewhere between healthy and a few times the threshold): Gaussian
posteriors and marginal likelihoods in closed form (Bishop 2006, section 3.3-3.4), the
truncation's mass P(c > 0) in the weight of each grid point. The data that do not fit
any model widen the band: when the residuals of the posterior's models scatter more
than the noise (chi^2 per degree of freedom, `misfit`, above its 99 % point) sigma is
scaled by its square root (the Birge ratio) and the fit repeated.

**RUL** (`samples`): grid points drawn by their posterior weights, (a, c) from their
truncated Gaussian posterior, the time the curve reaches u = 1 in closed form:
phi_g(tau) = (1 - a) phi_g(S) / c, tau = ln(1 + g (1 - a) phi_g(S) / c) / g from t_c
(no crossing, inf, when the rate settles before it). A unit test checks the closed form
against progpy's `simulate_to_threshold` on `CurveModel`.

Why not progpy's state estimators: t_c and g are static parameters, which a particle
filter learns by jittering particles; tried on synthetic endurance trends (a flat
healthy period, then an exponential rise), its RUL bands stayed 5-10 times wider than
the tests warrant 90 tests after the change, set by the jitter rather than the data,
and it cost ~3 ms per test here against ~1 ms for the exact posterior on the grid,
which has no random seed to tune either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import chdtri, ndtr, ndtri

KAPPA = (-1.0, 6.0)                # prior range of g (t_now - t_0): e-folds of the rate
KAPPA_MIN = 0.05                   # |kappa| below this: a straight line
G_POS = np.logspace(-5.0, 1.0, 61)  # |g| dt of the grid (dt: the healthy tests' interval)
G_NEG = np.logspace(-5.0, 0.0, 26)
MAX_CHANGE = 64                    # change-time candidates kept (thinned beyond)
MIN_AFTER = 3                      # tests after a change time for it to be a candidate
N_SAMPLES = 500
MISFIT_Q = 0.99


def phi(g: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(exp(g x) - 1) / g, x where g = 0 (x >= 0)."""
    with np.errstate(over="ignore", invalid="ignore"):
        zero = g == 0.0
        return np.where(zero, x, np.expm1(g * x) / np.where(zero, 1.0, g))


@dataclass
class Fit:
    """The posterior on the grid at one test: the weights of the (change time, growth)
    points kept, the (a, c) posterior of each; sigma used and how much it was widened."""
    t_now: float
    tc: np.ndarray           # (P,) change time of each grid point
    g: np.ndarray            # (P,) growth rate (per time unit)
    w: np.ndarray            # (P,) posterior weights (sum 1)
    post: np.ndarray         # (P, 5) posterior of (a, c), untruncated: mean a, mean c,
                             # var a, cov a c, var c
    sigma: float
    widened: float           # factor on sigma (1: the data fitted the noise)
    z_last: float            # last test's residual about the best curve, in sd


class CurvePosterior:
    """Sufficient statistics of the model (module docstring) for every change time and
    growth rate of the grid, updated test by test in O(grid): for the change time t_c
    and rate g, the sums over the tests after t_c of phi_g(t - t_c), its square and its
    product with z. The basis psi is phi over phi_g(t_now - t_c), a scalar of each grid
    point, so a new test never revisits the old ones. A growth rate whose kappa has left
    the prior's range for good (g (t_now - t_0) > KAPPA[1]) is dropped; change-time
    candidates beyond MAX_CHANGE are thinned to every other one."""

    def __init__(self, dt: float) -> None:
        self.g = np.concatenate([-G_NEG[::-1], [0.0], G_POS]) / dt      # (G,)
        self.on = np.ones(len(self.g), dtype=bool)
        self.tc = np.zeros(0)
        self.sums = np.zeros((0, 3, len(self.g)))          # phi, phi^2, phi z
        self.n_after = np.zeros(0, dtype=np.int64)
        self.n, self.sz, self.szz = 0, 0.0, 0.0
        self.t0 = math.nan
        self.t_now = math.nan
        self.z_now = math.nan
        self.step = 1
        self.seen = 0

    def add(self, t: float, z: float) -> None:
        """One more test, time `t`, level `z` (u units)."""
        if self.n == 0:
            self.t0 = t
        self.t_now, self.z_now = t, z
        if len(self.tc):
            # rates dropped for good are computed as g = 0 (finite, never read)
            v = phi(np.where(self.on, self.g, 0.0)[None, :], (t - self.tc)[:, None])
            self.sums[:, 0] += v
            self.sums[:, 1] += v * v
            self.sums[:, 2] += v * z
            self.n_after += 1
        self.n += 1
        self.sz += z
        self.szz += z * z
        self.on &= self.g * (t - self.t0) <= KAPPA[1] * 1.0001
        if self.seen % self.step == 0:
            self.tc = np.append(self.tc, t)
            self.sums = np.concatenate([self.sums, np.zeros((1, 3, len(self.g)))])
            self.n_after = np.append(self.n_after, 0)
            if len(self.tc) > MAX_CHANGE:
                keep = np.arange(len(self.tc)) % 2 == 0
                self.tc, self.sums, self.n_after = (self.tc[keep], self.sums[keep],
                                                    self.n_after[keep])
                self.step *= 2
        self.seen += 1

    def _prior(self) -> np.ndarray:
        """Weight of each growth rate: a flat prior in kappa = g (t_now - t_0) over
        KAPPA, each grid point standing for its cell; rates with |kappa| below
        KAPPA_MIN are g = 0's (a straight line over the tests so far)."""
        span = max(self.t_now - self.t0, 1e-12)
        k = self.g * span
        use = self.on & ((np.abs(k) >= KAPPA_MIN) | (self.g == 0.0))
        use &= (k >= KAPPA[0] - 0.5 * KAPPA_MIN) & (k <= KAPPA[1] * 1.0001)
        ku = k[use]
        mid = np.concatenate([[KAPPA[0]], 0.5 * (ku[1:] + ku[:-1]), [KAPPA[1]]])
        out = np.zeros(len(k))
        out[use] = np.maximum(np.minimum(mid[1:], KAPPA[1]) - np.maximum(mid[:-1], KAPPA[0]),
                              1e-6)
        return out

    def fit(self, sigma: float, a_sd: float) -> Fit:
        """The posterior now (module docstring): noise `sigma`, prior sd of a `a_sd`
        (both u units; a_sd is scaled with sigma when the fit widens it)."""
        prior = self._prior()
        ok = self.n_after >= MIN_AFTER
        if not ok.any():
            ok = self.n_after >= self.n_after.max()
        gi = np.flatnonzero(prior > 0)
        widened = 1.0
        for _ in range(2):
            post = self._posterior(ok, gi, sigma * widened, a_sd * widened, prior)
            logev, pst, rss, tc, g = post
            w = np.exp(logev - logev.max())
            w /= w.sum()
            dof = max(self.n - 3, 1)
            chi = float(np.sum(w * rss)) / (sigma * widened) ** 2 / dof
            if widened > 1.0 or chi <= chdtri(dof, 1.0 - MISFIT_Q) / dof:
                break
            widened = math.sqrt(chi)
        best = int(np.argmax(w))
        z_last = (self.z_now - pst[best, 0] - pst[best, 1]) / (sigma * widened)
        keep = w > 1e-9 * w[best]
        w = w[keep] / w[keep].sum()
        return Fit(self.t_now, tc[keep], g[keep], w, pst[keep], sigma * widened, widened,
                   z_last)

    def _posterior(self, ok: np.ndarray, gi: np.ndarray, sigma: float, a_sd: float,
                   prior: np.ndarray) -> tuple[np.ndarray, ...]:
        """Log evidence, posterior mean and covariance of (a, c), residual sum of squares,
        change time and growth of every grid point (candidates `ok` x rates `gi`)."""
        tc = self.tc[ok]
        g = self.g[gi]
        sums = self.sums[ok][:, :, gi]                       # (C, 3, K)
        norm = phi(g[None, :], np.maximum(self.t_now - tc, 1e-12)[:, None])   # (C, K)
        s1, s2, s3 = sums[:, 0] / norm, sums[:, 1] / norm ** 2, sums[:, 2] / norm
        s2v = sigma * sigma
        p11 = self.n / s2v + 1.0 / a_sd ** 2
        p12 = s1 / s2v
        p22 = s2 / s2v + 1.0
        b1 = self.sz / s2v
        b2 = s3 / s2v
        det = p11 * p22 - p12 * p12
        c11, c12, c22 = p22 / det, -p12 / det, p11 / det
        m1 = c11 * b1 + c12 * b2
        m2 = c12 * b1 + c22 * b2
        logev = 0.5 * (m1 * b1 + m2 * b2 - np.log(det)) - math.log(a_sd)
        logev = logev + np.log(np.maximum(ndtr(m2 / np.sqrt(c22)), 1e-300))
        logev = logev + np.log(prior[gi])[None, :]
        rss = (self.szz - 2.0 * (m1 * self.sz + m2 * s3) + m1 * m1 * self.n
               + 2.0 * m1 * m2 * s1 + m2 * m2 * s2)
        shape = m1.shape
        pst = np.stack([m1.ravel(), m2.ravel(), c11.ravel(), c12.ravel(), c22.ravel()], -1)
        return (logev.ravel(), pst, np.maximum(rss, 0.0).ravel(),
                np.broadcast_to(tc[:, None], shape).ravel(),
                np.broadcast_to(g[None, :], shape).ravel())


def samples(f: Fit, rng: np.random.Generator, n: int = N_SAMPLES
            ) -> tuple[np.ndarray, np.ndarray]:
    """n draws of the posterior (module docstring): the times from now until u = 1 (inf
    where the curve never gets there, 0 where it is past it) and the level now."""
    cs = np.cumsum(f.w)
    pick = np.minimum(np.searchsorted(cs, rng.random(n) * cs[-1]), len(cs) - 1)
    ma, mc, va, cac, vc = f.post[pick].T
    # c from its truncated (c > 0) marginal, then a given c
    sd_c = np.sqrt(vc)
    lo = ndtr(-mc / sd_c)
    q = lo + (1.0 - lo) * rng.random(n)
    c = np.maximum(mc + sd_c * ndtri(np.clip(q, 1e-16, 1 - 1e-16)), 1e-12)
    a = (ma + cac / vc * (c - mc)
         + np.sqrt(np.maximum(va - cac * cac / vc, 0.0)) * rng.standard_normal(n))
    tc = f.tc[pick]
    g = f.g[pick]
    need = (1.0 - a) * phi(g, f.t_now - tc) / c      # phi_g(tau) must reach this
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        arg = 1.0 + g * need
        tau = np.where(np.abs(g) < 1e-12, need, np.log(np.where(arg > 0, arg, np.nan)) / g)
    rul = tc + tau - f.t_now
    rul = np.where(np.isfinite(rul), rul, np.inf)
    level = a + c
    return np.where(level >= 1.0, 0.0, np.maximum(rul, 0.0)), level


def make_model(g: float = 0.0) -> Any:
    """The curve as a progpy `PrognosticsModel`: states u and r (its rate), du/dt = r,
    dr/dt = g r; event ``failure`` at u >= 1. From u(t_c) = a, r(t_c) = c / phi_g(S) it
    is the fitted curve (module docstring)."""
    import matplotlib
    with matplotlib.rc_context():   # importing progpy rewrites matplotlib's rcParams
        from progpy import PrognosticsModel

    class CurveModel(PrognosticsModel):  # type: ignore[misc]
        """Degradation level u with an exponentially growing rate r."""
        states = ["u", "r"]
        inputs: list[str] = []
        outputs = ["y"]
        events = ["failure"]
        default_parameters = {"x0": {"u": 0.0, "r": 0.01}, "g": g, "process_noise": 0.0}

        def initialize(self, u: Any = None, z: Any = None) -> Any:
            return self.StateContainer(self.parameters["x0"])

        def next_state(self, x: Any, u: Any, dt: float) -> Any:
            gg = self.parameters["g"]
            grow = math.exp(gg * dt)
            step = float(phi(np.array(gg), np.array(dt)))
            return self.StateContainer({"u": x["u"] + x["r"] * step, "r": x["r"] * grow})

        def output(self, x: Any) -> Any:
            return self.OutputContainer({"y": x["u"]})

        def event_state(self, x: Any) -> dict[str, Any]:
            return {"failure": max(1.0 - float(x["u"]), 0.0)}

        def threshold_met(self, x: Any) -> dict[str, Any]:
            return {"failure": bool(x["u"] >= 1.0)}

    return CurveModel()
