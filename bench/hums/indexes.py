"""HUMS indexes of thesis section 6.2, from traces (real vs nominal), whole-run and online.

The mean error, Cp, Ci and the peak-current ratio (eq. 6.4-6.7, in the ratio-of-integrals
reading) are written out in `bench.hums.formulas`.

- current spectrum (eq. 6.3): one-sided amplitude spectrum of a windowed rfft, calibrated
  so a sine of amplitude A reads A at its line (`amplitude_spectrum`); harmonic features
  are the amplitudes of the command frequency f0 and its multiples, each read from the
  energy of its main lobe so they hold off-bin too (`harmonic_amplitudes`).

Beyond the thesis, from signals an actuator has (encoder angle and speed, LVDT):
- lost motion (m): the hysteresis between the encoder travel (motor angle x tau p / 2 pi
  through the nominal LVDT dynamics) and the LVDT reading, split by the direction of
  motion: median while moving forward minus median while moving back. A rigid screw
  gives 0; backlash b gives about b / (cos alpha sin beta) once preload no longer takes
  it up.
- reversal dead time (s): per command period, the time the motor moves (|encoder speed| >
  10 % of its peak) while the nut does not (|LVDT speed| < 5 % of its peak), real minus
  nominal.

`period_indexes` yields all of them for each command period of a long trace (the RUL run,
a live bus run); `OnlineHums` does the same from samples pushed as they arrive.

Where each part lives (this module is their one public face; importers use it):
`bench.hums.formulas` (eq. 6.4-6.7 and the lost-motion reading on arrays),
`bench.hums.spectra` (eq. 6.3, harmonics), `bench.hums.motion` (the streaming signals
behind lost motion and dead time), `bench.hums.comparison` (`Indexes` of one window,
`compare`), `bench.hums.gaps` (lost samples: bridging, unavailable indexes) and
`bench.hums.periods` (per command period: `period_indexes`, `OnlineHums`).
"""

from __future__ import annotations

from bench.hums.comparison import Indexes, compare
from bench.hums.formulas import (
    CURRENT_SIGNALS,
    LOST_MOTION_SIGNALS,
    POSITION_SIGNALS,
    ci,
    ci_harmonic,
    cp,
    fidelity,
    friction_current,
    lost_motion_from,
    mean_error,
    peak_ratio,
    stall_time_from,
)
from bench.hums.gaps import (
    BRIDGE_MAX_FRACTION,
    BRIDGE_MAX_SAMPLES,
    HOLD_SIGNALS,
    INDEX_SIGNALS,
    Gaps,
    bridge,
    mark_unavailable,
    missing_runs,
    signal_gaps,
)
from bench.hums.motion import Kinematics, MotionStream, lost_motion, motion_signals, stall_time
from bench.hums.periods import OnlineHums, as_table, one_period, period_indexes
from bench.hums.spectra import N_HARMONICS, amplitude_spectrum, harmonic_amplitudes

__all__ = [
    "BRIDGE_MAX_FRACTION", "BRIDGE_MAX_SAMPLES", "CURRENT_SIGNALS", "HOLD_SIGNALS",
    "INDEX_SIGNALS", "LOST_MOTION_SIGNALS", "N_HARMONICS", "POSITION_SIGNALS", "Gaps",
    "Indexes", "Kinematics", "MotionStream", "OnlineHums", "amplitude_spectrum", "as_table",
    "bridge", "ci", "ci_harmonic", "compare", "cp", "fidelity", "friction_current",
    "harmonic_amplitudes", "lost_motion", "lost_motion_from", "mark_unavailable",
    "mean_error", "missing_runs", "motion_signals", "one_period", "peak_ratio",
    "period_indexes", "signal_gaps", "stall_time", "stall_time_from",
]
