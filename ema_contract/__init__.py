"""The bus contract of the EMA ball-screw HUMS bench: what crosses the CAN bus.

- `ema_contract.frames`: the DBC bound to the node ids in use (`Frames`, `FrameError`,
  `load_db`, `load_od`, `default_ids`, `exclude_filters`),
- `ema_contract.states`: NMT states and commands, control and status words, the plant's
  status bits, the pacer,
- `ema_contract.transport`: which CAN bus to open, and the bench's state files,
- `ema.dbc` and `ema.eds`: their source is the repository's top-level `dbc/`; the wheel
  carries them as package data in `ema_contract/dbc/` (`$EMA_BENCH_DBC_DIR` points
  elsewhere).

Both the simulated plant (`plant_rt`) and the bench (`bench`) import this package; it
imports neither of them (no numba, no physics), so a bus client needs only this.
"""
