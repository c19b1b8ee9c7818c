"""The ball contacts' stiffness as the kernel uses it, under either reading of k*.

Plain Python (no numba): `plant_rt.model` builds the kernel's parameters from it and
`plant_rt.wear` maps wear depth to preload through it.

The kernel represents each nut by one ball standing for Z (`screw.balls_active`) equal
balls, each with two contacts in series along the contact normal, k = k* + m F_pr
(eq. 5.21); the normal makes g = cos(alpha) sin(beta) with the axis (eq. 5.26). The two
nuts act in parallel, so the axial stiffness is 2 Z (k/2) g^2 = Z k g^2.

- ``screw.stiffness_reading = contact``: k* (`screw.contact_stiffness_n_per_m`) is the
  stiffness of one contact, as printed: axial stiffness Z k* g^2 (1,047 N/um).
- ``axial``: k* is the screw's axial stiffness without preload (100 N/um, section 5.6.2),
  shared by the N = circuits x Z balls of eq. 5.11 and table 5.4 (6 x 21 = 126, both nuts),
  each with two contacts in series along the normal: N (k_c/2) g^2 = k*, so
  k_c = 2 k* / (N g^2) per real contact. The kernel's ball stands for N/2 real balls per
  nut, so its contact carries (N / (2 Z)) (k_c + m F_pr): the axial stiffness is k*, and
  the relative gain from preload, m F_pr / k_c, does not depend on how balls are lumped.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from plant_rt.params import PlantParams


def normal_to_axis(params: PlantParams) -> float:
    """g = cos(alpha) sin(beta): contact-normal motion per unit of axial motion (eq. 5.26)."""
    s = params.screw
    return math.cos(math.radians(s.helix_angle_deg)) * math.sin(
        math.radians(s.contact_angle_deg))


def real_contact_stiffness(params: PlantParams) -> float:
    """k_c (N/m), the stiffness of one real ball contact without preload."""
    s = params.screw
    if s.stiffness_reading == "contact":
        return s.contact_stiffness_n_per_m
    g = normal_to_axis(params)
    return 2.0 * s.contact_stiffness_n_per_m / (s.circuits * s.balls_active * g * g)


def contact_geometry(params: PlantParams) -> tuple[float, float, float, float]:
    """(k*, m, Z, g) of the kernel's lumped contact: k = k* + m F_pr (eq. 5.21) per
    kernel contact, Z balls per nut, g = cos(alpha) sin(beta)."""
    s = params.screw
    g = normal_to_axis(params)
    if s.stiffness_reading == "contact":
        return s.contact_stiffness_n_per_m, s.stiffness_preload_slope_per_m, \
            float(s.balls_active), g
    lump = s.circuits / 2.0           # real balls per nut / Z: N / (2 Z) with N = circuits Z
    kc = real_contact_stiffness(params)
    return lump * kc, lump * s.stiffness_preload_slope_per_m, float(s.balls_active), g


def axial_stiffness(params: PlantParams, preload_n: float = 0.0) -> float:
    """The double nut's axial stiffness (N/m) at preload `preload_n`, both nuts carrying
    (the plant's linear, two-sided contacts): Z (k* + m F_pr) g^2."""
    kstar, m, z, g = contact_geometry(params)
    return z * (kstar + m * preload_n) * g * g
