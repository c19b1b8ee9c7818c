"""The ECU's set-up of the node for a run: reset, pace, parameters, timing."""

from __future__ import annotations

from typing import Any

from bench import BenchError
from bench.ecu.nodeinfo import NodeInfo
from bench.ecu.sdo import MISSING, NodeSdo
from ema_contract.states import Pace
from plant_rt.params import ParameterError, PlantParams


class NodePrepare(NodeSdo):
    """Mixin of `Ecu`: `prepare` a node for a run."""

    # -- running a profile ------------------------------------------------------------------
    def prepare(self, pace: Pace | None, values: dict[str, Any], spin_us: int | None = None,
                origin: dict[str, str] | None = None, encoder_counts: int | None = None,
                sync_driven: bool = False) -> PlantParams:
        """Reset the node, set pace (and the plant pacer's spin window, in real time) and
        parameters, restart the plant at t = 0; returns the parameters the plant now has
        (read back). `pace` None follows the node: its own pace after the reset (0x2200
        sub 1: the one it was started with), real time for a node without that object;
        `run_pace` and `pace_source` say which pace the run has and why.

        Only NMT, heartbeat, SDO of CiA 301 objects and the DBC's PDOs are required; the
        optional objects (0x2000-0x2008, 0x2100, 0x2200) are used when the node has them.
        Without them: `node_info` lists what is missing and `node_info.notes` what the
        ECU does instead (docs/node-contract.md). `encoder_counts` (counts/rev) stands in
        for a missing 0x2003 sub 11; `sync_driven` vouches that a node without 0x2200
        steps exactly one period per SYNC (else `Pace.SYNC` is refused)."""
        self.wait_for_plant(2.0)
        self.reset_node()
        info = self.node_info = NodeInfo(notes=[])
        info.identity = self.read_identity()
        pace = self._choose_pace(pace)
        self._set_pace(pace, sync_driven)
        if (pace == Pace.REALTIME and spin_us is not None
                and self.has_object("node_control.spin_us")):
            self.sdo_write("node_control.spin_us", int(spin_us))
        self.check_settable(values, origin)
        self.set_params(values)
        if self.has_object("node_control.reset_plant"):
            self.sdo_write("node_control.reset_plant", 1)
        else:
            info.notes.append("node has no plant reset (0x2200 sub 2 missing): the run "
                              "starts from the node's state after NMT reset node")
        params = self._timing(self.read_params(), encoder_counts)
        if not info.params_complete:
            absent = sorted({po.index for n, po in self.param_objects.by_name.items()
                             if n not in info.params})
            span = (f"0x{absent[0]:04X}-0x{absent[-1]:04X}" if len(absent) > 1
                    and absent[-1] - absent[0] == len(absent) - 1 else
                    ", ".join(f"0x{i:04X}" for i in absent))
            info.notes.append(f"node has {'no' if not info.params else 'not all'} plant "
                              f"parameter objects ({span} missing): {len(info.params)} of "
                              f"{len(self.param_objects.by_name)} read back")
        if not self.has_object("node_status.nmt_state"):
            info.notes.append("node has no counters (0x2100 missing): plant counters "
                              "skipped")
        info.missing = self.missing
        return params

    def _choose_pace(self, pace: Pace | None) -> Pace:
        """The run's pace: `pace` when given, else the node's own (after NMT reset node,
        the pace it was started with), else real time; `run_pace`, `pace_source`."""
        own = None
        if self.has_object("node_control.pace"):
            own = Pace(int(self.sdo_read("node_control.pace")))

        def name(p: Pace) -> str:
            return p.name.lower()

        if pace is not None:
            src = "as the command asks (its --pace or that option's default)"
            if own is not None and own != pace:
                src += f"; the plant runs {name(own)} on its own (0x2200 sub 1)"
        elif own is not None:
            pace, src = own, ("the plant's own (0x2200 sub 1, the pace it was started "
                              "with); --pace overrides it")
        else:
            pace, src = Pace.REALTIME, ("the node has no pace object (0x2200 sub 1): real "
                                        "time, as hardware")
        self.run_pace, self.pace_source = pace, f"pace {name(pace)}: {src}"
        return pace

    def _set_pace(self, pace: Pace, sync_driven: bool) -> None:
        """Write the lockstep object 0x2200 sub 1, or decide without it."""
        if self.has_object("node_control.pace"):
            self.sdo_write("node_control.pace", int(pace))
        elif pace == Pace.SYNC and not sync_driven:
            raise BenchError(f"--pace sync needs the lockstep object 0x2200 sub 1, which "
                             f"actuator node 0x{self.node_id:02X} does not have (a real "
                             "actuator runs on its own clock): use --pace realtime")
        elif pace == Pace.SYNC:
            self.node_info.notes.append("node has no lockstep (0x2200 sub 1 missing): "
                                        "lockstep on the caller's word that the node "
                                        "steps one period per SYNC")
        else:
            self.node_info.notes.append("node has no lockstep (0x2200 sub 1 missing): "
                                        "running in real time")

    def _timing(self, params: PlantParams, encoder_counts: int | None) -> PlantParams:
        """`params` with the encoder resolution and SYNC period the run uses: the node's
        parameter objects, else `encoder_counts` / object 0x1006, else the EDS defaults."""
        info = self.node_info
        cpr_name, ts_name = "sensors.encoder_counts_per_rev", "sim.sync_period_s"
        cpr_po = self.param_objects.by_name[cpr_name]
        cpr_obj = f"0x{cpr_po.index:04X} sub {cpr_po.subindex}"
        cpr_default = int(self.od[cpr_po.index][cpr_po.subindex].default)
        if cpr_name in info.params:
            cpr, source = int(info.params[cpr_name]), f"node {cpr_obj}"
            if encoder_counts is not None and int(encoder_counts) != cpr:
                raise BenchError(f"--encoder-counts {encoder_counts} disagrees with the node's "
                                 f"encoder resolution {cpr_obj} = {cpr} counts/rev")
        elif encoder_counts is not None:
            cpr, source = int(encoder_counts), "--encoder-counts"
        else:
            cpr, source = cpr_default, f"the EDS default of {cpr_obj}"
        if cpr_name not in info.params:
            note = (f"node has no encoder resolution ({cpr_obj} missing): {cpr} counts/rev "
                    f"from {source}")
            if encoder_counts is None:
                note += " (--encoder-counts N for another encoder)"
            if cpr != cpr_default:   # decoders assume the default when the log lacks it
                note += f"; the log does not carry it: decode with --counts-per-rev {cpr}"
            info.notes.append(note)
        if ts_name in info.params:
            ts, ts_source = float(info.params[ts_name]), "node 0x2008 sub 1"
        else:
            us = self.read_optional(0x1006)
            if us is not MISSING and int(us) > 0:
                ts, ts_source = int(us) * 1e-6, "node 0x1006"
            else:
                ts = int(self.od[0x1006].default) * 1e-6
                ts_source = "EDS default of 0x1006"
                info.notes.append(f"node has no SYNC period (0x1006 missing or 0): "
                                  f"{ts * 1e3:g} ms, the EDS default")
        info.encoder_counts_per_rev, info.encoder_counts_source = cpr, source
        info.sync_period_s, info.sync_period_source = ts, ts_source
        try:
            return params.with_dict({cpr_name: cpr, ts_name: ts})
        except ParameterError as exc:
            raise BenchError(str(exc)) from None
