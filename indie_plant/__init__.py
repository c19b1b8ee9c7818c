"""An independent actuator for the blind benchmark: physics that differ from
`plant_rt` on purpose (LuGre friction, Hertzian preloaded double nut, cogging and torque
ripple, ADC/encoder/LVDT quantisation), its own parameters and controller, runnable
in-process (`indie_plant.generate`) or as a CANopen node obeying only `ema_contract`
(`python -m indie_plant`). Imports only `ema_contract`, numpy, scipy and numba; never
`plant_rt` or `bench`. Equations: docs/independent-plant.md.
"""
