"""Modbus TCP, sans-IO: the MBAP header around the PDUs of :mod:`.modbus`, and a parser for each side.

The MBAP header (MODBUS Messaging on TCP/IP Implementation Guide V1.0b §3.1.3) is seven bytes: a transaction
id the server echoes, a protocol id (0 for Modbus), a length (the bytes that follow it: the unit id and the
PDU, so 2..254 for a PDU of at most 253 bytes, application protocol V1.1b3 §4.1) and the unit id. TCP
keeps the bytes in order and the length frames them, so unlike RTU nothing is guessed: a header that is not
Modbus's, or a PDU whose length does not fit its function, is a :class:`~.modbus.ModbusLengthError` and the
stream cannot be trusted until the connection's buffer is dropped (the parser drops it). The transaction id
tells a late reply (an exchange that already gave up) from the one awaited: it is consumed in silence and
counted (:attr:`MbapResponseParser.late`).
"""

from __future__ import annotations

import struct

from .modbus import (
    ModbusLengthError,
    ModbusUnitError,
    Request,
    Response,
    check_slave,
    decode_request_pdu,
    decode_response_pdu,
    request_pdu_length,
    response_pdu_length,
)

__all__ = ["ANY_UNIT", "MBAP_PORT", "MbapRequestParser", "MbapResponseParser", "mbap_frame"]

MBAP_PORT = 502  # the Modbus TCP port (Implementation Guide V1.0b §4.1.1)
HEADER = struct.Struct(">HHHB")  # transaction, protocol, length, unit
MAX_LENGTH = 254  # unit id + a PDU of at most 253 bytes
ANY_UNIT = 0xFF  # a device that is no gateway: unit id "not significant" (Implementation Guide §4.4.1.2)


def mbap_frame(transaction: int, unit: int, pdu: bytes) -> bytes:
    """One Modbus TCP ADU: the MBAP header and ``pdu``."""
    if (
        unit != 0xFF
    ):  # 0xFF: "not significant", for a device that is no gateway (Implementation Guide §4.4.1.2)
        check_slave(unit)
    if not 0 <= transaction <= 0xFFFF or not 1 <= len(pdu) <= MAX_LENGTH - 1:
        raise ValueError(f"MBAP: transaction {transaction} (0..65535), a PDU of 1..253 bytes")
    return HEADER.pack(transaction, 0, len(pdu) + 1, unit) + pdu


class _MbapParser:
    """Bytes in, ``(transaction, unit, pdu, raw)`` out, framed by the header's length."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.dropped = 0  # bytes dropped after a header that was not Modbus's

    def reset(self) -> None:
        self.dropped += len(self._buf)
        self._buf.clear()

    def pending(self) -> int:
        return len(self._buf)

    def _adus(self, data: bytes) -> list[tuple[int, int, bytes, bytes]]:
        buf = self._buf
        buf += data
        out = []
        while len(buf) >= HEADER.size:
            transaction, protocol, length, unit = HEADER.unpack_from(buf)
            if protocol != 0 or not 2 <= length <= MAX_LENGTH:
                head = bytes(buf[: HEADER.size]).hex(" ")
                self.reset()  # nothing after a false header can be framed: the stream is lost
                raise ModbusLengthError(
                    f"not a Modbus TCP header: {head} (protocol {protocol}, length {length})"
                )
            end = 6 + length
            if len(buf) < end:
                break
            raw = bytes(buf[:end])
            del buf[:end]
            out.append((transaction, unit, raw[HEADER.size :], raw))
        return out


class MbapRequestParser(_MbapParser):
    """The server's side: every request, whatever its unit id (the device decides whether it is its own).
    A PDU of a known function whose length does not fit is returned ``malformed`` (the device answers
    exception 03); an unknown function is returned as it is (the device answers exception 01)."""

    def feed(self, data: bytes) -> list[Request]:
        out = []
        for transaction, unit, pdu, raw in self._adus(data):
            if request_pdu_length(pdu) == len(pdu):
                out.append(decode_request_pdu(unit, pdu, raw, transaction))
            else:
                out.append(Request(unit, pdu[0], raw=raw, transaction=transaction, malformed=True))
        return out


class MbapResponseParser(_MbapParser):
    """The client's side: ``expect(transaction, function, count)`` names the one reply awaited; a reply of
    another transaction is late and dropped, one of this transaction from another unit id or of a length its
    function does not fit raises a typed error."""

    def __init__(self, unit: int | None) -> None:
        super().__init__()
        self.unit = unit  # None: any (a monitor)
        self.late = 0  # replies of another transaction, dropped
        self._expected: tuple[int, int, int] | None = None

    def expect(self, transaction: int, function: int, count: int) -> None:
        self._expected = (transaction, function, count)

    def feed(self, data: bytes) -> list[Response]:
        out = []
        for transaction, unit, pdu, raw in self._adus(data):
            function: int | None = None
            count = 0
            if self._expected is not None:
                awaited, function, count = self._expected
                if transaction != awaited:
                    self.late += 1
                    continue
            if response_pdu_length(pdu, function, count) != len(pdu):
                raise ModbusLengthError(f"a reply that does not fit its function: {raw.hex(' ')}")
            if self.unit is not None and unit != self.unit:
                raise ModbusUnitError(
                    f"unit {unit} answered transaction {transaction}, not {self.unit}", unit=unit
                )
            out.append(decode_response_pdu(unit, pdu, raw, transaction))
        return out
