"""Named nominal models ("sim" in sim-to-real) the diagnosis compares a log against.

    plant     the high-fidelity plant of chapter 5 at nominal (or calibrated) parameters,
              fitted in its fast mode (averaged PWM, massless balls), with the fast
              mode's own error against full fidelity counted in the noise floor
    monitor   the HUMS monitoring model of eq. 6.1-6.2 (bench.hums.monitor): rigid
              screw, no PWM; it reads the plant parameters it models (motor, reducer,
              friction tables, lead, sensor dynamics), so candidate effects acting
              through other parameters (backlash, preload, stiffness, friction scale,
              sensor gains/offsets/delay) do not change it and are skipped

Each is a re-simulation callable ``closed_loop(params, drive, n=None, noise=None)``
returning logged-style columns.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bench import BenchError
from bench.gap import resim
from bench.hums import monitor

MODELS: dict[str, Callable[..., Any]] = {
    "plant": resim.closed_loop,
    "monitor": monitor.closed_loop,
}


def check_model(name: str) -> Callable[..., Any]:
    """The model's re-simulation callable; BenchError when `name` is unknown."""
    try:
        return MODELS[name]
    except KeyError:
        raise BenchError(f"unknown model {name!r} (choose from {', '.join(MODELS)})") from None


def closed_loop_of(name: str) -> Callable[..., Any]:
    """The re-simulation callable of model `name` (as `check_model`)."""
    return check_model(name)
