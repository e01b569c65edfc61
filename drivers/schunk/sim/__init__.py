"""The simulated SCHUNK unit: :class:`SchunkModel` (pure, simulated time) served by the backend kit's
``SimServer``: its web API on loopback TCP (``http://HOST:PORT``), or Modbus RTU on a pseudo-terminal."""

from __future__ import annotations

from ...simkit import SimServer
from ...urls import format_host, on_transport, parse_url
from ..protocol import ERR_FAST_STOP
from .model import ModuleSpec, SchunkModel
from .web import WebSession

__all__ = ["ModuleSpec", "SchunkModel", "SchunkServer", "serve"]


class SchunkServer(SimServer):
    """A unit's simulator: ``.model``, ``.url`` (``schunk+http://HOST:PORT`` or ``schunk+serial://PATH``),
    the kit's clock and fault hooks, and the unit's own faults (:meth:`inject_error`,
    :meth:`lose_connection`)."""

    model: SchunkModel

    def inject_error(self, code: int = 0xEF) -> None:
        with self.lock:
            self.model.advance(self.now())
            self.model.inject_error(code)

    def fast_stop(self) -> None:
        """The unit in fast stop (0xD9), as at power-up or after an e-stop by another program."""
        self.inject_error(ERR_FAST_STOP)

    def lose_connection(self, seconds: float) -> None:
        """The unit unreachable behind its web server (HTTP 503) for ``seconds`` of simulated time."""
        with self.lock:
            self._unreachable[0] = self.now() + seconds

    _unreachable: list[float]


def serve(model: SchunkModel, listen: str, *, time_scale: float = 1.0, slave: int = 12) -> SchunkServer:
    """Serve ``model`` where ``listen`` says: ``http://HOST:PORT`` (or ``tcp://``; port 0: a free one) for
    the web API, ``pty`` for Modbus RTU on a pseudo-terminal (``slave``: its device id)."""
    unreachable = [0.0]
    if listen in ("pty", "serial"):
        from ...modbus_sim import ModbusFaults, ModbusSession
        from .rtu import SchunkRegisters

        model.slave_id = slave
        registers, faults = SchunkRegisters(model, slave), ModbusFaults()
        server = SchunkServer(
            "pty",
            lambda: ModbusSession(registers, "rtu", faults),
            family="schunk",
            time_scale=time_scale,
            advance=model.advance,
            faults=faults,
        )
        if slave != 12:
            server.url += f"?slave={slave}"
    else:
        where = parse_url(on_transport(listen, {"http": "tcp"})[0], bare_family="schunk", listen=True)
        host = where.host or "127.0.0.1"
        tcp = f"tcp://{format_host(host, where.port or 0)}"
        server = SchunkServer(
            tcp,
            lambda: WebSession(model, unreachable),
            family="schunk",
            time_scale=time_scale,
            advance=model.advance,
        )
        server.url = f"schunk+http://{format_host(host, server.port)}"
    server.model = model
    server._unreachable = unreachable
    return server
