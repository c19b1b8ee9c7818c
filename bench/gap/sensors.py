"""Candidate effects of the sensors' timing and of the logging channel, each sensor apart
(docs/gap.md, "Candidate effects and their families"): a transport delay of the LVDT or of the encoder alone
in the loop (the controller reads an older sample of that sensor: `bench.gap.delays`), the
same delays in the log alone (the logger's channel is late, the controller is not), and
the logged current's own delay, offset and gain (a current channel the drive does not
regulate on).

Why apart: a delay of one sensor shifts its phase against the other's by omega d, growing
with frequency, and a loop that reads it late rings at another frequency; a gain scales
the same sensor at every frequency. The library's `sensor_delay` delays both position
sensors together; a log whose LVDT alone is late has no candidate of that shape there,
and a fit then takes the nearest other, an encoder gain (seen on an actuator node written
apart from the bench: an LVDT transport delay of 3 ms read as `encoder_gain`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from bench.gap.candidate import Effect, Param
from plant_rt.params import PlantParams

DELAY_MAX_S = 0.008
DELAY_STEP_S = 0.001


def _periods(seconds: float, dt: float) -> int:
    return max(int(round(seconds / dt)), 0)


def _delay_param(name: str) -> Param:
    """A sensor delay in seconds, searched in whole steps of `DELAY_STEP_S`."""
    return Param(name, "s", 0.0, DELAY_MAX_S, "delay", integer_step=DELAY_STEP_S)


def late(y: np.ndarray, d: int) -> np.ndarray:
    """`y` read `d` samples late (its first sample repeated before the start)."""
    if d <= 0 or len(y) == 0:
        return y
    return np.concatenate([np.full(min(d, len(y)), y[0]), y[:-d]])[:len(y)]


class _Delay(Effect):
    """A whole-period delay of one sensor: `sensor` is "lvdt" or "encoder"."""
    sensor: ClassVar[str] = ""
    columns: ClassVar[tuple[str, ...]] = ()

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {self.params[0].name: 0.0}

    def loop_delays(self, theta: Mapping[str, float], dt: float) -> tuple[int, int]:
        """(LVDT, encoder) periods late in the loop; a delay in the log alone has none."""
        if self.where == "log":
            return 0, 0
        d = _periods(theta[self.params[0].name], dt)
        return (d, 0) if self.sensor == "lvdt" else (0, d)


class LvdtDelay(_Delay):
    name = "lvdt_delay"
    doc = ("transport delay of the LVDT alone, in the loop: the ECU reads an older position "
           "sample (whole SYNC periods)")
    params = (_delay_param("lvdt_delay_s"),)
    sensor = "lvdt"


class EncoderDelay(_Delay):
    name = "encoder_delay"
    doc = ("transport delay of the encoder alone (angle and speed), in the loop: the ECU "
           "reads an older speed sample (whole SYNC periods)")
    params = (_delay_param("encoder_delay_s"),)
    sensor = "encoder"


class _LogDelay(_Delay):
    where = "log"

    def post(self, cols: dict[str, np.ndarray], theta: Mapping[str, float],
             dt: float) -> dict[str, np.ndarray]:
        d = _periods(theta[self.params[0].name], dt)
        if d <= 0:
            return cols
        out = dict(cols)
        for c in self.columns:
            if c in cols:
                out[c] = late(cols[c], d)
        return out


class LvdtDelayLog(_LogDelay):
    name = "lvdt_delay_log"
    doc = "the logged LVDT late, not the ECU's (the logger's channel; whole SYNC periods)"
    params = (_delay_param("lvdt_delay_log_s"),)
    columns = ("position_m",)


class EncoderDelayLog(_LogDelay):
    name = "encoder_delay_log"
    doc = ("the logged encoder angle and speed late, not the ECU's (the logger's channel; "
           "whole SYNC periods)")
    params = (_delay_param("encoder_delay_log_s"),)
    columns = ("motor_angle_rad", "motor_speed_rad_s")


class CurrentDelayLog(_LogDelay):
    name = "current_delay_log"
    doc = ("the logged current late (its ADC or channel; the ECU does not read the current, "
           "so no loop sees it; whole SYNC periods)")
    params = (_delay_param("current_delay_log_s"),)
    columns = ("current_a",)


class _CurrentLog(Effect):
    """An error of the logged current alone: `exact` is the parameter's no-error value."""
    where = "log"
    exact: ClassVar[float] = 0.0

    def nominal(self, base: PlantParams) -> dict[str, float]:
        return {self.params[0].name: self.exact}

    @staticmethod
    def apply(current: np.ndarray, value: float) -> np.ndarray:
        raise NotImplementedError

    def post(self, cols: dict[str, np.ndarray], theta: Mapping[str, float],
             dt: float) -> dict[str, np.ndarray]:
        out = dict(cols)
        out["current_a"] = self.apply(cols["current_a"], theta[self.params[0].name])
        return out


class CurrentOffsetLog(_CurrentLog):
    name = "current_offset_log"
    doc = ("offset of the logged current alone (the logger's current sensor, not the "
           "drive's): the drive regulates the true current")
    params = (Param("current_offset_log_a", "A", -2.0, 2.0, "offset"),)
    exact = 0.0

    @staticmethod
    def apply(current: np.ndarray, value: float) -> np.ndarray:
        return current + value


class CurrentGainLog(_CurrentLog):
    name = "current_gain_log"
    doc = ("gain error of the logged current alone (the logger's sensor; in the drive's own "
           "loop a current gain is a torque-constant error, `kt`)")
    params = (Param("current_gain_log", "-", 0.8, 1.25, "gain (1 = exact)"),)
    exact = 1.0

    @staticmethod
    def apply(current: np.ndarray, value: float) -> np.ndarray:
        return current * value


BUILTIN: tuple[type[Effect], ...] = (LvdtDelay, EncoderDelay, LvdtDelayLog, EncoderDelayLog,
                                     CurrentDelayLog, CurrentOffsetLog, CurrentGainLog)
"""The sensor-side candidates of this module, in the diagnosis' order."""

__all__ = ["BUILTIN", "late"] + [c.__name__ for c in BUILTIN]
