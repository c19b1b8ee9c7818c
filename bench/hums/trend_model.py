"""The degradation model of a rig's own trend, fitted by Bayes on a grid.

The index is turned into a degradation level u: 0 at the healthy level h0 (the mean of
the healthy tests), 1 at the failure threshold F the user states,
u = s (y - h0) / (F - h0) with s = +-1 the direction of wear.

**The model** (`CurveModel`, a progpy `PrognosticsModel`): the three phases of wear
(run-in aside): a steady drift from the first test, and from a change time t_c a
wear-out whose rate grows exponentially (an exponential with a random rate; g = 0 a
straight line, g < 0 a rate that settles):

    u(t) = a + b x(t) + c psi(t),   x = (t - t_0) / (t_now - t_0),
    psi(t) = phi_g(t - t_c) / phi_g(t_now - t_c)  (0 before t_c),
    phi_g(x) = (exp(g x) - 1) / g  (x for g = 0)

so that b is the drift over the tests so far, c the wear-out reached at the present test
t_now and a the healthy level's own offset. The tests are u(t_i) plus Gaussian noise of
an unknown sd sigma.

**Fit** (`CurvePosterior.fit`): the exact posterior over a grid of the two nonlinear
parameters, the change time (every test, thinned to `MAX_CHANGE` candidates, with at
least `MIN_AFTER` tests after it) and kappa = g (t_now - t_0), the e-folds the rate grows
over as long as the tests have run (`KAPPA`; so a change seen on the last few tests is
not extrapolated as a steep exponential). The prior over the grid: flat over the change
times; over kappa, half its mass on the straight line (kappa = 0: a constant wear rate,
Archard's law at a steady use, the simplest shape) and half flat over `KAPPA`, -1 to 12.
Its top is above the steepest development rise (synthetic exponentials that grow up to
10 e-folds over the tests' span): a cut at 6 held such a rise below its true rate, and
the bands came out late on every accelerating development trend, never early. Given the
grid point the model is linear in (a, b, c): the conjugate normal-inverse-gamma
posterior (Bishop 2006, sections 3.3 and 3.5; Gelman et al., BDA section 14.2) with
the priors (given sigma) a ~ N(0, sigma^2 / N) (the healthy mean's error, N healthy
tests), b, c ~ N(0, sigma^2 / sigma0^2) (of the order of the threshold at the healthy
noise sigma0), c truncated to c > 0 (wear goes toward the threshold), and sigma^2 ~
scaled inverse chi^2 (N - 1, sigma0^2): the healthy tests' noise, which the residuals
then override. Its marginal likelihood and Student-t posteriors are in closed form, the
truncation's mass P(c > 0) in the weight of each grid point; when the tests scatter
more about every curve than the healthy tests did, sigma's posterior grows and the band
with it. The statistics are sums over the tests (`CurvePosterior.add`, O(grid) per test).

**Beyond white noise** (`CurvePosterior._wander`): the residuals of the best curve over
the last `WANDER_TESTS` tests; their lag-1 autocorrelation rho inflates the parameters'
covariance by (1 + rho) / (1 - rho) (correlated residuals carry less information than
as many independent ones), their variogram gives the variance q per time unit of a
random walk on top of the curve.

**RUL** (`samples`): grid points drawn by their weights, sigma^2 from its inverse gamma,
c from its truncated normal, (a, b) given c; the time the curve reaches u = 1 by
Newton's method (`_crossings`, compiled; inf when it does not within `HORIZON` times the
time the tests span), spread by the random walk's first passage over the distance left
(inverse Gaussian IG(tau, d^2 / q), exact for a straight line). Tests check the
crossing against progpy's `simulate_to_threshold` on `CurveModel` and against a
brute-force search.

**Two models** (`local_drift`): the curve's RUL draws are mixed, half and half, with
those of a local drift model: the straight line through the tests in the later half of
the time since the change (a constant drift, as a Wiener process's mean, without its
diffusion term), level and slope drawn from their Student-t posterior. The curve, fitted to every test, extrapolates the shape it has
seen; the local drift follows the recent rate only. Where their RULs differ (an
index whose rise is slightly convex or concave: the campaign's lost motion and Ci), the
band holds both and its median lies between; on the bench's development trends (the
campaign's judged actuators 2024-2048 as foreign files) the curve alone was late on a
slightly convex lost motion and early on a concave Ci, the local drift alone too late
on every accelerating synthetic shape (the truth in the band on 4 % of the days after
the warning of exponential rises), the even mix kept both within a few % of the better.

Why not progpy's state estimators: t_c and g are static parameters, which a particle
filter learns by jittering particles; tried on synthetic endurance trends (a flat
healthy period, then an exponential rise), its RUL bands stayed 5-10 times wider than
the tests warrant 90 tests after the change, set by the jitter rather than the data,
and it cost more per test than this exact posterior, which has no random walk to tune.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ndtr, ndtri, stdtr

from plant_rt.jit import njit

KAPPA = (-1.0, 12.0)               # prior range of g (t_now - t_0): e-folds of the rate
KAPPA_MIN = 0.05                   # |kappa| below this: a straight line
P_LINE = 0.5                       # prior mass of the straight line (a constant wear rate)
G_POS = np.logspace(-5.0, 1.0, 61)  # |g| dt of the grid (dt: the healthy tests' interval)
G_NEG = np.logspace(-5.0, 0.0, 26)
MAX_CHANGE = 64                    # change-time candidates kept (thinned beyond)
MIN_AFTER = 3                      # tests after a change time for it to be a candidate
N_SAMPLES = 500
HORIZON = 50.0                     # RUL beyond HORIZON x (t_now - t_0): never (inf)
N_SUMS = 4                         # per grid point: sum psi, psi^2, psi z, psi t
WANDER_TESTS = 60                  # tests whose residuals show a wander
WANDER_LAG = 5
P_LOCAL = 0.5                      # share of the RUL draws from the local drift model
LOCAL_FRAC = 0.5                   # its tests: the later half of the time since the change
LOCAL_MIN = 5


def phi(g: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(exp(g x) - 1) / g, x where g = 0 (x >= 0)."""
    with np.errstate(over="ignore", invalid="ignore"):
        zero = g == 0.0
        return np.where(zero, x, np.expm1(g * x) / np.where(zero, 1.0, g))


@dataclass
class Fit:
    """The posterior on the grid at one test: the grid points kept, their weights and
    the posterior of (a, b, c, sigma^2) at each."""
    t_now: float
    t0: float
    tc: np.ndarray           # (P,) change time of each grid point
    g: np.ndarray            # (P,) growth rate (per time unit)
    w: np.ndarray            # (P,) posterior weights (sum 1)
    mean: np.ndarray         # (P, 3) posterior mean of (a, b, c), untruncated
    cov: np.ndarray          # (P, 6) its covariance over sigma^2, packed 11 12 13 22 23 33
    alpha: float             # sigma^2's inverse gamma (the same alpha at every point)
    beta: np.ndarray         # (P,)
    sigma: float             # the noise's posterior mean (u units)
    widened: float           # sigma over the healthy tests' noise
    z_last: float            # last test's residual about the best curve, in sd
    inflate: float = 1.0     # on the (a, b, c) covariance: correlated residuals
    wander: float = 0.0      # q, the residuals' random-walk variance (u^2 per time unit)


class CurvePosterior:
    """Sufficient statistics of the model (module docstring) for every change time and
    growth rate of the grid, updated test by test in O(grid): for the change time t_c
    and rate g, the sums over the tests after t_c of phi_g(t - t_c), its square, its
    products with z and with t - t_0. The basis psi is phi over phi_g(t_now - t_c), a
    scalar of each grid point, so a new test never revisits the old ones. A growth rate
    whose kappa has left the prior's range for good is dropped; change-time candidates
    beyond MAX_CHANGE are thinned to every other one."""

    def __init__(self, dt: float) -> None:
        self.g = np.concatenate([-G_NEG[::-1], [0.0], G_POS]) / dt      # (G,)
        self.on = np.ones(len(self.g), dtype=bool)
        self.tc = np.zeros(0)
        self.sums = np.zeros((0, N_SUMS, len(self.g)))
        self.n_after = np.zeros(0, dtype=np.int64)
        self.glob = np.zeros(6)          # n, sum t', t'^2, z, t' z, z^2 (t' = t - t_0)
        self.t0 = math.nan
        self.t_now = math.nan
        self.z_now = math.nan
        self.step = 1
        self.seen = 0
        self.recent: list[tuple[float, float]] = []        # the last WANDER_TESTS tests

    def add(self, t: float, z: float) -> None:
        """One more test, time `t`, level `z` (u units)."""
        if self.seen == 0:
            self.t0 = t
        self.t_now, self.z_now = t, z
        tp = t - self.t0
        if len(self.tc):
            # rates dropped for good are computed as g = 0 (finite, never read)
            v = phi(np.where(self.on, self.g, 0.0)[None, :], (t - self.tc)[:, None])
            self.sums[:, 0] += v
            self.sums[:, 1] += v * v
            self.sums[:, 2] += v * z
            self.sums[:, 3] += v * tp
            self.n_after += 1
        self.glob += (1.0, tp, tp * tp, z, tp * z, z * z)
        self.on &= self.g * tp <= KAPPA[1] * 1.0001
        if self.seen % self.step == 0:
            self.tc = np.append(self.tc, t)
            self.sums = np.concatenate([self.sums, np.zeros((1, N_SUMS, len(self.g)))])
            self.n_after = np.append(self.n_after, 0)
            if len(self.tc) > MAX_CHANGE:
                keep = np.arange(len(self.tc)) % 2 == 0
                self.tc, self.sums, self.n_after = (self.tc[keep], self.sums[keep],
                                                    self.n_after[keep])
                self.step *= 2
        self.seen += 1
        self.recent.append((t, z))
        if len(self.recent) > WANDER_TESTS:
            del self.recent[0]

    def _prior(self) -> np.ndarray:
        """Weight of each growth rate (module docstring): P_LINE on g = 0, the rest flat
        in kappa over KAPPA, each grid point standing for its cell; rates with |kappa|
        below KAPPA_MIN are g = 0's (a straight line over the tests so far)."""
        span = max(self.t_now - self.t0, 1e-12)
        k = self.g * span
        use = self.on & (np.abs(k) >= KAPPA_MIN)
        use &= (k >= KAPPA[0]) & (k <= KAPPA[1] * 1.0001)
        ku = k[use]
        mid = np.concatenate([[KAPPA[0]], 0.5 * (ku[1:] + ku[:-1]), [KAPPA[1]]])
        mid[np.searchsorted(ku, 0.0)] = 0.0          # the cells stop at the line
        out = np.zeros(len(k))
        out[use] = np.maximum(mid[1:] - mid[:-1], 1e-9)
        out *= (1.0 - P_LINE) / max(out.sum(), 1e-300)
        out[self.g == 0.0] = P_LINE
        return out

    def fit(self, sigma0: float, n_healthy: int) -> Fit:
        """The posterior now (module docstring): `sigma0` the healthy tests' noise (u
        units) from `n_healthy` tests."""
        prior = self._prior()
        ok = self.n_after >= MIN_AFTER
        if not ok.any():
            ok = self.n_after >= self.n_after.max()
        gi = np.flatnonzero(prior > 0)
        logev, mean, cov, alpha, beta, tc, g = self._posterior(ok, gi, sigma0, n_healthy,
                                                              prior)
        w = np.exp(logev - logev.max())
        w /= w.sum()
        best = int(np.argmax(w))
        sig = np.sqrt(beta / max(alpha - 1.0, 0.5))
        z_last = (self.z_now - float(mean[best].sum())) / float(sig[best])
        keep = w > 1e-9 * w[best]
        w = w[keep] / w[keep].sum()
        sigma = float(np.sum(w * sig[keep]))
        f = Fit(self.t_now, self.t0, tc[keep], g[keep], w, mean[keep], cov[keep], alpha,
                beta[keep], sigma, sigma / sigma0, z_last)
        f.inflate, f.wander = self._wander(f, int(np.argmax(w)))
        return f

    def _wander(self, f: Fit, best: int) -> tuple[float, float]:
        """What the residuals of the best curve over the last WANDER_TESTS tests say
        beyond white noise: their lag-1 autocorrelation rho gives the factor
        (1 + rho) / (1 - rho) on the parameters' covariance (correlated residuals carry
        less information than as many independent ones), their variogram the variance q
        per time unit of a random walk on top of the curve (gamma(h) = s^2 + q h / 2,
        from lags 1 and `WANDER_LAG`)."""
        if len(self.recent) < 3 * WANDER_LAG:
            return 1.0, 0.0
        t, z = np.array(self.recent).T
        a, b, c = f.mean[best]
        r = z - level(f, np.array(a), np.array(b), np.array(c), f.tc[best:best + 1],
                      f.g[best:best + 1], t)
        r = r - r.mean()
        v = float(np.mean(r * r))
        if not v > 0:
            return 1.0, 0.0
        rho = float(np.mean(r[1:] * r[:-1])) / v
        inflate = min((1.0 + rho) / (1.0 - rho), 10.0) if rho > 2.0 / math.sqrt(len(r)) else 1.0
        g1 = 0.5 * float(np.mean((r[1:] - r[:-1]) ** 2))
        gm = 0.5 * float(np.mean((r[WANDER_LAG:] - r[:-WANDER_LAG]) ** 2))
        h1 = float(np.mean(t[1:] - t[:-1]))
        hm = float(np.mean(t[WANDER_LAG:] - t[:-WANDER_LAG]))
        q = max(0.0, 2.0 * (gm - g1) / (hm - h1)) if hm > h1 else 0.0
        return inflate, q

    def _posterior(self, ok: np.ndarray, gi: np.ndarray, sigma0: float, n_healthy: int,
                   prior: np.ndarray) -> tuple[Any, ...]:
        """Per grid point (candidates `ok` x rates `gi`): log evidence, posterior mean and
        covariance over sigma^2 of (a, b, c), sigma^2's alpha and beta, t_c and g."""
        tc = self.tc[ok]
        g = self.g[gi]
        n, st, stt, sz, stz, szz = self.glob
        span = max(self.t_now - self.t0, 1e-12)
        sums = self.sums[ok][:, :, gi]                             # (C, 4, K)
        norm = phi(g[None, :], np.maximum(self.t_now - tc, 1e-12)[:, None])   # (C, K)
        s1, s2, s3 = sums[:, 0] / norm, sums[:, 1] / norm ** 2, sums[:, 2] / norm
        sx = sums[:, 3] / norm / span
        prec = sigma0 * sigma0
        dof0 = max(n_healthy - 1.0, 1.0)
        alpha = 0.5 * (dof0 + n)
        logdet, mean, cov, beta = _nig(
            s1.ravel(), s2.ravel(), s3.ravel(), sx.ravel(), float(n_healthy) + n, st / span,
            prec + stt / span ** 2, sz, stz / span, szz, prec, dof0)
        logev = -0.5 * logdet - alpha * np.log(beta)
        # the truncation c > 0: the mass of c's Student-t marginal above 0
        logev = logev + np.log(np.maximum(stdtr(2.0 * alpha, mean[:, 2] / np.sqrt(
            beta / alpha * cov[:, 5])), 1e-300))
        logev = logev + np.log(np.broadcast_to(prior[gi][None, :], s1.shape)).ravel()
        shape = s1.shape
        return (logev, mean, cov, alpha, beta,
                np.broadcast_to(tc[:, None], shape).ravel(),
                np.broadcast_to(g[None, :], shape).ravel())


@njit(cache=True, error_model="numpy")
def _nig(s1: np.ndarray, s2: np.ndarray, s3: np.ndarray, sx: np.ndarray, p11: float,
         p12: float, p22: float, b1: float, b2: float, szz: float, prec: float,
         dof0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                               np.ndarray]:  # pragma: no cover - compiled
    """The normal-inverse-gamma posterior of (a, b, c) at each grid point: the design's
    precision P = V0^-1 + X'X (X = [1, x, psi]; P11, P12, P22 are the same at every
    point, P13 = sum psi, P23 = sum x psi, P33 = prec + sum psi^2), its log determinant,
    the mean P^-1 X'z, P^-1 packed (11, 12, 13, 22, 23, 33), and beta of sigma^2."""
    m = len(s1)
    logdet = np.empty(m)
    mean = np.empty((m, 3))
    cov = np.empty((m, 6))
    beta = np.empty(m)
    for i in range(m):
        p13, p23, p33 = s1[i], sx[i], prec + s2[i]
        c11 = p22 * p33 - p23 * p23
        c12 = p13 * p23 - p12 * p33
        c13 = p12 * p23 - p13 * p22
        c22 = p11 * p33 - p13 * p13
        c23 = p12 * p13 - p11 * p23
        c33 = p11 * p22 - p12 * p12
        det = p11 * c11 + p12 * c12 + p13 * c13
        c11, c12, c13, c22, c23, c33 = (c11 / det, c12 / det, c13 / det, c22 / det,
                                        c23 / det, c33 / det)
        b3 = s3[i]
        m1 = c11 * b1 + c12 * b2 + c13 * b3
        m2 = c12 * b1 + c22 * b2 + c23 * b3
        m3 = c13 * b1 + c23 * b2 + c33 * b3
        logdet[i] = math.log(det)
        mean[i, 0], mean[i, 1], mean[i, 2] = m1, m2, m3
        cov[i, 0], cov[i, 1], cov[i, 2] = c11, c12, c13
        cov[i, 3], cov[i, 4], cov[i, 5] = c22, c23, c33
        beta[i] = 0.5 * (dof0 * prec + max(szz - m1 * b1 - m2 * b2 - m3 * b3, 0.0))
    return logdet, mean, cov, beta


def level(f: Fit, a: np.ndarray, b: np.ndarray, c: np.ndarray, tc: np.ndarray,
          g: np.ndarray, t: np.ndarray) -> np.ndarray:
    """u of the curves (a, b, c, t_c, g) at times t >= t_now."""
    span = max(f.t_now - f.t0, 1e-12)
    s = np.maximum(f.t_now - tc, 1e-12)
    return a + b * (t - f.t0) / span + c * phi(g, t - tc) / phi(g, s)


def samples(f: Fit, rng: np.random.Generator, n: int = N_SAMPLES
            ) -> tuple[np.ndarray, np.ndarray]:
    """n draws of the posterior (module docstring): the times from now until u = 1 (inf
    where the curve does not get there within HORIZON spans, 0 where it is past it) and
    the level now."""
    cs = np.cumsum(f.w)
    pick = np.minimum(np.searchsorted(cs, rng.random(n) * cs[-1]), len(cs) - 1)
    m, cv = f.mean[pick], f.cov[pick]
    s2 = f.inflate * f.beta[pick] / rng.gamma(f.alpha, size=n)   # sigma^2, inverse gamma
    # c from its truncated (c > 0) marginal, then (a, b) given c
    sd_c = np.sqrt(s2 * cv[:, 5])
    lo = ndtr(-m[:, 2] / sd_c)
    q = lo + (1.0 - lo) * rng.random(n)
    c = np.maximum(m[:, 2] + sd_c * ndtri(np.clip(q, 1e-16, 1 - 1e-16)), 1e-12)
    a, b = _given_c(m, cv, s2, c, rng.standard_normal(n), rng.standard_normal(n))
    tc, g = f.tc[pick], f.g[pick]
    now = a + b + c
    rul = _crossing(f, a, b, c, tc, g)
    if f.wander > 0:
        # the random walk on top: the first passage of a drift with its variance q over
        # the distance left, IG(rul, d^2 / q) (exact for a straight line)
        d = np.maximum(1.0 - now, 0.0)
        go = np.isfinite(rul) & (rul > 0) & (d > 0)
        if go.any():
            rul = rul.copy()
            rul[go] = rng.wald(rul[go], d[go] ** 2 / f.wander)
    return np.where(now >= 1.0, 0.0, rul), now


def local_drift(t: np.ndarray, u: np.ndarray, t_change: float, rng: np.random.Generator,
                n: int) -> np.ndarray:
    """n RUL draws of the local drift model (module docstring, "Two models"): the level
    rising at the constant drift of the recent tests (no diffusion term), those of the later half
    of the time since the change `t_change` (at least `LOCAL_MIN` tests): the ordinary
    least-squares line through them, level now and slope drawn from their Student-t
    posterior (flat prior; Gelman et al., BDA section 14.2), the time the line reaches
    u = 1 (0 where it is past, inf where it does not rise)."""
    t_now = float(t[-1])
    sel = t >= t_change + LOCAL_FRAC * (t_now - t_change)
    if sel.sum() < LOCAL_MIN:
        sel = np.arange(len(t)) >= len(t) - LOCAL_MIN
    x, y = t[sel] - t_now, u[sel]
    m = len(x)
    if m < 3 or np.ptp(x) <= 0:
        return np.full(n, np.inf)
    xm, ym = float(x.mean()), float(y.mean())
    sxx = float(np.sum((x - xm) ** 2))
    slope = float(np.sum((x - xm) * (y - ym))) / sxx
    now = ym - slope * xm
    dof = m - 2.0
    s2 = max(float(np.sum((y - now - slope * x) ** 2)) / max(dof, 1.0), 1e-30)
    # (now, slope): covariance s2 (X'X)^-1, X = [1, x], as a Student-t of dof
    c11, c12, c22 = s2 * (1.0 / m + xm * xm / sxx), -s2 * xm / sxx, s2 / sxx
    l11 = math.sqrt(c11)
    l21 = c12 / l11
    l22 = math.sqrt(max(c22 - l21 * l21, 0.0))
    e = rng.standard_normal((2, n)) / np.sqrt(rng.chisquare(max(dof, 1.0), n) / max(dof, 1.0))
    lv = now + l11 * e[0]
    sl = slope + l21 * e[0] + l22 * e[1]
    with np.errstate(divide="ignore"):
        rul = np.where(sl > 0, (1.0 - lv) / np.where(sl > 0, sl, 1.0), np.inf)
    return np.where(lv >= 1.0, 0.0, rul)


@njit(cache=True, error_model="numpy")
def _given_c(m: np.ndarray, cv: np.ndarray, s2: np.ndarray, c: np.ndarray, e1: np.ndarray,
             e2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
    """(a, b) drawn given c from the Gaussian of (a, b, c) (mean `m`, covariance `s2` x
    `cv`, cv packed 11 12 13 22 23 33): the conditional mean and the Cholesky factor of
    the conditional covariance, times the standard normals e1, e2."""
    n = len(c)
    a = np.empty(n)
    b = np.empty(n)
    for i in range(n):
        c11, c12, c13, c22, c23, c33 = cv[i, 0], cv[i, 1], cv[i, 2], cv[i, 3], cv[i, 4], cv[i, 5]
        scale = math.sqrt(s2[i])
        k1, k2 = c13 / c33, c23 / c33
        d = c[i] - m[i, 2]
        v11 = c11 - k1 * c13
        v21 = c12 - k1 * c23
        v22 = c22 - k2 * c23
        l11 = math.sqrt(max(v11, 0.0))
        l21 = v21 / l11 if l11 > 0 else 0.0
        l22 = math.sqrt(max(v22 - l21 * l21, 0.0))
        a[i] = m[i, 0] + k1 * d + scale * l11 * e1[i]
        b[i] = m[i, 1] + k2 * d + scale * (l21 * e1[i] + l22 * e2[i])
    return a, b


def _crossing(f: Fit, a: np.ndarray, b: np.ndarray, c: np.ndarray, tc: np.ndarray,
              g: np.ndarray) -> np.ndarray:
    """The first time after now each curve reaches u = 1 (inf when none does within
    HORIZON spans; `_crossings`)."""
    span = max(f.t_now - f.t0, 1e-12)
    n = len(a)
    return _crossings(np.ascontiguousarray(a, dtype=np.float64),
                      np.ascontiguousarray(np.broadcast_to(b, n), dtype=np.float64),
                      np.ascontiguousarray(np.broadcast_to(c, n), dtype=np.float64),
                      np.ascontiguousarray(np.broadcast_to(f.t_now - tc, n), dtype=np.float64),
                      np.ascontiguousarray(np.broadcast_to(g, n), dtype=np.float64),
                      span, HORIZON * span)


@njit(cache=True, error_model="numpy")
def _crossings(a: np.ndarray, b: np.ndarray, c: np.ndarray, s: np.ndarray, g: np.ndarray,
               span: float, hor: float) -> np.ndarray:  # pragma: no cover - compiled
    """Per curve u(tau) = a + b (span + tau) / span + c phi_g(s + tau) / phi_g(s): the
    first tau >= 0 with u = 1. A straight line's in closed form; a curved one's by
    Newton's method, which is monotone here: the curve is convex for g > 0 (one
    crossing from below at most; started at the sooner of the drift's and the wear-out's
    own crossing) and concave for g < 0 (a slope <= 0 before the crossing means its top
    is below 1: never). inf when none within `hor`."""
    # long: one Newton iteration per curve, its start and its two ways out
    out = np.empty(len(a))
    for i in range(len(a)):
        si = max(s[i], 1e-12)
        gi = g[i]
        line = gi == 0.0
        phis = si if line else math.expm1(gi * si) / gi
        bs, cp = b[i] / span, c[i] / phis
        base = a[i] + b[i]
        need = 1.0 - (base + c[i])
        if need <= 0.0:
            out[i] = 0.0
            continue
        if line:
            slope = bs + cp
            out[i] = need / slope if slope > 0 and need / slope < hor else np.inf
            continue
        # the start: the sooner of the wear-out alone (exact for b = 0) and the drift alone
        arg = 1.0 + need * gi * phis / (c[i] * math.exp(min(gi * si, 700.0)))
        tau = math.log(arg) / gi if arg > 0 else np.inf
        if b[i] > 0:
            tau = min(tau, need / bs)
        tau = min(max(tau, 0.0), hor)
        found = False
        jumped = False
        for _ in range(100):
            e = math.exp(min(gi * (si + tau), 700.0))
            val = base + bs * tau + cp * (e - 1.0) / gi
            slope = bs + cp * e
            if abs(val - 1.0) < 1e-10:
                found = True
                break
            if slope <= 0.0:
                if gi > 0 and not jumped:  # convex, falling now: from the horizon's side
                    tau, jumped = hor, True
                    continue
                break                      # concave past its top below 1
            nxt = min(max(tau - (val - 1.0) / slope, 0.0), hor)
            if nxt == tau:
                found = abs(val - 1.0) < 1e-6
                break
            tau = nxt
        out[i] = tau if found and tau < hor else np.inf
    return out


def make_model(g: float = 0.0, b_rate: float = 0.0) -> Any:
    """The curve as a progpy `PrognosticsModel`: states u and r (the wear-out's rate),
    du/dt = b_rate + r, dr/dt = g r; event ``failure`` at u >= 1. From u(t_now) = a + b
    + c, b_rate = b / (t_now - t_0), r(t_now) = c exp(g S) / phi_g(S) it is a fitted
    curve from now on (module docstring)."""
    import matplotlib
    with matplotlib.rc_context():   # importing progpy rewrites matplotlib's rcParams
        from progpy import PrognosticsModel

    class CurveModel(PrognosticsModel):  # type: ignore[misc]
        """Degradation level u: a steady drift and a wear-out of exponential rate."""
        states = ["u", "r"]
        inputs: list[str] = []
        outputs = ["y"]
        events = ["failure"]
        default_parameters = {"x0": {"u": 0.0, "r": 0.01}, "g": g, "b": b_rate,
                              "process_noise": 0.0}

        def initialize(self, u: Any = None, z: Any = None) -> Any:
            return self.StateContainer(self.parameters["x0"])

        def next_state(self, x: Any, u: Any, dt: float) -> Any:
            gg = self.parameters["g"]
            step = float(phi(np.array(gg), np.array(dt)))
            return self.StateContainer({"u": x["u"] + self.parameters["b"] * dt
                                        + x["r"] * step, "r": x["r"] * math.exp(gg * dt)})

        def output(self, x: Any) -> Any:
            return self.OutputContainer({"y": x["u"]})

        def event_state(self, x: Any) -> dict[str, Any]:
            return {"failure": max(1.0 - float(x["u"]), 0.0)}

        def threshold_met(self, x: Any) -> dict[str, Any]:
            return {"failure": bool(x["u"] >= 1.0)}

    return CurveModel()
