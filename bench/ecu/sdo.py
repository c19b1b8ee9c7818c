"""The ECU's queries of the node over SDO: objects it has or lacks, parameters, status."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from bench import BenchError
from bench.ecu.errors import PlantLost
from bench.ecu.link import EcuLink
from ema_contract.states import NMTCommand, NMTState
from plant_rt.paramobjects import ParamObjects
from plant_rt.params import ParameterError, PlantParams, check_value, resolve

# CiA 301 SDO abort codes by which a node says it does not have an object
ABSENT_ABORTS = (0x06020000, 0x06090011)   # object / sub-index does not exist
MISSING = object()                         # what `Ecu.read_optional` returns for them
IDENTITY = {"device_type": (0x1000, None), "vendor_id": (0x1018, 1),
            "product_code": (0x1018, 2), "revision": (0x1018, 3), "serial": (0x1018, 4)}
# why a profile's own parameter settings cannot go to a node without the plant's objects
SETTING_HINTS = {
    "load": "the load is the rig's, not the node's: run it unloaded with --load-n 0 and let "
            "the rig apply its load",
    "schedule": "the degradation schedule exists only in the simulated plant",
}



class NodeSdo(EcuLink):
    """Part of `Ecu`: the node's presence, NMT state and objects over SDO."""

    def wait_for_plant(self, timeout: float = 0.5) -> NMTState:
        """The plant's NMT state from its heartbeat, else from an SDO read (the heartbeat
        may be disabled); PlantLost if neither answers within about `timeout` + 0.3 s."""
        self.listen()
        end = self._clock() + timeout
        seen = self.plant_hb
        while self._clock() < end:
            if self.plant_hb is not None and self.plant_hb != seen:
                return self.plant_state or NMTState.PRE_OPERATIONAL
            time.sleep(0.01)
        try:   # heartbeat disabled (0x1017 = 0)? ask by SDO
            if self.has_object("node_status.nmt_state"):
                return NMTState(int(self.sdo_read("node_status.nmt_state")))
            # a node that answers SDO is PRE-OPERATIONAL or OPERATIONAL (CiA 301)
            return self.plant_state or NMTState.PRE_OPERATIONAL
        except Exception:  # noqa: BLE001
            pass
        raise PlantLost(f"no actuator node 0x{self.node_id:02X} answering on the bus "
                        f"(no heartbeat within {timeout:g} s, no SDO answer)")

    def reset_node(self, timeout: float = 3.0) -> None:
        """NMT reset node and wait for the boot-up frame."""
        self.listen()
        before = self.bootups
        self.nmt(NMTCommand.RESET_NODE)
        end = self._clock() + timeout
        while self._clock() < end:
            if self.bootups > before:
                return
            time.sleep(0.005)
        raise PlantLost(f"actuator node 0x{self.node_id:02X} did not boot up within "
                        f"{timeout:g} s of an NMT reset")

    # -- SDO ----------------------------------------------------------------------------------
    def _sdo_var(self, name: str | int | tuple[int, int]):
        """The SDO variable of object `name`: ``group.leaf`` (e.g. ``node_status.cycles``),
        a group name, an index, or (index, sub-index)."""
        group: str | int
        leaf: str | int | None
        if isinstance(name, tuple):
            group, leaf = name
        elif isinstance(name, str) and "." in name:
            group, leaf = name.split(".", 1)
        else:
            group, leaf = name, None
        try:
            var = self.remote.sdo[group]
            return var[leaf] if leaf is not None else var
        except KeyError:
            raise BenchError(f"the object dictionary has no object {name!r}") from None

    def sdo_transfer(self, transfer: Callable[[], Any]) -> Any:
        """`transfer()` (one SDO upload or download), started again from its initiation
        when an answer does not come within the SDO timeout, up to `sdo_attempts` times
        (`bench.ecu.sdoclient`); the last SdoCommunicationError when none succeeds.
        Writes are the same value again, so a repeated transfer is harmless."""
        for attempt in range(1, self.sdo_attempts + 1):
            try:
                return transfer()
            except SdoCommunicationError:
                if attempt == self.sdo_attempts:
                    raise
                self.sdo_retries += 1
        raise AssertionError("unreachable")

    @staticmethod
    def _label(var) -> str:
        """``0xIIII sub S (group.leaf)`` of an SDO variable, for messages."""
        od = var.od
        parent = getattr(od, "parent", None)
        if parent is None:
            return f"0x{od.index:04X} ({od.name})"
        return f"0x{od.index:04X} sub {od.subindex} ({parent.name}.{od.name})"

    def _note_absent(self, var, code: int) -> None:
        """Remember that the node lacks `var` (`code` 0x06020000: its whole object)."""
        od = var.od
        if code == ABSENT_ABORTS[0]:
            self._absent_index.add(od.index)
            parent = getattr(od, "parent", None)
            label = f"0x{od.index:04X} ({(parent or od).name})"
        else:
            self._present[(od.index, od.subindex)] = False
            label = self._label(var)
        self._missing.setdefault(label, None)

    @property
    def missing(self) -> list[str]:
        """Optional objects the node was found not to have (labels, sorted)."""
        return sorted(self._missing)

    def has_object(self, name: str | int | tuple[int, int]) -> bool:
        """True if the node has object `name`: an SDO upload is answered, or refused for
        another reason than absence (e.g. a write-only object). Cached per object."""
        self.listen()
        var = self._sdo_var(name)
        od = var.od
        key = (od.index, od.subindex)
        if od.index in self._absent_index:
            return False
        if key not in self._present:
            try:
                self.sdo_transfer(lambda: self.remote.sdo.upload(*key))
                self._present[key] = True
            except SdoAbortedError as exc:
                if exc.code in ABSENT_ABORTS:
                    self._note_absent(var, exc.code)
                else:
                    self._present[key] = True
            except SdoCommunicationError as exc:
                raise PlantLost(f"no SDO answer reading {self._label(var)}{self._tries()}: "
                                f"{exc}") from None
        return self._present.get(key, False)

    def read_optional(self, name: str | int | tuple[int, int]) -> Any:
        """Object `name` by SDO, or `MISSING` if the node does not have it (recorded in
        `missing`); other refusals are a BenchError, no answer PlantLost."""
        self.listen()
        var = self._sdo_var(name)
        if var.od.index in self._absent_index or self._present.get(
                (var.od.index, var.od.subindex)) is False:
            return MISSING
        try:
            value = self.sdo_transfer(lambda: var.raw)
        except SdoAbortedError as exc:
            if exc.code in ABSENT_ABORTS:
                self._note_absent(var, exc.code)
                return MISSING
            raise BenchError(f"the plant refused to read {self._label(var)}: {exc}") from None
        except SdoCommunicationError as exc:
            raise PlantLost(f"no SDO answer reading {self._label(var)}{self._tries()}: "
                            f"{exc}") from None
        self._present[(var.od.index, var.od.subindex)] = True
        return value

    def sdo_read(self, name: str | int | tuple[int, int]) -> Any:
        """Read an object by name (``group.leaf``, e.g. ``node_status.cycles``)."""
        value = self.read_optional(name)
        if value is MISSING:
            raise BenchError(f"actuator node 0x{self.node_id:02X} has no object "
                             f"{self._label(self._sdo_var(name))}")
        return value

    def sdo_write(self, name: str | int | tuple[int, int], raw: Any) -> None:
        self.listen()
        var = self._sdo_var(name)

        def write() -> None:
            var.raw = raw

        try:
            self.sdo_transfer(write)
        except SdoAbortedError as exc:
            if exc.code in ABSENT_ABORTS:
                self._note_absent(var, exc.code)
                raise BenchError(f"actuator node 0x{self.node_id:02X} has no object "
                                 f"{self._label(var)} (writing {raw!r})") from None
            raise BenchError(f"the plant refused {name} = {raw!r}: {exc}") from None
        except SdoCommunicationError as exc:
            raise PlantLost(f"no SDO answer writing {self._label(var)}{self._tries()}: "
                            f"{exc}") from None

    def _tries(self) -> str:
        """How long the ECU waited for an SDO answer, for messages."""
        t = self.remote.sdo.RESPONSE_TIMEOUT
        n = self.sdo_attempts
        return f" ({n} attempts of {t:g} s)" if n > 1 else f" (within {t:g} s)"

    def set_params(self, values: dict[str, Any]) -> None:
        """Write plant parameters by SDO (checked here first for a clear message)."""
        for name, value in values.items():
            try:
                info = resolve(name)
                raw = ParamObjects.to_od(info, check_value(info, value))
            except ParameterError as exc:
                raise BenchError(str(exc)) from None
            self.sdo_write(info.name, raw)

    def check_settable(self, values: dict[str, Any], origin: dict[str, str] | None = None
                       ) -> None:
        """BenchError (one line, naming every setting and object) if the node lacks an
        object that `values` would write; `origin` says where each name came from
        (``--set``, ``profile NAME``), by canonical parameter name."""
        origin = origin or {}
        absent: dict[str, list[str]] = {}
        for name in values:
            try:
                info = resolve(name)
            except ParameterError as exc:
                raise BenchError(str(exc)) from None
            if not self.has_object(info.name):
                absent.setdefault(origin.get(info.name, "the run"), []).append(info.name)
        if not absent:
            return
        parts = []
        for source, names in absent.items():
            objs = ", ".join(f"0x{self.param_objects.by_name[n].index:04X} sub "
                             f"{self.param_objects.by_name[n].subindex}" for n in names)
            part = f"{', '.join(names)} ({source}) need{'s' if len(names) == 1 else ''} {objs}"
            hints = {SETTING_HINTS[n.split('.')[0]] for n in names
                     if n.split(".")[0] in SETTING_HINTS}
            parts.append(part + "".join(f": {h}" for h in sorted(hints)))
        raise BenchError(f"actuator node 0x{self.node_id:02X} lacks the parameter objects "
                         "this run writes: " + "; ".join(parts))

    def read_params(self) -> PlantParams:
        """Every plant parameter the node has, read by SDO (the others at their default;
        `node_info.params_complete` says whether all were there)."""
        values = {}
        for name, po in self.param_objects.by_name.items():
            raw = self.read_optional(name)
            if raw is not MISSING:
                values[name] = ParamObjects.from_od(po.info, raw)
        self.node_info.params = values
        self.node_info.params_complete = len(values) == len(self.param_objects.by_name)
        return PlantParams().with_dict(values)

    def read_status(self) -> dict[str, Any]:
        """Object 0x2100 (node status and counters) by name; {} if the node has none."""
        rec = self.od["node_status"]
        if not self.has_object("node_status.nmt_state"):
            return {}
        return {var.name: self.sdo_read(f"node_status.{var.name}")
                for sub, var in rec.subindices.items() if sub}

    def read_identity(self) -> dict[str, int]:
        """CiA 301 device type (0x1000) and identity (0x1018 sub 1-4), those the node has."""
        out = {}
        for key, (index, sub) in IDENTITY.items():
            v = self.read_optional(index if sub is None else (index, sub))
            if v is not MISSING:
                out[key] = int(v)
        return out
