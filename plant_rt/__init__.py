"""The EMA actuator plant of thesis chapter 5, as a model API and as a CANopen node.

`plant_rt.params` holds the parameter sets (tables 5.1-5.4), `plant_rt.kernel` the
compiled fixed-step core, `plant_rt.model.Plant` the one-SYNC-period step used by both
the live node (`python -m plant_rt`) and offline studies. This package imports the bus
contract (`ema_contract`) and never `bench`.

The names below are resolved on first use (PEP 562), so `import plant_rt.params` (the
ECU, the log decoder) does not compile or even import numba.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ema_contract.states import Status
    from plant_rt.model import Measurement, Plant
    from plant_rt.params import ParameterError, PlantParams

# public name -> module that defines it
_LAZY = {
    "Plant": "plant_rt.model",
    "Measurement": "plant_rt.model",
    "Status": "ema_contract.states",
    "PlantParams": "plant_rt.params",
    "ParameterError": "plant_rt.params",
}

__all__ = ["Plant", "PlantParams", "ParameterError", "Measurement", "Status"]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
