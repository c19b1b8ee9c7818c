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
    from plant_rt.params import PlantParams, ScrewParams


def helix_rad(s: ScrewParams) -> float:
    """The helix angle alpha (rad) at the screw's lead: `helix_angle_deg` at
    `helix_reference_lead_m`; at another lead on the same screw radius tan alpha scales with
    the lead (tan alpha = p / 2 pi r_m), so that the reaction lever of eq. 5.10 and 5.15,
    the torque an axial force needs, follows a lead change as the kinematics do (eq. 5.26).
    A reference lead of 0 (the default, the thesis' model) keeps alpha whatever the lead."""
    alpha = math.radians(s.helix_angle_deg)
    ref = s.helix_reference_lead_m
    if ref <= 0.0 or s.lead_m == ref:
        return alpha
    return math.atan(math.tan(alpha) * s.lead_m / ref)


def normal_to_axis(params: PlantParams) -> float:
    """g = cos(alpha) sin(beta): contact-normal motion per unit of axial motion (eq. 5.26)."""
    s = params.screw
    return math.cos(helix_rad(s)) * math.sin(math.radians(s.contact_angle_deg))


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


# --- a Hertzian preloaded double nut (off unless screw.hertz_reference_preload_n > 0) ----
# Plain math only: `plant_rt.kernel` compiles `hertz_share` with njit for its sub-step
# (the word keeps this file in `plant_rt.jit`'s cache key) and mirrors the ratio.
HERTZ_NEWTON_STEPS = 8
HERTZ_MIN_PRELOAD_FRAC = 1e-3
"""The preload the law uses is at least this fraction of the reference (at zero preload
and zero load a Hertzian contact has no stiffness; the floor keeps 10 % of it)."""


def hertz_share(q: float) -> float:
    """s = delta / d0 of a Hertzian double nut (each half F = k_H d^1.5, both preloaded
    to d0 = (F_pr / k_H)^(2/3)) under the axial load q = |F| / F_pr: while both halves
    carry, (1 + s)^1.5 - (1 - s)^1.5 = q (Newton from s = q / 3, below the root of this
    concave function, so it converges monotonically); beyond lift-off (q >= 2^1.5) the
    unloaded half carries nothing and (1 + s)^1.5 = q."""
    if q >= 2.0 * math.sqrt(2.0):
        return q ** (2.0 / 3.0) - 1.0
    s = q / 3.0
    for _ in range(HERTZ_NEWTON_STEPS):
        a = math.sqrt(1.0 + s)
        b = math.sqrt(max(1.0 - s, 0.0))
        s += (q - (1.0 + s) * a + (1.0 - s) * b) / (1.5 * (a + b))
        if s > 1.0:
            s = 1.0
    return s


def hertz_stiffness_ratio(f_axial: float, preload_n: float, ref_n: float) -> float:
    """The double nut's secant axial stiffness |F| / delta at load F and preload F_pr over
    the same at the reference preload F_ref (Hertz: delta = d0 s(|F| / F_pr), d0 ~
    F_pr^(2/3)): (F_ref / F_pr)^(2/3) s(|F| / F_ref) / s(|F| / F_pr); at small loads
    the tangent ratio (F_pr / F_ref)^(1/3). Exactly 1 at F_pr = F_ref for every load."""
    fpr = max(preload_n, HERTZ_MIN_PRELOAD_FRAC * ref_n)
    f = abs(f_axial)
    if f < 1e-6 * ref_n:
        return (fpr / ref_n) ** (1.0 / 3.0)
    return (ref_n / fpr) ** (2.0 / 3.0) * hertz_share(f / ref_n) / hertz_share(f / fpr)


def hertz_reference(params: PlantParams) -> float:
    """F_ref (N) of the Hertzian preload law, 0 when off (eq. 5.21's linear law)."""
    return params.screw.hertz_reference_preload_n


# --- a double nut preloaded by an interference (screw.preload_by_interference) ----------
def worn_nut(preload_n: float, clearance_m: float, kstar: float, mslope: float, z: float,
             g: float, ref_n: float) -> tuple[float, float]:
    """(preload N, backlash m along the contact normal) of a double nut preloaded to
    `preload_n` by an interference (a spacer between the halves) that has worn a
    clearance `clearance_m` (along the normal, as `effects.backlash_m`): the clearance
    first eats the interference, the preload falls to what the rest holds, and only the
    clearance beyond it is lost motion (thesis eq. 2.19: the preload loss is the nut's
    stiffness times the deformation lost; section 2.3: backlash appears when the preload
    is null). Axial interference, both halves: 4 F / (Z k g^2) under eq. 5.21's linear
    law (`plant_rt.wear.interference_from_preload`), 2 d0 = 6 F_ref / (Z k_ref g^2)
    (F / F_ref)^(2/3) under the Hertzian law (`ref_n` = F_ref > 0; each half's tangent
    stiffness 1.5 F / d0 at small loads), where the preload left is F (1 - c / 2 d0)^1.5.
    Plain math (`plant_rt.kernel` compiles it with njit)."""
    if preload_n <= 0.0 or clearance_m <= 0.0:
        return preload_n, clearance_m
    c = clearance_m / g                                   # axial clearance
    if ref_n > 0.0:
        kref = kstar + mslope * ref_n
        inter = 6.0 * ref_n / (z * kref * g * g) * (preload_n / ref_n) ** (2.0 / 3.0)
        if c < inter:
            return preload_n * (1.0 - c / inter) ** 1.5, 0.0
        return 0.0, (c - inter) * g
    inter = 4.0 * preload_n / (z * (kstar + mslope * preload_n) * g * g)
    rest = inter - c
    if rest <= 0.0:
        return 0.0, -rest * g
    a = rest * z * g * g                                  # the inverse of the line above
    den = 4.0 - a * mslope
    if den <= 1e-12:
        den = 1e-12
    return a * kstar / den, 0.0
