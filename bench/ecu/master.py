"""`Ecu`, the bench's CANopen master: the link, claim, SDO, set-up and run-loop parts together."""

from __future__ import annotations

from bench.ecu.runloop import RunLoop


class Ecu(RunLoop):
    """The bench's CANopen master for the actuator node `node_id` on `bus`.

    The NMT/EMCY consumers are the ECU's own (`EcuLink._monitor`), not canopen's
    `RemoteNode.nmt`/`.emcy`: during a run the ECU reads the bus itself in the main thread
    (no notifier, so no canopen callback would ever fire), and one monitor feeds the log,
    the foreign-producer watch, the heartbeat and the EMCYs with every frame in both modes.
    """
