"""The EMA actuator plant of thesis chapter 5, as a model API and as a CANopen node.

`plant_rt.params` holds the parameter sets (tables 5.1-5.4), `plant_rt.kernel` the
compiled fixed-step core, `plant_rt.model.Plant` the one-SYNC-period step used by both
the live node (`python -m plant_rt`) and offline studies. This package never imports
`bench`.
"""

from plant_rt.model import Measurement, Plant, Status
from plant_rt.params import ParameterError, PlantParams

__all__ = ["Plant", "PlantParams", "ParameterError", "Measurement", "Status"]
