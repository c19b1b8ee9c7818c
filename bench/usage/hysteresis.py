"""The hysteresis each counter uses on one log, and why (docs/usage.md, "Hysteresis").

The settings' hystereses are chosen for the thesis' sensors (20 um: ten times the LVDT's
2 um noise; 100 N: fifty times the load cell's 2 N). A log from another rig can be far
noisier (the Cranfield rig's linear potentiometer at 25 Hz: about 0.3 mm), and then
rainflow counts its noise as cycles. So a counter takes the larger of its setting and a
factor (`usage.position_noise_factor`, 10) x the log's own noise of its signal: a noise
peak of 5 sigma each way does not close a cycle, the rationale of the default. The noise
is the white-noise sigma the rig calibration uses (`bench.signals.estimators.noise_floor`: the
robust spread of the second differences / sqrt 6), from the log's measured samples; a
smooth motion's second differences are small except where it accelerates, and the
median-based spread ignores those few samples.

The load's factor (`usage.load_noise_factor`) is 0 by default, the rule off: the second
differences cannot tell sensor noise from a load that is itself rough, and the bench's
own aero load (first-order coloured gusts, 1 kN std, 0.5 s) reads 36-37 N of "noise" at
1 kHz where its load cell has 2 N: 100 N would become 360-370 N, and the load cycles of a
20 s flight 206 instead of 1298. A rig with a noisy load cell sets it (10, as the position's).

The setting stays a floor: a `--set` value is raised too when the log is noisier (the
output says so); a factor of 0 turns the rule off. The rule raises a setting only when
the log's noise is above the setting's share (setting / factor) by more than
`SCATTER_SIGMAS` times the estimate's own scatter, so that a log of the bench's plant,
whose LVDT noise is the very 2 um the default was chosen for, keeps the setting rather
than whichever side of it its estimate falls on.

The reversal and revolution counters run on the encoder angle (quantised, not noisy in
this sense): they keep their setting. The live watcher (`bench.usage.online`) uses the
settings: the rule needs the whole log's noise before the first row is counted.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.signals.estimators import noise_floor
from bench.usage.settings import UsageSettings

COUNTERS = {"reversal": ("motor_angle_rad", "reversal_hysteresis_m", "m"),
            "position": ("position_m", "position_hysteresis_m", "m"),
            "load": ("load_force_n", "load_hysteresis_n", "N")}
"""Counter: (the signal it counts on, its setting, unit)."""
NOISY = {"position": "position_noise_factor", "load": "load_noise_factor"}
"""The counters the noise rule can apply to (measured analogue signals): their factor."""
SCATTER = 1.4
"""Relative standard error of `noise_floor` x sqrt(samples), measured on white noise under
a slow sine (200 draws each: 3.3 % on 1500 samples, 2.0 % on 5000, 0.95 % on 20000)."""
SCATTER_SIGMAS = 3.0
"""How far above the setting's share the estimate must be, in its own standard errors."""


@dataclass(frozen=True)
class Hysteresis:
    """One counter's hysteresis on one log: `used` is `setting`, or `factor` x `noise` when
    that is above it by more than the estimate's scatter (`of_log`)."""
    counter: str
    setting: float
    used: float
    noise: float = math.nan        # the log's white-noise sigma of the signal (NaN: none)
    samples: int = 0               # measured samples the noise is taken from
    factor: float = 0.0            # the noise rule's multiple (0: rule off or not applied)
    note: str = ""                 # why the setting holds, when the rule was not applied

    @property
    def unit(self) -> str:
        return COUNTERS[self.counter][2]

    @property
    def raised(self) -> bool:
        return self.used > self.setting

    def why(self) -> str:
        """``20 um (setting)``, ``2.7 mm = 10 x the log's position noise 0.27 mm (setting
        20 um)`` and the like."""
        v, s, u = _fmt(self.used, self.unit), _fmt(self.setting, self.unit), self.unit
        if self.raised:
            return (f"{v} = {self.factor:g} x the log's {self.counter} noise "
                    f"{_fmt(self.noise, u)} (setting {s})")
        return f"{s} (setting; {self.note or self._not_raised()})"

    def _not_raised(self) -> str:
        if self.counter not in NOISY:
            return "on the encoder angle, no noise rule"
        if self.factor == 0:
            return f"noise rule off: usage.{NOISY[self.counter]}=0"
        if math.isnan(self.noise):
            return (f"no measured {COUNTERS[self.counter][0]}" if not self.samples else
                    f"{self.samples} samples are too few for its noise")
        share = _fmt(self.setting / self.factor, self.unit)
        if self.factor * self.noise > self.setting:
            return (f"the log's {self.counter} noise {_fmt(self.noise, self.unit)} is within "
                    f"its estimate's scatter of {share}")
        return f"the log's {self.counter} noise {_fmt(self.noise, self.unit)}"


def _fmt(x: float, unit: str) -> str:
    """A length in um or mm, a force in N or kN, three significant digits."""
    if not math.isfinite(x):
        return "n/a"
    if unit == "m":
        return f"{x * 1e3:.3g} mm" if abs(x) >= 1e-4 else f"{x * 1e6:.3g} um"
    return f"{x / 1e3:.3g} kN" if abs(x) >= 1e3 else f"{x:.3g} N"


def of_settings(settings: UsageSettings, note: str = "no noise rule applied"
                ) -> dict[str, Hysteresis]:
    """The settings alone (the live watcher), `note` saying why for the noisy signals."""
    return {c: Hysteresis(c, float(getattr(settings, name)), float(getattr(settings, name)),
                          note=note if c in NOISY else "")
            for c, (_, name, _) in COUNTERS.items()}


def of_log(settings: UsageSettings, columns: Mapping[str, Any]) -> dict[str, Hysteresis]:
    """Each counter's hysteresis on a log with these columns (module docstring)."""
    out = of_settings(settings)
    for c, factor_name in NOISY.items():
        factor = float(getattr(settings, factor_name))
        signal, _, _ = COUNTERS[c]
        setting = out[c].setting
        y = np.asarray(columns[signal], dtype=float) if signal in columns else np.zeros(0)
        n = int(np.isfinite(y).sum())
        sigma = noise_floor(y) if n and factor > 0 else math.nan   # rule off: not needed
        used = setting
        if math.isfinite(sigma):
            low = sigma * (1.0 - SCATTER_SIGMAS * SCATTER / math.sqrt(n))
            if factor * low > setting:
                used = factor * sigma
        out[c] = Hysteresis(c, setting, used, sigma, n, factor)
    return out


def merged_why(a: Mapping[str, str], b: Mapping[str, str], used: Mapping[str, float]
               ) -> dict[str, str]:
    """The reasons of two summaries added (`bench.usage.summary.merged`): a reason both
    give, else the largest hysteresis `used` (position, load) and that the runs differ."""
    out = {}
    for c in COUNTERS:
        wa, wb = a.get(c), b.get(c)
        if wa is None or wb is None or wa == wb:
            w = wa if wb is None else wb
            if w is not None:
                out[c] = w
            continue
        top = f"up to {_fmt(used[c], COUNTERS[c][2])}; " if c in used else ""
        out[c] = f"{top}the runs differ (each run's line says why)"
    return out


def text(why: Mapping[str, str]) -> str:
    """One line: ``reversal 2 um (setting; ...); position ...; load ...``."""
    return "; ".join(f"{c} {w}" for c, w in why.items())
