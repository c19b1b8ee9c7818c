"""`bench fleet status`: one line per actuator from the fleet store.

For each actuator: its last test (UTC), the level of that test (the verdict of
`bench.hums.verdict.judge`), the trend (least-squares slope of Ci per day over its last
`n_trend` tests, with its sign), the RUL with its band, the usage consumed.

Ci here is the index the verdict rests on in position mode: Ci over the command
frequency and its first 15 harmonics where the log gives it, else the broadband Ci
(eq. 6.6; `bench.hums.verdict`). The RUL is the thesis' algorithm (section 6.5,
`bench.hums.rul.thesis_predict`) applied to the actuator's series of daily tests
instead of the command periods of one run: once Ci has crossed the threshold 0.93 and
then the warning level 0.80, a cubic fitted to Ci(t) from the threshold crossing to the
latest test is extrapolated to the failure level 0.56; the band is the 5-95 % spread of
a residual bootstrap of that fit. Where the algorithm does not apply (no crossing yet,
or too few tests between the crossings) the RUL is "n/a" with the reason.
The usage consumed is the sum of the logged runs' ``life_consumed`` (fraction of L10,
Palmgren-Miner; docs/usage.md); n/a when no run had a load signal, and a note under the
table where an actuator at WARNING or FAILURE shows ~0 (`usage_note`).
"""

from __future__ import annotations

import datetime as dt
import math
import textwrap
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench import BenchError
from bench.core.verdict import Level
from bench.hums import rul as R
from bench.hums.verdict import judged_ci

DAY_S = 86400.0
N_TREND = 10
"""Tests the trend's slope is fitted over (the last ones)."""


@dataclass
class ActuatorStatus:
    """One actuator's state in the store (times in epoch seconds, RUL in days)."""
    ident: str
    tests: int
    last_time_s: float
    verdict: str
    ci_last: float
    slope_per_day: float
    rul_days: float = math.nan
    rul_band_days: tuple[float, float] = (math.nan, math.nan)
    rul_why: str = ""
    life_consumed: float = math.nan
    reasons: str = ""
    t_threshold_s: float = math.nan
    t_warning_s: float = math.nan
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def level(self) -> Level:
        """The last test's level (`bench.core.verdict.Level`: its code is -1 for UNKNOWN)."""
        return Level.parse(self.verdict)


def slope_per_day(t_s: np.ndarray, y: np.ndarray, n: int = N_TREND) -> float:
    """Least-squares slope of y per day over the last `n` finite points (NaN if < 2)."""
    m = np.isfinite(y)
    t, v = t_s[m][-n:], y[m][-n:]
    if len(t) < 2 or np.ptp(t) <= 0:
        return math.nan
    return float(np.polyfit((t - t[-1]) / DAY_S, v, 1)[0])


def rul_of(t_s: np.ndarray, ci: np.ndarray) -> tuple[float, tuple[float, float], str,
                                                    float, float]:
    """The thesis' RUL over the daily tests (module docstring): (RUL days, band days,
    why not, threshold crossing, warning crossing)."""
    m = np.isfinite(ci)
    t, y = t_s[m], ci[m]
    nan2 = (math.nan, math.nan)
    if len(t) == 0:
        return math.nan, nan2, "n/a: no Ci in any test", math.nan, math.nan
    if y[-1] < R.FAILURE:
        hit = np.flatnonzero(y >= R.FAILURE)
        since = t[hit[-1] + 1] if len(hit) else t[0]
        return (0.0, (0.0, 0.0), f"failure level {R.FAILURE} reached on {_date(since)}",
                math.nan, math.nan)
    days = (t - t[0]) / DAY_S
    res = R.thesis_predict(days, y, t_pred_s=float(days[-1]))
    if res is None:
        return (math.nan, nan2, f"n/a: Ci above the threshold {R.THRESHOLD} in every test "
                "(no degradation to extrapolate)", math.nan, math.nan)
    t_thr = t[0] + res.t_threshold_s * DAY_S
    if math.isnan(res.t_warning_s):
        return (math.nan, nan2, f"n/a: below the threshold {R.THRESHOLD} since "
                f"{_date(t_thr)}, not yet below the warning level {R.WARNING} (the thesis "
                "predicts from the warning crossing)", t_thr, math.nan)
    t_warn = t[0] + res.t_warning_s * DAY_S
    if res.prediction is None:
        return (math.nan, nan2, "n/a: fewer than 5 tests between the threshold and "
                "warning crossings (a cubic needs them)", t_thr, t_warn)
    p = res.prediction
    lo, hi = p.band()
    return (p.rul_s, (max(lo - p.t_pred_s, 0.0), hi - p.t_pred_s), "", t_thr, t_warn)


def _date(t_s: float) -> str:
    return dt.datetime.fromtimestamp(t_s, dt.UTC).strftime("%Y-%m-%d")


def fleet_status(store: Any, n_trend: int = N_TREND, as_of: float | None = None
                 ) -> list[ActuatorStatus]:
    """Every actuator's status, by actuator id; with `as_of` (epoch seconds) as it was
    then: only the tests up to and including `as_of` count (an actuator with none is
    left out)."""
    return status_of_series(store.series(SERIES_COLUMNS), n_trend, as_of)


SERIES_COLUMNS = ("ci", "ci_harmonic", "verdict", "life_consumed", "reasons")
"""The columns `status_of_series` needs from `Store.series`."""


def status_of_series(s: dict[str, Any], n_trend: int = N_TREND, as_of: float | None = None
                     ) -> list[ActuatorStatus]:
    """`fleet_status` on columns already fetched (`Store.series(SERIES_COLUMNS)`), so
    that a study can ask for the status as of many dates with one query."""
    ids = np.asarray(s["actuator_id"], dtype=object)
    t_all = np.asarray(s["run_time"], dtype=float)
    keep = np.ones(len(ids), dtype=bool) if as_of is None else t_all <= as_of
    ids, t_all = ids[keep], t_all[keep]
    if not len(ids):
        return []
    ci_all = judged_ci(floats(s["ci"]), floats(s["ci_harmonic"]))[keep]
    life_all = floats(s["life_consumed"])[keep]
    verdicts = np.asarray(s["verdict"], dtype=object)[keep]
    reasons = np.asarray(s["reasons"], dtype=object)[keep]
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], len(ids)]
    out = []
    for a, b in zip(starts, ends, strict=True):
        t, ci = t_all[a:b], ci_all[a:b]
        life = life_all[a:b]
        rul, band, why, t_thr, t_warn = rul_of(t, ci)
        out.append(ActuatorStatus(
            str(ids[a]), int(b - a), float(t[-1]), stored_level(verdicts[b - 1]).name,
            float(ci[-1]), slope_per_day(t, ci, n_trend), rul, band, why,
            float(np.nansum(life)) if np.isfinite(life).any() else math.nan,
            str(reasons[b - 1] or ""), t_thr, t_warn))
    return out


def stored_level(value: Any) -> Level:
    """The level of a stored run (`Level.parse`: a name, a code, NULL for UNKNOWN, as
    every schema version stored it); BenchError naming the value when it is none."""
    try:
        return Level.parse(value)
    except ValueError:
        raise BenchError(f"the fleet store holds a run whose verdict is not a level: "
                         f"{value!r}") from None


def parse_as_of(text: str) -> float:
    """`--as-of`: an ISO 8601 time (UTC unless it says otherwise) as epoch seconds; a
    date alone is the end of that day (its tests count)."""
    try:
        if len(text) == 10:
            day = dt.datetime.strptime(text, "%Y-%m-%d").replace(tzinfo=dt.UTC)
            return (day + dt.timedelta(days=1)).timestamp() - 1e-6
        t = dt.datetime.fromisoformat(text)
    except ValueError:
        raise BenchError(f"--as-of: not a date or ISO 8601 time: {text!r}") from None
    except OverflowError:                  # the day after 9999-12-31
        raise BenchError(f"--as-of: {text}: beyond the last date a store holds "
                         "(9999-12-30)") from None
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.UTC)
    return t.timestamp()


def floats(col: Any) -> np.ndarray:
    """A fetched column (masked where NULL) as floats with NaN for NULL."""
    if isinstance(col, np.ma.MaskedArray):
        return np.asarray(np.ma.filled(col.astype(float), np.nan), dtype=float)
    return np.asarray(col, dtype=float)


def urgency(st: ActuatorStatus) -> tuple[float, float, float]:
    """Sort key, most urgent first: level of the last test, then RUL, then Ci falling."""
    rul = st.rul_days if math.isfinite(st.rul_days) else math.inf
    slope = st.slope_per_day if math.isfinite(st.slope_per_day) else 0.0
    return (-st.level, rul, slope)


def rul_text(st: ActuatorStatus) -> str:
    if not math.isfinite(st.rul_days) or st.rul_days == 0.0 and st.rul_why:
        return st.rul_why or "n/a"
    lo, hi = st.rul_band_days
    return f"{st.rul_days:.1f} d [{lo:.1f}, {hi:.1f}]"


def usage_text(st: ActuatorStatus) -> str:
    """The usage consumed, as the sum over the logged runs it is."""
    if not math.isfinite(st.life_consumed):
        return "n/a (no run with a load signal)"
    return f"{100.0 * st.life_consumed:.3g} % of L10 in the logged runs"


USAGE_NOTE_BELOW = 1e-6
"""L10 life consumed (fraction) below which a WARNING or FAILURE actuator's usage is ~0:
its wear did not come from the logged runs (`usage_note`)."""


def usage_note(rows: list[ActuatorStatus]) -> str:
    """What ~0 % of L10 next to WARNING or FAILURE means ("" when no line shows it): the
    usage sums the logged runs only. In a synthetic fleet those are unloaded ground
    tests, and the wear comes from flights that are not logged, one synthetic day
    standing for many real ones (the time compression of `bench.fleet.synth`)."""
    odd = [st.ident for st in rows if st.level >= 2 and math.isfinite(st.life_consumed)
           and st.life_consumed < USAGE_NOTE_BELOW]
    if not odd:
        return ""
    names = ", ".join(odd[:5]) + (f" and {len(odd) - 5} more" if len(odd) > 5 else "")
    return (f"note: {names}: WARNING or FAILURE with ~0 % of L10 used. The usage column "
            "sums the logged runs only, and this wear did not come from them. In a "
            "synthetic fleet (`bench fleet synth`) the logs are unloaded ground tests and "
            "the wear comes from flights that are not logged, each synthetic day standing "
            "for many real ones (the time compression K in fleet-truth.json, docs/fleet.md); "
            "on a real fleet, log the flights' load for the usage to count them.")


HEADER = ("actuator", "tests", "last test (UTC)", "level", "Ci", "trend Ci/day",
          "RUL [90 % band]", "usage consumed")


def format_table(rows: list[ActuatorStatus]) -> str:
    """The status lines, one per actuator, with a header."""
    from bench.core.filenames import one_line
    body = [(one_line(st.ident), str(st.tests),
             dt.datetime.fromtimestamp(st.last_time_s, dt.UTC).strftime(
                 "%Y-%m-%d %H:%M"), st.verdict,
             "-" if not math.isfinite(st.ci_last) else f"{st.ci_last:.3f}",
             "-" if not math.isfinite(st.slope_per_day) else f"{st.slope_per_day:+.4f}",
             rul_text(st), usage_text(st)) for st in rows]
    widths = [max(len(r[k]) for r in [HEADER, *body]) for k in range(len(HEADER) - 2)]
    lines = []
    for r in [HEADER, *body]:
        lines.append("  ".join(c.ljust(w) for c, w in zip(r[:-2], widths, strict=True))
                     + "  " + r[-2] + "  |  " + r[-1])
    note = usage_note(rows)
    return "\n".join(lines + (textwrap.wrap(note, 100) if note else []))
