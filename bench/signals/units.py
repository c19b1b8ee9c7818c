"""The units a rig's table, map or baseline may give a quantity in, and their factor to
SI (value_SI = value x factor): the one table `bench import`'s column maps, the rig's
load units (`bench rig baseline --load-unit`) and the load matching of `bench gap`
against a baseline read. A kilogram-force is the standard 9.80665 N, a pound-force
0.45359237 kg x 9.80665 m/s^2.
"""

from __future__ import annotations

import math

FORCE: dict[str, float] = {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605, "kgf": 9.80665}
"""Force units -> newtons."""

UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0},
    "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "in": 0.0254},
    "speed": {"rad/s": 1.0, "rpm": 2 * math.pi / 60, "deg/s": math.pi / 180,
              "rev/s": 2 * math.pi},
    "angle": {"rad": 1.0, "deg": math.pi / 180, "rev": 2 * math.pi},
    "current": {"A": 1.0, "mA": 1e-3},
    "force": FORCE,
    "mode": {"-": 1.0, "": 1.0},
}
"""Quantity -> unit -> factor to the SI unit (the first of each)."""


def convert(value: float, unit: str, target: str, quantity: str = "force") -> float:
    """`value` in `unit` expressed in `target` (both of `quantity`); unchanged when the
    two are the same or either is not a unit of that quantity."""
    table = UNITS[quantity]
    if unit == target or unit not in table or target not in table:
        return value
    return value * table[unit] / table[target]


def summary() -> str:
    """The units per quantity in a few words, for a command's help:
    ``time s/ms/us/ns/min, length m/mm/um/in, ...``."""
    return ", ".join(f"{q} {'/'.join(u for u in us if u)}" for q, us in UNITS.items())
