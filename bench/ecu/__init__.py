"""The ECU: a CANopen master that runs the bench's controller against the plant over the bus.

It holds a python-can bus and nothing of the plant but what the bus carries: NMT, SYNC
production, its own heartbeat, SDO (canopen `RemoteNode` from `dbc/ema.eds`) and the
PDOs of `dbc/ema.dbc` (cantools). The same `bench.sim.control.Controller` as the in-process
harness computes the current demand, so a lockstep bus run reproduces
`bench.sim.harness.simulate` within the DBC quantisation.

Per control period k (CiA 301 synchronous PDOs):

    ECU: SYNC(k) -> plant: latches RPDO(k-1), sends TPDO1-3 (sensors at t_k), steps
    ECU: sends ECU_Setpoint(k) (the set-points of t_k) right after its SYNC
    ECU: decodes TPDOs, demand(k) = controller(set-points(t_k), measurements(t_k)),
         sends RPDO1(k)  -> applied by the plant at SYNC(k+1)

`pace="sync"`: the next SYNC goes out as soon as the period is done (lockstep);
`pace="realtime"`: SYNCs are released on absolute wall-clock deadlines
(`plant_rt.pacing`), and a TPDO that misses its window leaves the previous value.

Every frame goes to the candump log: received frames as they arrive, the ECU's own
as it sends them (with ``echo=True``, as the bus returns them through
``receive_own_messages``, at the cost of one more frame per send to receive). The log is
flushed and closed whatever ends the run.

A run is a success only when nothing spoilt it: the plant reporting a
condition that changes what it does with the demand (`FAILING_BITS`, any EMCY outside
`REPORTING_EMCY`), another ECU on the bus (`claim` before anything is sent, any foreign
SYNC/RPDO/set-point/heartbeat during the run), a log that cannot be written, or a
signal (`StopSignal`) end it with an error, the partial trace kept and the node set
PRE-OPERATIONAL. In lockstep the heartbeat follows the SYNC grid (the plant counts its
consumer time in SYNC periods) and the wall clock while waiting.

Modules, one job each: `link` (sends, the frame monitor, NMT, heartbeat), `claim` (the claim
on the node, the foreign-producer watch, abort), `sdo` (queries over SDO, `NodeInfo`),
`prepare` (the node's set-up for a run), `runloop` (`run`: the control loop and the run's end),
`period` (the steps of one SYNC period, the loop's state, `EcuStats`),
`master` (`Ecu`, the mixins put together), `logwriter`, `signals`, `errors`, `session`
(`run_over_bus`, the session from bus to trace).
"""

from bench.ecu.errors import (
                              FAILING_BITS,
                              FAILING_TEXT,
                              REPORTING_EMCY,
                              BusLost,
                              ForeignEcu,
                              Interrupted,
                              LogWriteError,
                              PlantFault,
                              PlantLost,
                              status_names,
)
from bench.ecu.link import ECU_FRAMES
from bench.ecu.master import Ecu
from bench.ecu.nodeinfo import NodeInfo
from bench.ecu.period import EcuStats
from bench.ecu.runloop import RUN_COLUMNS, run_periods
from bench.ecu.sdo import MISSING
from bench.ecu.session import plant_values, run_over_bus, setting_origins
from bench.ecu.signals import StopSignal

__all__ = ["Ecu", "EcuStats", "NodeInfo", "PlantLost", "BusLost", "PlantFault", "ForeignEcu",
           "LogWriteError", "Interrupted", "StopSignal", "run_periods", "status_names",
           "MISSING", "RUN_COLUMNS", "ECU_FRAMES", "FAILING_BITS", "FAILING_TEXT",
           "REPORTING_EMCY", "plant_values", "run_over_bus", "setting_origins"]
