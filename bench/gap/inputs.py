"""Reading what the gap commands are given: logs, traces and nominal parameter files.

- ``*.log`` (candump log format): decoded through the DBC by
  `bench.bus.logs.trace_from_log` (the bus's log decoder);
- ``*.npz`` / ``*.csv`` / ``*.parquet``: a `bench.signals.trace.Trace` file (e.g. from
  `bench import` or a saved run).
Both through the one log loader, `bench.bus.logs.load_trace`: only measured columns are
kept (simulation truth is dropped), and metadata is reduced to what a real log could
carry (the command fundamental, if recorded) and what the decoder or the importer found
missing or repeated in it (`bench.bus.logs.LOG_INTEGRITY`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench import BenchError
from bench.signals.trace import Trace
from plant_rt.params import ParameterError, PlantParams

BASELINE_FORMAT = "bench-rig-baseline/1"
"""The format tag of a healthy baseline file (`bench.rig.baseline` writes and checks it):
defined here, below the rig, so `read_nominal` tells a baseline given as --nominal apart
without importing the rig (which imports this package)."""


class BaselineAsNominal(BenchError):
    """A healthy baseline file given where a calibration or parameter file goes."""


CALIBRATION_KINDS = {
    "plant": "the thesis plant's uncertain parameters fitted to a healthy log (`bench "
             "calibrate`): {\"params\": {dotted name: value}, ...}",
    "actuator": "another actuator's generic nut-level model fitted to healthy logs "
                "(`bench calibrate --actuator`): its description and values",
}
"""What a calibration file calibrates, by its ``kind`` field."""


@dataclass(frozen=True)
class Calibration:
    """A calibration file's object (`doc`) and its `kind` (CALIBRATION_KINDS). A file
    written before calibrations said their kind is told by its content: a generic
    model's ``model`` name is an actuator's, a ``params`` object the plant's."""
    kind: str
    doc: dict[str, Any]

    @classmethod
    def of(cls, data: Any, path: str | Path = "calibration") -> Calibration | None:
        """The calibration `data` is, None for another object (a parameter file); a
        one-line BenchError for an unknown kind."""
        if not isinstance(data, dict):
            return None
        kind = data.get("kind")
        if kind is None:
            if str(data.get("model", "")).startswith("generic"):
                kind = "actuator"
            elif isinstance(data.get("params"), dict):
                kind = "plant"
            else:
                return None
        if kind not in CALIBRATION_KINDS:
            raise BenchError(f"{path}: unknown calibration kind {kind!r} (known: "
                             f"{', '.join(CALIBRATION_KINDS)})")
        return cls(str(kind), data)

    def to_dict(self) -> dict[str, Any]:
        """The file's object, its kind first."""
        return {"kind": self.kind, **{k: v for k, v in self.doc.items() if k != "kind"}}


def load_log(path: str | Path) -> Trace:
    """A log or trace file as a Trace of measured columns (`bench.bus.logs.load_trace`,
    the one log loader, with ``measured``); BenchError if unreadable."""
    from bench.bus.logs import load_trace
    return load_trace(path, measured=True)


def read_nominal(path: str | Path) -> dict[str, Any]:
    """The JSON object of a --nominal file (a calibration or a parameter JSON), read
    once; a missing file, bad JSON or another JSON value is a one-line BenchError."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"no such file: {path}")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise BenchError(f"{path}: not valid JSON ({exc})") from None
    except RecursionError:
        raise BenchError(f"{path}: not a calibration or parameter JSON (nested too deep "
                         "to read)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BenchError(f"{path}: cannot be read ({exc})") from None
    if not isinstance(data, dict):
        raise BenchError(f"{path}: expected a JSON object")
    if not data:
        raise BenchError(f"{path}: an empty JSON object holds no parameter: give a "
                         "calibration (bench calibrate) or a parameter file, or leave "
                         "--nominal out for the thesis values")
    if data.get("format") == BASELINE_FORMAT:
        raise BaselineAsNominal(f"{path}: a healthy baseline (bench rig baseline), not a "
                                f"calibration or parameter file: bench gap and bench hums "
                                f"report take it with --baseline {path}")
    return data


def nominal_params(data: dict[str, Any], path: str | Path) -> PlantParams:
    """The parameters of a --nominal file's object (`read_nominal`): a calibration's
    {"params": {dotted name: value}} on the thesis values, or a full parameter JSON."""
    try:
        cal = Calibration.of(data, path)
        if cal is not None and cal.kind == "plant":
            return PlantParams().with_dict(data["params"])
        return PlantParams.from_dict(data)
    except ParameterError as exc:
        raise BenchError(f"{path}: {exc}") from None


def load_nominal(path: str | Path | None) -> PlantParams:
    """The nominal parameters: thesis values, or a calibration file from `bench calibrate`
    ({"params": {dotted name: value}, ...}), or a full parameter JSON."""
    if path is None:
        return PlantParams()
    return nominal_params(read_nominal(path), path)
