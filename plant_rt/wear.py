"""Use-driven wear of the ball tracks (Archard), as pure functions.

Archard's law (J. F. Archard, "Contact and rubbing of flat surfaces", J. Appl. Phys. 24,
981-988, 1953): the worn volume is

    V = k F_N s / H

with k the dimensionless wear coefficient, F_N the normal contact load, s the sliding
(here: rolling, with its micro-slip absorbed into k) distance and H the hardness of the
softer surface. The plant accumulates V over every sub-step in its state
(`plant_rt.kernel`, state ``WEAR_V``); this module holds the laws and the mapping from
the worn volume to what the plant's chapter 5 model can express: preload loss, backlash
and a friction scale (`wear_to_effects`; the reasoning is in docs/model.md, "Wear").

Everything here is plain Python (math, numpy for the seeded draw): importing it brings in
no numba. `plant_rt.kernel` compiles `effects_from_depth` for its use.

Geometry of the plant's double nut (eq. 5.19-5.29), used throughout: each nut is Z balls,
each ball with two contacts in series (screw-ball, ball-nut) of stiffness k = k* + m F_pr
(eq. 5.21) along the contact normal; the normal makes the factor g = cos(alpha) sin(beta)
with the screw axis (eq. 5.26). ``kstar`` and ``mslope`` below are the kernel's per-contact
values (`plant_rt.contacts.contact_geometry`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from plant_rt.contacts import contact_geometry, helix_rad

if TYPE_CHECKING:
    from plant_rt.params import PlantParams

# the seed stream of the wear coefficient (separate from the sensor and gust streams)
COEFF_STREAM = 12


def wear_rate(k: float, contact_load_n: float, rolling_speed_m_s: float,
              hardness_pa: float) -> float:
    """Worn volume rate dV/dt (m^3/s) = k F_N |v| / H (Archard 1953)."""
    return k * abs(contact_load_n) * abs(rolling_speed_m_s) / hardness_pa


def draw_coefficient(median: float, log_std: float, seed: int) -> float:
    """One actuator's Archard coefficient: log-normal, ln k ~ N(ln median, log_std^2),
    drawn from its own seeded stream (the population spread of wear rates)."""
    if median <= 0.0:
        return 0.0
    z = float(np.random.default_rng([int(seed), COEFF_STREAM]).standard_normal())
    return median * math.exp(log_std * z)


def coefficient(params: PlantParams) -> float:
    """The actuator's effective k: its draw times the time compression
    (`wear.acceleration`). Plant truth: the HUMS never reads it."""
    w = params.wear
    return draw_coefficient(w.coefficient_median, w.coefficient_log_std, w.seed) \
        * w.acceleration


def rolling_distance_per_rad(params: PlantParams) -> float:
    """Rolling distance of each contact along its raceway per radian of screw rotation
    (m/rad): the ball centre travels the helix of radius r_m (length r_m / cos alpha per
    radian) at half the screw's relative speed, as the cage of a rolling bearing does."""
    s = params.screw
    return 0.5 * s.nominal_radius_m / math.cos(helix_rad(s))


def kernel_wear_gain(params: PlantParams) -> float:
    """The kernel's factor: dV = gain * (sum over the four contact forces of one ball
    pair, N) * |screw speed| * dt, i.e. Z k / H times the rolling distance per radian;
    0 unless `wear.kind = archard`."""
    if params.wear.kind != "archard":
        return 0.0
    return (params.screw.balls_active * coefficient(params) / params.wear.hardness_pa
            * rolling_distance_per_rad(params))


def interference_from_preload(preload_n: float, kstar: float, mslope: float, z: float,
                              g: float) -> float:
    """Axial interference (m) between the two nuts that holds `preload_n`: each nut's
    contacts (Z balls, two contacts of k = k* + m F in series, along the normal) compress
    by F / (Z (k/2) g) along the normal, F / (Z (k/2) g^2) axially (eq. 5.21, 5.26)."""
    if preload_n <= 0.0:
        return 0.0
    k = kstar + mslope * preload_n
    return 4.0 * preload_n / (z * k * g * g)


def preload_from_interference(delta_m: float, kstar: float, mslope: float, z: float,
                              g: float) -> float:
    """Inverse of `interference_from_preload`: F = d Z g^2 k* / (4 - d Z g^2 m), 0 for
    no interference."""
    if delta_m <= 0.0:
        return 0.0
    a = delta_m * z * g * g
    den = 4.0 - a * mslope
    if den <= 1e-12:      # the linear law of eq. 5.21 runs away: cap at a large preload
        den = 1e-12
    return a * kstar / den


def effects_from_depth(depth_m: float, preload0_n: float, kstar: float, mslope: float,
                       z: float, g: float, friction_per_m: float) -> tuple[float, float,
                                                                         float]:
    """(preload loss N, backlash m along the contact normal, friction scale) for a wear
    depth `depth_m` at every contact of a double nut preloaded to `preload0_n` when new.

    Each nut's chain (screw-ball-nut) loses 2 depth along the normal, 2 depth / g axially;
    the two nuts 4 depth / g of the preload interference. While interference remains, the
    preload is what it holds (`preload_from_interference`); past it, the gap opens: the
    axial clearance 4 depth / g - interference is lost motion b / g of the plant's
    backlash b (eq. 5.19-5.24). Friction grows linearly with depth (pitting and debris).
    """
    if depth_m <= 0.0:
        return 0.0, 0.0, 1.0
    d = depth_m
    # self-contained (plant_rt.kernel compiles it): `interference_from_preload`, then
    # `preload_from_interference` written out
    delta0 = 0.0
    if preload0_n > 0.0:
        delta0 = 4.0 * preload0_n / (z * (kstar + mslope * preload0_n) * g * g)
    delta = delta0 - 4.0 * d / g
    if delta > 0.0:
        a = delta * z * g * g
        den = 4.0 - a * mslope
        if den <= 1e-12:
            den = 1e-12
        remaining = a * kstar / den
        backlash = 0.0
    else:
        remaining = 0.0
        backlash = -delta * g
    loss = preload0_n - remaining
    if loss < 0.0:
        loss = 0.0
    return loss, backlash, 1.0 + friction_per_m * d


def depth_from_volume(volume_m3: float, params: PlantParams) -> float:
    """Mean wear depth (m) at each contact: the worn volume over the track area."""
    return volume_m3 / params.wear.track_area_m2


def wear_to_effects(volume_m3: float, params: PlantParams) -> tuple[float, float, float]:
    """(preload_loss_n, backlash_m, friction_scale) of a worn volume `volume_m3` for the
    actuator of `params`, new at `effects.preload_n`: the preload lost, the backlash
    added along the contact normal, and the factor on the friction (docs/model.md)."""
    kstar, mslope, z, g = contact_geometry(params)
    return effects_from_depth(depth_from_volume(volume_m3, params), params.effects.preload_n,
                              kstar, mslope, z, g, params.wear.friction_per_depth_per_m)


def volume_for_backlash(backlash_m: float, params: PlantParams) -> float:
    """The worn volume (m^3) at which wear has opened `backlash_m` of backlash (the inverse
    of `wear_to_effects` past the preload): for end-of-life thresholds and tests."""
    kstar, mslope, z, g = contact_geometry(params)
    delta0 = interference_from_preload(params.effects.preload_n, kstar, mslope, z, g)
    depth = (backlash_m / g + delta0) * g / 4.0
    return depth * params.wear.track_area_m2
