"""Usage monitoring, the "U" of HUMS (docs/usage.md): from a trace or a log, per run, and
accumulated per actuator; live through `bench hums watch`.

    from bench.usage import usage_of_trace, accumulate
    s = usage_of_trace(trace)          # UsageSummary: s.as_dict() flat floats
    per_actuator = accumulate([s1, s2, ...])

One module per job: `settings` (hystereses, regimes, preload option, fixed bins),
`tracker` (play operator and turning points with hysteresis), `hysteresis` (each
counter's hysteresis on a log: its setting or ten times the log's noise, and why), `life`
(ISO 3408-5 rating life, Palmgren-Miner, the double nut's preload), `accumulator` (rows
in, usage out), `summary` (`UsageSummary`, `accumulate`), `table` (text), `figure` (PNG),
`online` (the live watcher's per-run usage).
"""

from bench.usage.accumulator import Geometry, UsageAccumulator, usage_of_trace
from bench.usage.settings import UsageSettings
from bench.usage.summary import UNKNOWN, UsageSummary, accumulate

__all__ = ["UNKNOWN", "Geometry", "UsageAccumulator", "UsageSettings", "UsageSummary",
           "accumulate", "usage_of_trace"]
