"""The ECU's SDO client: canopen's `SdoClient`, with each answer matched to its request.

CiA 301 leaves the SDO timeout to the application and defines the abort code for it
(0x05040000, "SDO protocol timed out"); it does not say what a client does next. The
ECU waits `SDO_TIMEOUT_S` for each answer and, when none comes, starts the whole
transfer again, up to `SDO_ATTEMPTS` times (`bench.ecu.sdo.NodeSdo`): on a loaded
machine an answer can come late, and one late answer in the few hundred transfers of a
run's set-up failed the run ("no SDO answer reading 0x2003 sub 8").

A transfer is restarted from its initiation, never from a segment: a server that saw
the segment request answers its repetition with "toggle bit not alternated". Starting
again makes the late answer of the abandoned attempt a stray frame, which canopen's
client would take for the answer to whatever it asks next (its queue holds any frame
from the server, and a download's answer is not checked against its object). So here
an answer is taken only when it can be the answer to the request just sent: an
initiation's answer names the same object (index and sub-index) with the answering
command, a segment's answer has the answering command and the request's toggle bit, an
abort names the object of the transfer. Anything else is dropped and counted
(`stray`), and the wait goes on until the timeout.
"""

from __future__ import annotations

import queue
import struct
import time

import canopen
from canopen.sdo import SdoClient
from canopen.sdo.constants import ABORT_TIMED_OUT, RESPONSE_ABORTED
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

SDO_TIMEOUT_S = 0.5
"""Wait for one SDO answer (s): far above the round trip of a loaded machine
(docs/bus.md, "SDO set-up on a loaded machine")."""
SDO_ATTEMPTS = 3
"""Transfers started for one object before the node is taken to be gone."""

_TOGGLE = 0x10


def expected_answer(request: bytes, mux: bytes | None) -> tuple[int, int, bytes | None]:
    """(mask, value, object) an answer to `request` must match: ``answer[0] & mask ==
    value``, and for an initiation its bytes 1-3 (index, sub-index) equal `object`.
    `mux` is the object of the transfer the request belongs to (for aborts)."""
    ccs = request[0] >> 5
    if ccs == 2:                                    # initiate upload -> scs 2
        return 0xE0, 0x40, bytes(request[1:4])
    if ccs == 1:                                    # initiate download -> scs 3
        return 0xE0, 0x60, bytes(request[1:4])
    if ccs == 3:                                    # upload segment -> scs 0, same toggle
        return 0xF0, request[0] & _TOGGLE, mux
    if ccs == 0:                                    # download segment -> scs 1, same toggle
        return 0xF0, 0x20 | (request[0] & _TOGGLE), mux
    return 0, 0, mux                                # block transfers: canopen's checks


class MatchingSdoClient(SdoClient):
    """`SdoClient` whose `request_response` takes only an answer to the request just
    sent (see the module's docstring); one attempt, no retry at the segment level."""

    MAX_RETRIES = 1
    RESPONSE_TIMEOUT = SDO_TIMEOUT_S

    def __init__(self, rx_cobid: int, tx_cobid: int, od) -> None:
        super().__init__(rx_cobid, tx_cobid, od)
        self.stray = 0               # answers dropped as not answering the request
        self._mux: bytes | None = None

    def request_response(self, sdo_request) -> bytes:
        req = bytes(sdo_request)
        mask, value, mux = expected_answer(req, self._mux)
        if req[0] >> 5 in (1, 2):
            self._mux = mux           # the transfer's object, for its segments' aborts
        while True:                   # answers that arrived before the request are stale
            try:
                self.responses.get_nowait()
                self.stray += 1
            except queue.Empty:
                break
        self.send_request(req)
        end = time.monotonic() + self.RESPONSE_TIMEOUT
        while True:
            left = end - time.monotonic()
            try:
                answer = self.responses.get(block=True, timeout=max(left, 0.0))
            except queue.Empty:
                self.abort(ABORT_TIMED_OUT)
                raise SdoCommunicationError("No SDO response received") from None
            if answer[0] == RESPONSE_ABORTED:
                if mux is None or answer[1:4] == mux:
                    code, = struct.unpack_from("<L", answer, 4)
                    raise SdoAbortedError(code)
            elif mask == 0 or (answer[0] & mask == value
                               and (value not in (0x40, 0x60) or answer[1:4] == mux)):
                return answer
            self.stray += 1


class EcuRemoteNode(canopen.RemoteNode):
    """canopen's `RemoteNode` with the `MatchingSdoClient`."""

    def add_sdo(self, rx_cobid: int, tx_cobid: int) -> SdoClient:
        client = MatchingSdoClient(rx_cobid, tx_cobid, self.object_dictionary)
        self.sdo_channels.append(client)
        if self.has_network():
            self.network.subscribe(client.tx_cobid, client.on_response)
        return client
