"""`UsageSummary`: the usage of one run (or of several, accumulated), and `accumulate`.

Scalars are additive (sums), extremes or derived from sums (F_m, L10, RMS current), so
that `accumulate` over runs equals the usage of the runs joined end to end (apart from
the cycles a rainflow count would close across two runs, and the reversal where one
run ends and the next begins). The spectra and rainflow matrices have fixed bins
(`bench.usage.settings`) and add bin by bin. `as_dict` gives flat floats for a store
(`bench.usage` is called per run by the fleet store); `to_json` everything.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from bench import BenchError
from bench.usage import life
from bench.usage.hysteresis import merged_why
from bench.usage.settings import (
    LOAD_EDGES_N,
    LOAD_MEAN_EDGES_N,
    LOAD_RANGE_EDGES_N,
    POS_MEAN_EDGES_M,
    POS_RANGE_EDGES_M,
    REGIMES,
    TEMP_EDGES_K,
    edge_label,
)

UNKNOWN = "unknown"
ARRAYS = {"load_spectrum_rev": (len(LOAD_EDGES_N) - 1,),
          "temperature_time_s": (len(TEMP_EDGES_K) - 1,),
          "position_rainflow": (len(POS_RANGE_EDGES_M) - 1, len(POS_MEAN_EDGES_M) - 1),
          "load_rainflow": (len(LOAD_RANGE_EDGES_N) - 1, len(LOAD_MEAN_EDGES_N) - 1)}
"""The binned quantities: load spectrum (revolutions per signed load bin), time per
winding-temperature bin, rainflow matrices (cycles per range bin x mean bin)."""
SUMS = ("runs", "samples", "duration_s", "screw_revolutions", "nut_travel_m", "reversals",
        "position_cycles", "load_cycles", "load_cube_sum", "damage", "damage_nut1",
        "damage_nut2", "i2t_a2s", "time_unknown_regime_s", "dwell_s", "slow_s", "fast_s",
        "revolutions_dwell", "revolutions_slow", "revolutions_fast", "load_samples")
MAXIMA = ("position_range_max_m", "load_range_max_n", "load_max_n", "temperature_max_k",
          "position_hysteresis_m", "load_hysteresis_n")
MINIMA = ("load_min_n",)


def _zeros(name: str) -> np.ndarray:
    return np.zeros(ARRAYS[name])


@dataclass
class UsageSummary:
    """The usage of one actuator over one run or more (docs/usage.md for each quantity)."""
    actuator_serial: str = UNKNOWN
    source: str = ""
    load_rating_n: float = math.nan        # C_a used
    preload_mode: str = "none"
    preload_n: float = 0.0
    runs: float = 1.0
    samples: float = 0.0
    duration_s: float = 0.0
    screw_revolutions: float = 0.0         # through the play of the reversal hysteresis
    nut_travel_m: float = 0.0              # screw revolutions x lead
    reversals: float = 0.0
    position_cycles: float = 0.0           # rainflow (ASTM E1049): full cycles, halves as 0.5
    position_range_max_m: float = 0.0
    load_cycles: float = 0.0
    load_range_max_n: float = 0.0
    load_samples: float = 0.0              # samples with a load-cell reading
    load_max_n: float = -math.inf
    load_min_n: float = math.inf
    load_cube_sum: float = 0.0             # sum |F|^3 n over revolutions (N^3 rev)
    damage: float = 0.0                    # life consumed, Miner sum (mode "none")
    damage_nut1: float = 0.0
    damage_nut2: float = 0.0
    i2t_a2s: float = 0.0
    temperature_max_k: float = -math.inf
    dwell_s: float = 0.0
    slow_s: float = 0.0
    fast_s: float = 0.0
    time_unknown_regime_s: float = 0.0
    revolutions_dwell: float = 0.0
    revolutions_slow: float = 0.0
    revolutions_fast: float = 0.0
    load_spectrum_rev: np.ndarray = field(default_factory=lambda: _zeros("load_spectrum_rev"))
    temperature_time_s: np.ndarray = field(default_factory=lambda: _zeros("temperature_time_s"))
    position_rainflow: np.ndarray = field(default_factory=lambda: _zeros("position_rainflow"))
    load_rainflow: np.ndarray = field(default_factory=lambda: _zeros("load_rainflow"))
    position_hysteresis_m: float = 0.0     # the hystereses used (bench.usage.hysteresis)
    load_hysteresis_n: float = 0.0
    hysteresis: dict[str, str] = field(default_factory=dict)      # counter -> used and why
    not_available: dict[str, str] = field(default_factory=dict)   # quantity -> reason

    # -- derived ---------------------------------------------------------------------------
    @property
    def fm_n(self) -> float:
        """Equivalent dynamic axial load, the cubic mean of |F| over revolutions."""
        return life.equivalent_load_n(self.load_cube_sum, self.screw_revolutions)

    @property
    def l10_rev(self) -> float:
        """Rating life at F_m: (C_a / F_m)^3 x 10^6 revolutions (NaN when the revolutions
        or the load are not available)."""
        if math.isnan(self.load_cube_sum) or math.isnan(self.screw_revolutions):
            return math.nan
        return life.rating_life_rev(self.load_rating_n, self.fm_n)

    @property
    def life_consumed(self) -> float:
        """Fraction of the rating life used (Palmgren-Miner), as `preload_mode` says."""
        if self.preload_mode == "double-nut":
            return life.system_damage(self.damage_nut1, self.damage_nut2)
        return self.damage

    @property
    def current_rms_a(self) -> float:
        return math.sqrt(self.i2t_a2s / self.duration_s) if self.duration_s > 0 else math.nan

    # -- output ----------------------------------------------------------------------------
    def as_dict(self) -> dict[str, float]:
        """Flat floats for a store: every scalar, the derived ones, the time per regime and
        per temperature bin (``time_s_temp_<lo>_<hi>_k``); an extreme of a signal the run
        did not have is NaN, L10 without load inf. The load spectrum and the
        rainflow matrices are in `arrays` (and `to_json`)."""
        out: dict[str, float] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float | int) and not isinstance(v, bool):
                out[f.name] = float(v)
        for name in (*MAXIMA, *MINIMA):      # no sample seen: NaN, not the +-inf seed
            if math.isinf(out[name]):
                out[name] = math.nan
        out.update(fm_n=self.fm_n, l10_rev=self.l10_rev, life_consumed=self.life_consumed,
                   current_rms_a=self.current_rms_a)
        for k, (lo, hi) in enumerate(zip(TEMP_EDGES_K[:-1], TEMP_EDGES_K[1:], strict=True)):
            out[f"time_s_temp_{edge_label(lo, hi)}_k"] = float(self.temperature_time_s[k])
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name) for name in ARRAYS}

    def to_json(self) -> dict[str, Any]:
        """Everything, JSON-ready (no inf or NaN: None); `not_available`: the quantities
        the run's signals cannot give (null) and why."""
        def clean(v: float) -> float | None:
            return v if math.isfinite(v) else None
        return {"actuator_serial": self.actuator_serial, "source": self.source,
                "preload_mode": self.preload_mode, "hysteresis": dict(self.hysteresis),
                **{k: clean(v) for k, v in self.as_dict().items()},
                **{k: (None if k in self.not_available else a.tolist())
                   for k, a in self.arrays().items()},
                "not_available": dict(self.not_available),
                "bins": {"load_edges_n": _edges(LOAD_EDGES_N),
                         "temperature_edges_k": _edges(TEMP_EDGES_K),
                         "position_range_edges_m": _edges(POS_RANGE_EDGES_M),
                         "position_mean_edges_m": _edges(POS_MEAN_EDGES_M),
                         "load_range_edges_n": _edges(LOAD_RANGE_EDGES_N),
                         "load_mean_edges_n": _edges(LOAD_MEAN_EDGES_N)},
                "regimes": list(REGIMES)}


def blank(s: UsageSummary, names: Iterable[str]) -> None:
    """Set the scalar quantities `names` of `s` to NaN (not available; the derived ones,
    F_m, L10, life consumed and RMS current, follow from them)."""
    scalars = {f.name for f in fields(s) if f.type in ("float", float)}
    for name in names:
        if name in scalars:
            setattr(s, name, math.nan)


def _edges(e: np.ndarray) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in e]


def accumulate(summaries: list[UsageSummary]) -> dict[str, UsageSummary]:
    """Per actuator (by serial, in order of first appearance): the runs' usage added up
    (Miner sums added, spectra and rainflow matrices merged bin by bin, F_m the cubic mean
    over all revolutions). BenchError when one actuator's runs disagree on C_a or on the
    preload treatment (their life consumed could not be added)."""
    out: dict[str, UsageSummary] = {}
    for s in summaries:
        acc = out.get(s.actuator_serial)
        if acc is None:
            out[s.actuator_serial] = merged(UsageSummary(
                actuator_serial=s.actuator_serial, source="", runs=0.0,
                load_rating_n=s.load_rating_n, preload_mode=s.preload_mode,
                preload_n=s.preload_n), s)
        else:
            out[s.actuator_serial] = merged(acc, s)
    return out


def merged(a: UsageSummary, b: UsageSummary) -> UsageSummary:
    """`a` and `b` added (a new summary; `a` keeps C_a and the preload treatment; the
    preload must agree only where it counts, with `preload_mode` double-nut)."""
    if a.load_rating_n != b.load_rating_n or a.preload_mode != b.preload_mode \
            or a.preload_mode == "double-nut" and a.preload_n != b.preload_n:
        raise BenchError(f"actuator {b.actuator_serial}: runs with different C_a or preload "
                         f"({a.load_rating_n:g} N {a.preload_mode} {a.preload_n:g} N against "
                         f"{b.load_rating_n:g} N {b.preload_mode} {b.preload_n:g} N {b.source})"
                         ": their life consumed does not add")
    new = UsageSummary(actuator_serial=a.actuator_serial,
                       source=", ".join(x for x in (a.source, b.source) if x),
                       load_rating_n=a.load_rating_n, preload_mode=a.preload_mode,
                       preload_n=a.preload_n)
    for name in SUMS:
        setattr(new, name, getattr(a, name) + getattr(b, name))
    for name in MAXIMA:
        setattr(new, name, max(getattr(a, name), getattr(b, name)))
    for name in MINIMA:
        setattr(new, name, min(getattr(a, name), getattr(b, name)))
    for name in ARRAYS:
        setattr(new, name, getattr(a, name) + getattr(b, name))
    new.hysteresis = merged_why(a.hysteresis, b.hysteresis,
                                {"position": new.position_hysteresis_m,
                                 "load": new.load_hysteresis_n})
    # what one run cannot give, the sum cannot either (named with the run)
    new.not_available = {**a.not_available, **{
        k: f"{v} ({b.source or 'a run'})" for k, v in b.not_available.items()
        if k not in a.not_available}}
    blank(new, new.not_available)
    return new
