"""Rating life of the ball screw (ISO 3408-5, Lundberg-Palmgren) and the life consumed
(Palmgren-Miner), from the axial load and the screw revolutions made under it.

- Basic rating life at a constant axial load F: L10 = (C_a / F)^3 x 10^6 revolutions
  (90 % reliability; ISO 3408-5; the thesis, section 2.1, defines C_a by the 10^6).
- A varying load is reduced to the equivalent dynamic axial load, the cubic mean over
  revolutions: F_m = (sum |F_i|^3 n_i / sum n_i)^(1/3) (ISO 3408-5).
- Life consumed (Palmgren-Miner): D = sum n_i / L10(F_i) = sum n_i |F_i|^3 / (C_a^3 10^6),
  which is n / L10(F_m) exactly by the definition of F_m. D = 1: the rating life is used.

Preload (`preload_mode` "double-nut", docs/usage.md): in a preloaded double nut both nuts
carry the preload F_pr and an external load F shifts it from one nut to the other until,
at |F| = 2^1.5 F_pr = 2.83 F_pr, the relieved nut is free (Hertzian contacts, deflection
~ F^(2/3)). Manufacturers' rule (Steinmeyer, 'Equivalent load: considering the preload
with double nuts'):
F_1 = F_pr (1 + F / (2.83 F_pr))^1.5 and F_2 = F_pr (1 - F / (2.83 F_pr))^1.5 for
|F| < 2.83 F_pr; beyond it the loaded nut carries F and the other none. Each nut gets its
own Miner sum D_j with the nut's rating C_a; the pair's life follows the system rule of
rolling bearings, L = (L_1^(-10/9) + L_2^(-10/9))^(-9/10), so
D = (D_1^(10/9) + D_2^(10/9))^(9/10). Sign: positive F (the load cell's sign: pushes the nut
towards negative positions) loads nut 1. With F_pr = 0 each direction loads one nut.
"""

from __future__ import annotations

import math

import numpy as np

RATED_REVOLUTIONS = 1e6
RELEASE_RATIO = 2.0 ** 1.5      # 2.83: the external load that frees the relieved nut
SYSTEM_EXPONENT = 10.0 / 9.0    # life of two rolling contacts in series


def nut_loads(force_n: np.ndarray, preload_n: float) -> tuple[np.ndarray, np.ndarray]:
    """Axial loads of nut 1 and nut 2 of a preloaded double nut under external load F."""
    f = np.asarray(force_n, dtype=float)
    if preload_n <= 0.0:
        return np.maximum(f, 0.0), np.maximum(-f, 0.0)
    u = f / (RELEASE_RATIO * preload_n)
    inside = np.abs(u) < 1.0
    f1 = np.where(inside, preload_n * np.clip(1.0 + u, 0.0, None) ** 1.5, np.maximum(f, 0.0))
    f2 = np.where(inside, preload_n * np.clip(1.0 - u, 0.0, None) ** 1.5, np.maximum(-f, 0.0))
    return f1, f2


def rating_life_rev(ca_n: float, fm_n: float) -> float:
    """L10 = (C_a / F_m)^3 x 10^6 revolutions; inf without load."""
    if not fm_n > 0.0:
        return math.inf
    return (ca_n / fm_n) ** 3 * RATED_REVOLUTIONS


def damage(revs: np.ndarray, load_n: np.ndarray, ca_n: float) -> float:
    """Palmgren-Miner sum of revolutions `revs` made under loads `load_n`."""
    return float(np.sum(np.abs(revs) * np.abs(load_n) ** 3)) / (ca_n ** 3 * RATED_REVOLUTIONS)


def system_damage(d1: float, d2: float) -> float:
    """Life consumed of the two nuts together: (D_1^(10/9) + D_2^(10/9))^(9/10)."""
    return (d1 ** SYSTEM_EXPONENT + d2 ** SYSTEM_EXPONENT) ** (1.0 / SYSTEM_EXPONENT)


def equivalent_load_n(cube_sum: float, revs: float) -> float:
    """F_m from sum |F|^3 n and sum n (NaN without revolutions)."""
    return (cube_sum / revs) ** (1.0 / 3.0) if revs > 0.0 else math.nan
