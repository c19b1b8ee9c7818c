"""A loop that oscillates by itself: detected in the log, and the effects that make the
model's loop oscillate the same way (docs/gap.md, "The verdict in words").

A self-excited oscillation (a limit cycle: a speed loop with too much delay, too little
phase margin) is not locked to the set-point. A model with the right cause oscillates at
the same frequency but at its own phase, so the sample-by-sample residual of two
oscillations is larger than that of none, and a least-squares fit, and every score on
that residual, prefers a cause that does not oscillate. The frequency is what the two
share. This module is a note next to the verdict, not a verdict: it says that the log
holds such an oscillation and which effects, at which values, reproduce its frequency.

The statistic, on the motor speed's residual against the nominal re-simulation (Welch
spectra, about 1 Hz bins): the strongest line above `F_LO_HZ`, its power over the noise
floor's at that frequency (the bootstrap of the noise through the loop) and the share of
the residual's power above `F_LO_HZ` that the line (+-2 bins) holds. A limit cycle is a
line that holds most of it (`LINE_SHARE`) far above the floor (`PSD_RATIO`). Both were
set on development logs only (docs/gap.md, the same section).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.signal import welch

from bench.gap import effects as E
from bench.gap.problem import Problem

SIGNAL = "motor_speed_rad_s"
F_LO_HZ = 5.0           # below: the set-point's own motion and its first harmonics
LINE_SHARE = 0.8        # share of the residual's power above F_LO_HZ in the line (+-2 bins)
PSD_RATIO = 1e3         # the line's power over the noise floor's at that frequency
MATCH_BINS = 1.5        # a model reproduces the oscillation within this many bins


def line(residual: np.ndarray, dt: float, floor: Sequence[np.ndarray] = ()
         ) -> dict[str, float]:
    """The strongest spectral line of `residual` above F_LO_HZ: its frequency (Hz), the
    share of the power above F_LO_HZ it holds (+-2 bins), its power over the mean of the
    `floor` residuals' at that frequency (inf without them) and the bin width (Hz)."""
    fs = 1.0 / dt
    nps = int(min(1024, max(16, len(residual) // 4)))
    f, pr = welch(np.asarray(residual, float), fs=fs, nperseg=nps)
    idx = np.where((f >= F_LO_HZ) & (f <= 0.45 * fs))[0]
    if len(idx) < 5 or not np.all(np.isfinite(pr[idx])) or pr[idx].sum() <= 0.0:
        return {"freq_hz": float("nan"), "line_share": 0.0, "psd_ratio": 0.0,
                "bin_hz": float(f[1] - f[0])}
    k = int(idx[np.argmax(pr[idx])])
    share = float(pr[max(k - 2, idx[0]):min(k + 3, idx[-1] + 1)].sum() / pr[idx].sum())
    ratio = float("inf")
    if len(floor):
        pb = np.mean([welch(np.asarray(b, float), fs=fs, nperseg=nps)[1] for b in floor],
                     axis=0)
        ratio = float(pr[k] / pb[k]) if pb[k] > 0 else float("inf")
    return {"freq_hz": float(f[k]), "line_share": share, "psd_ratio": ratio,
            "bin_hz": float(f[1] - f[0])}


def oscillates(st: dict[str, float]) -> bool:
    return st["line_share"] >= LINE_SHARE and st["psd_ratio"] >= PSD_RATIO


def detect(p: Problem) -> dict[str, Any]:
    """The log's statistic (`line`) on the motor speed's residual against the nominal
    re-simulation, with the noise floor's bootstrap; "detected" when it `oscillates`."""
    r = p.meas[SIGNAL] - p.info["nominal"][SIGNAL]
    st = line(r, p.dt, [b[SIGNAL] for b in p.info.get("bootstrap", [])])
    return {"signal": SIGNAL, **st, "detected": oscillates(st)}


def reproduced_by(p: Problem, names: Sequence[str], freq_hz: float, bin_hz: float
                  ) -> list[dict[str, Any]]:
    """The in-loop effects of `names` that, at one of their start points (a discrete
    parameter: each value of its grid), make the model's loop oscillate at `freq_hz`
    (+-MATCH_BINS bins): per effect, the value whose line is closest."""
    out = []
    nominal = p.info["nominal"][SIGNAL]
    for name in names:
        eff = E.get(name).for_model(p.base)
        if eff.in_log(p.base):
            continue                      # after the run: cannot change the loop
        one = eff.params[0]
        points = ([{one.name: v} for v in one.grid()] if eff.discrete and len(eff.params) == 1
                  else eff.start_points(p.base))
        best = None
        for th in points:
            sim = p.simulate([eff], [th], p.n)
            st = line(sim[SIGNAL] - nominal, p.dt)
            off = abs(st["freq_hz"] - freq_hz)
            if st["line_share"] >= LINE_SHARE and off <= MATCH_BINS * bin_hz \
                    and (best is None or off < best[0]):
                best = (off, th, st["freq_hz"])
        if best is not None:
            out.append({"effect": name, "params": best[1], "freq_hz": best[2]})
    return out


def note(p: Problem, names: Sequence[str]) -> dict[str, Any] | None:
    """The localisation's `limit_cycle` entry: None when the log shows none; else the
    statistic, the effects that reproduce its frequency and the note in words."""
    d = detect(p)
    if not d["detected"]:
        return None
    d["reproduced_by"] = reproduced_by(p, names, d["freq_hz"], d["bin_hz"])
    who = ", ".join(f"{r['effect']} (" + ", ".join(f"{k} = {v:.4g}" for k, v in
                                                   r["params"].items())
                    + f": {r['freq_hz']:.1f} Hz)" for r in d["reproduced_by"])
    d["note"] = (f"the loop oscillates by itself at {d['freq_hz']:.1f} Hz (motor speed: one "
                 f"line holds {100 * d['line_share']:.0f}\u00a0% of the residual above "
                 f"{F_LO_HZ:g} Hz); a self-excited oscillation is not locked to the set-point, "
                 "so the residual-based fit and ranking cannot match it; "
                 + (f"at this frequency the model oscillates with {who}" if who else
                    "no single effect of the library makes the model oscillate at it"))
    return d
