"""Named nominal models ("sim" in sim-to-real) the diagnosis compares a log against.

    plant     the high-fidelity plant of chapter 5 at nominal (or calibrated) parameters,
              fitted in its fast mode (averaged PWM, massless balls), with the fast
              mode's own error against full fidelity counted in the noise floor
    monitor   the HUMS monitoring model of eq. 6.1-6.2 (bench.hums.monitor, issue 4):
              rigid screw, no PWM; it reads the plant parameters it models (motor,
              reducer, friction tables, lead, sensor dynamics), so candidate effects acting
              through other parameters (backlash, preload, stiffness, friction scale,
              sensor gains/offsets/delay) do not change it and are skipped

A model is looked up lazily by name (name -> (module, attribute)) so a model whose
module is missing only fails when it is asked for, with a clear message.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from bench import BenchError

MODELS: dict[str, tuple[str, str]] = {
    "plant": ("bench.gap.resim", "closed_loop"),
    "monitor": ("bench.hums.monitor", "closed_loop"),
}


def check_model(name: str) -> Callable[..., Any]:
    """The model's re-simulation callable ``closed_loop(params, drive, n=None, noise=None)``
    returning logged-style columns; BenchError when unknown or not available."""
    try:
        module, attr = MODELS[name]
    except KeyError:
        raise BenchError(f"unknown model {name!r} (choose from {', '.join(MODELS)})") from None
    try:
        mod = importlib.import_module(module)
        fn = getattr(mod, attr)
    except (ImportError, AttributeError):
        raise BenchError(
            f"model {name!r} is not available: it needs {module}.{attr}(params, drive, n, "
            f"noise) -> logged columns (the monitoring model comes with the HUMS, issue 4); "
            f"use --model plant") from None
    return fn


_FN: dict[str, Callable[..., Any]] = {}


def closed_loop_of(name: str) -> Callable[..., Any]:
    """The (cached) re-simulation callable of model `name`."""
    if name not in _FN:
        _FN[name] = check_model(name)
    return _FN[name]
