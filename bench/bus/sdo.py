"""SDO traffic of a log -> the values that crossed the SDO server (CiA 301 expedited and
segmented transfers), the plant parameters they are (`sdo_values`) and the actuator's
serial number (`serial_of`, identity object 0x1018 sub 4)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import can

from plant_rt.paramobjects import ParamObjects


@dataclass
class _Transfer:
    index: int
    sub: int
    upload: bool
    data: bytearray = field(default_factory=bytearray)
    size: int | None = None


class SdoTracker:
    """Values that crossed an SDO server (CiA 301 expedited and segmented transfers),
    confirmed by the server: object (index, sub) -> raw bytes, in log order."""

    def __init__(self, rx_cob: int, tx_cob: int) -> None:
        self.rx_cob, self.tx_cob = rx_cob, tx_cob
        self.values: dict[tuple[int, int], bytes] = {}
        self._req: _Transfer | None = None
        self._pending_write: _Transfer | None = None

    def feed(self, msg: can.Message) -> None:
        d = bytes(msg.data)
        if len(d) != 8:
            return
        if msg.arbitration_id == self.rx_cob:          # client -> server
            self._from_client(d)
        elif msg.arbitration_id == self.tx_cob:        # server -> client
            self._from_server(d)

    def _from_client(self, d: bytes) -> None:
        cmd = d[0]
        ccs = cmd >> 5
        if ccs == 1:                                 # initiate download
            t = _Transfer(d[1] | d[2] << 8, d[3], False)
            if cmd & 0x2:                            # expedited
                n = 4 - ((cmd >> 2) & 0x3) if cmd & 0x1 else 4
                t.data += d[4:4 + n]
                t.size = n
            elif cmd & 0x1:
                t.size = int.from_bytes(d[4:8], "little")
            self._pending_write = t
        elif ccs == 0 and self._pending_write is not None:   # download segment
            n = 7 - ((cmd >> 1) & 0x7)
            self._pending_write.data += d[1:1 + n]
            if cmd & 0x1:
                self._pending_write.size = len(self._pending_write.data)
        elif ccs == 2:                               # initiate upload
            self._req = _Transfer(d[1] | d[2] << 8, d[3], True)

    def _from_server(self, d: bytes) -> None:
        cmd = d[0]
        scs = cmd >> 5
        if scs == 4:                                 # abort
            self._req = self._pending_write = None
        elif scs in (3, 1) and self._pending_write is not None:  # download / segment confirmed
            t = self._pending_write
            if t.size is not None and len(t.data) >= t.size:
                self.values[(t.index, t.sub)] = bytes(t.data[:t.size])
                self._pending_write = None
        elif scs == 2 and self._req is not None:     # initiate upload response
            t = self._req
            if cmd & 0x2:
                n = 4 - ((cmd >> 2) & 0x3) if cmd & 0x1 else 4
                self.values[(t.index, t.sub)] = d[4:4 + n]
                self._req = None
            else:
                t.size = int.from_bytes(d[4:8], "little") if cmd & 0x1 else None
        elif scs == 0 and self._req is not None:     # upload segment
            t = self._req
            n = 7 - ((cmd >> 1) & 0x7)
            t.data += d[1:1 + n]
            if cmd & 0x1:
                self.values[(t.index, t.sub)] = bytes(t.data if t.size is None
                                                      else t.data[:t.size])
                self._req = None

def sdo_values(sdo: SdoTracker, pobj: ParamObjects, od: Any) -> dict[str, Any]:
    """The plant parameters the SDO traffic revealed (name -> value)."""
    values: dict[str, Any] = {}
    for (idx, sub), raw in sdo.values.items():
        po = pobj.by_key.get((idx, sub))
        if po is None:
            continue
        try:
            values[po.info.name] = ParamObjects.from_od(po.info, od[idx][sub].decode_raw(raw))
        except Exception:  # noqa: BLE001 - a garbled transfer is skipped, not fatal
            continue
    if (0x1006, 0) in sdo.values:
        try:
            us = od[0x1006].decode_raw(sdo.values[(0x1006, 0)])
            values.setdefault("sim.sync_period_s", us * 1e-6)
        except Exception:  # noqa: BLE001
            pass
    return values


def serial_of(sdo: SdoTracker, od: Any) -> str:
    """The serial number (identity 0x1018 sub 4) the ECU read by SDO in the log, else
    "unknown" (a node without it, or a log without the ECU's start-up)."""
    raw = sdo.values.get((0x1018, 4))
    if raw is None:
        return "unknown"
    try:
        return str(int(od[0x1018][4].decode_raw(raw)))
    except Exception:  # noqa: BLE001 - a garbled transfer is not a serial number
        return "unknown"
