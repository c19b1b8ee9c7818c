"""Candidate effects by name: the registry the diagnosis, the CLI and the benchmark use.

``EFFECTS`` maps an effect's name to what makes it: the built-in effects' classes, taken
from `bench.gap.library` (the one place they are listed), and the loaders of effects
added with ``register(name, module, cls)`` (project- or user-specific ones, imported only
when first used, as python-can's interface table). `Param` and `Effect` (what an effect
is) live in `bench.gap.candidate` and are re-exported here.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from bench import BenchError
from bench.gap.candidate import Effect, Param
from bench.gap.library import BUILTIN
from bench.gap.sensors import BUILTIN as SENSOR_BUILTIN

EFFECTS: dict[str, Callable[[], object]] = {cls.name: cls for cls in BUILTIN + SENSOR_BUILTIN}
_CACHE: dict[str, Effect] = {}


def _loader(module: str, cls: str) -> Callable[[], object]:
    def load() -> object:
        return getattr(importlib.import_module(module), cls)()
    load.__qualname__ = f"{module}.{cls}"
    return load


def register(name: str, module: str, cls: str) -> None:
    """Add (or replace) a candidate effect: `module`.`cls` must subclass `Effect`; it is
    imported when the effect is first used."""
    EFFECTS[name] = _loader(module, cls)
    _CACHE.pop(name, None)


def names() -> list[str]:
    return list(EFFECTS)


def get(name: str) -> Effect:
    """The effect called `name` (BenchError naming the known ones if none)."""
    if name in _CACHE:
        return _CACHE[name]
    try:
        make = EFFECTS[name]
    except KeyError:
        raise BenchError(f"unknown effect {name!r} (known: {', '.join(EFFECTS)})") from None
    what = getattr(make, "__qualname__", repr(make))
    try:
        obj = make()
    except (ImportError, AttributeError, TypeError) as exc:
        raise BenchError(f"effect {name!r} cannot be loaded from {what}: {exc}") from None
    if not isinstance(obj, Effect):
        raise BenchError(f"effect {name!r}: {what} is not a bench.gap Effect")
    _CACHE[name] = obj
    return obj


def parse_list(text: str | None) -> list[str]:
    """``"a,b,c"`` -> validated effect names (all known effects when empty/None)."""
    if not text:
        return names()
    out = []
    for part in text.split(","):
        part = part.strip()
        if part:
            get(part)
            if part not in out:
                out.append(part)
    if not out:
        raise BenchError("--effects lists no effect")
    return out


__all__ = ["EFFECTS", "Effect", "Param", "get", "names", "parse_list", "register"]
