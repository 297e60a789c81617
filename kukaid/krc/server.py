"""A virtual KR C4 that speaks KUKAVARPROXY.

:class:`KvpServer` is a threaded TCP server speaking the KUKAVARPROXY protocol
(:mod:`kukaid.krc.kvp`), bound to loopback by default, accepting up to 10 clients like the real
proxy.  What it serves comes from a pluggable *variable source* (anything with
``read(name) -> str | None`` and ``write(name, value) -> bool``):

- :class:`StaticSource`: a dictionary of KRL texts (tests, globals);
- :class:`kukaid.krc.sim_source.SimSource`: the virtual KR C4 run in real time (:func:`serve_sim`
  starts both).

Faults for tests (:class:`Faults`, changeable while running): slow replies, replies split into
single bytes, a dropped connection, garbage bytes, empty values or status 0 for chosen names, and
an outage (:meth:`KvpServer.go_down`) during which connections are refused.

Like the real proxy, an unknown variable is answered with success and an empty value.
"""
from __future__ import annotations

import socket
import struct
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Protocol

from kukaid.krc.kvp import (DEFAULT_PORT, MAX_NAME_BYTES, MAX_VALUE_BYTES, MODE_READ, KvpProtocolError,
                           decode_request, encode_reply)
from kukaid.krc.sim_source import SimSource

class VariableSource(Protocol):
    def read(self, name: str) -> str | None: ...

    def write(self, name: str, value: str) -> bool: ...


class StaticSource:
    """Variables from a dictionary of KRL texts; names are case-insensitive, all writable."""

    def __init__(self, values: dict[str, str] | None = None) -> None:
        self._lock = threading.Lock()
        self.values = {k.upper(): v for k, v in (values or {}).items()}
        self.writes: list[tuple[str, str]] = []

    def read(self, name: str) -> str | None:
        with self._lock:
            return self.values.get(name.upper())

    def write(self, name: str, value: str) -> bool:
        with self._lock:
            self.values[name.upper()] = value
            self.writes.append((name.upper(), value))
        return True


@dataclass
class Faults:
    """Faults the server injects (all off by default); fields may be changed while it runs.

    delay : s added before every reply (slow controller).
    split : send every reply one byte at a time (tests reassembly).
    empty : names answered with success and an empty value.
    fail : names answered with status 0.
    garbage : number of upcoming replies replaced by garbage bytes.
    drop : number of upcoming requests answered by closing the connection instead.
    """

    delay: float = 0.0
    split: bool = False
    empty: set[str] = field(default_factory=set)
    fail: set[str] = field(default_factory=set)
    garbage: int = 0
    drop: int = 0


class KvpServer:
    """KUKAVARPROXY server over ``source``.  Use as a context manager or call start()/stop().

    Parameters
    ----------
    source : the variable source.
    host : interface to bind; loopback by default (a real controller network is explicit).
    port : TCP port; 0 picks a free port (see :attr:`port` after start).
    max_clients : simultaneous connections (the real proxy accepts 10).
    faults : fault injection (:class:`Faults`).
    """

    def __init__(self, source: VariableSource, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 max_clients: int = 10, faults: Faults | None = None) -> None:
        self.source = source
        self.host = host
        self.requested_port = int(port)
        self.max_clients = int(max_clients)
        self.faults = faults or Faults()
        self._lsock: socket.socket | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._clients: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._down_until = 0.0
        self._bound_port = 0
        self.n_requests = 0
        self.n_refused = 0
        self.n_connections = 0

    # -- lifecycle ----------------------------------------------------------------------------
    @property
    def port(self) -> int:
        return self._bound_port or self.requested_port

    def start(self) -> "KvpServer":
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((self.host, self.requested_port))
        except OSError as e:
            s.close()
            from kukaid.errors import ControllerError
            raise ControllerError(f"serve-sim: cannot listen on {self.host}:{self.requested_port} "
                                  f"({e.strerror or e})") from None
        s.listen(16)
        s.settimeout(0.1)
        self._bound_port = s.getsockname()[1]
        self._lsock = s
        t = threading.Thread(target=self._accept_loop, name="kvp-accept", daemon=True)
        t.start()
        self._threads.append(t)
        return self

    def stop(self) -> None:
        self._stop.set()
        self.drop_clients()
        if self._lsock is not None:
            try:
                self._lsock.close()
            except OSError:
                pass
        for t in list(self._threads):
            if t is not threading.current_thread():
                t.join(timeout=2.0)
        self._threads.clear()

    def __enter__(self) -> "KvpServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def drop_clients(self) -> None:
        """Close every client connection now (a dropped link)."""
        with self._lock:
            clients = list(self._clients)
            self._clients.clear()
        for c in clients:
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            try:
                c.close()
            except OSError:
                pass

    def go_down(self, seconds: float) -> None:
        """Drop every client and refuse connections for ``seconds`` (the controller goes away)."""
        self._down_until = time.monotonic() + seconds
        self.drop_clients()

    @property
    def n_clients(self) -> int:
        with self._lock:
            return len(self._clients)

    # -- serving ------------------------------------------------------------------------------
    def _accept_loop(self) -> None:
        assert self._lsock is not None
        while not self._stop.is_set():
            try:
                conn, _ = self._lsock.accept()
            except socket.timeout:
                continue
            except OSError:
                break
            with self._lock:
                full = len(self._clients) >= self.max_clients
            if full or time.monotonic() < self._down_until:
                self.n_refused += 1
                conn.close()
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.settimeout(0.2)
            with self._lock:
                self._clients.add(conn)
            self.n_connections += 1
            t = threading.Thread(target=self._serve_client, args=(conn,), name="kvp-client", daemon=True)
            t.start()
            self._threads = [x for x in self._threads if x.is_alive()] + [t]

    def _recv_exact(self, conn: socket.socket, n: int) -> bytes | None:
        buf = bytearray()
        while len(buf) < n:
            if self._stop.is_set():
                return None
            try:
                chunk = conn.recv(n - len(buf))
            except socket.timeout:
                continue
            except OSError:
                return None
            if not chunk:
                return None
            buf += chunk
        return bytes(buf)

    def _serve_client(self, conn: socket.socket) -> None:
        try:
            while not self._stop.is_set():
                head = self._recv_exact(conn, 4)
                if head is None:
                    return
                msg_id, length = struct.unpack(">HH", head)
                if length < 4 or length > 3 + MAX_NAME_BYTES + 2 + MAX_VALUE_BYTES:
                    return  # not a KUKAVARPROXY client: hang up
                body = self._recv_exact(conn, length)
                if body is None:
                    return
                try:
                    mode, name, value = decode_request(body)
                except KvpProtocolError:
                    return
                self.n_requests += 1
                reply = self._answer(msg_id, mode, name.strip(), value)
                if reply is None:
                    return
                if not self._send(conn, reply):
                    return
        finally:
            with self._lock:
                self._clients.discard(conn)
            try:
                conn.close()
            except OSError:
                pass

    def _answer(self, msg_id: int, mode: int, name: str, value: str | None) -> bytes | None:
        f = self.faults
        if f.drop > 0:
            f.drop -= 1
            return None
        if f.delay > 0:
            time.sleep(f.delay)
        if f.garbage > 0:
            f.garbage -= 1
            return b"\xde\xad\xff\xff\xff\x13garbage\x00\x01" * 3  # wrong id, impossible length
        key = name.upper()
        if key in {n.upper() for n in f.fail}:
            return encode_reply(msg_id, mode, "", ok=False)
        if key in {n.upper() for n in f.empty}:
            return encode_reply(msg_id, mode, "", ok=True)
        if mode == MODE_READ:
            if key == "PING":
                return encode_reply(msg_id, mode, "PONG")
            try:
                text = self.source.read(key)
            except Exception:  # a broken source must not kill the server
                return encode_reply(msg_id, mode, "", ok=False)
            if text is None:
                return encode_reply(msg_id, mode, "", ok=True)  # unknown variable, like the real proxy
            raw = text.encode("ascii", "replace")[:MAX_VALUE_BYTES]
            return encode_reply(msg_id, mode, raw, ok=True)
        assert value is not None
        try:
            ok = bool(self.source.write(key, value))
        except Exception:
            ok = False
        return encode_reply(msg_id, mode, value if ok else "", ok=ok)

    def _send(self, conn: socket.socket, data: bytes) -> bool:
        try:
            if self.faults.split:
                for i in range(len(data)):
                    conn.sendall(data[i:i + 1])
                    time.sleep(0.0002)
            else:
                conn.sendall(data)
            return True
        except OSError:
            return False


def serve_sim(sim: Any, host: str = "127.0.0.1", port: int = DEFAULT_PORT, axis: int = 3,
              trajectory: Any = None, speed: float = 1.0, ring: Any = None,
              faults: Faults | None = None, follower: Any = None) -> tuple[KvpServer, SimSource]:
    """Start a virtual KR C4 on ``host:port``; returns (server, source), both running.

    Stop with ``server.stop(); source.stop()``.
    """
    source = SimSource(sim, axis=axis, trajectory=trajectory, speed=speed, ring=ring, follower=follower).start()
    try:
        server = KvpServer(source, host=host, port=port, faults=faults).start()
    except BaseException:
        source.stop()
        raise
    return server, source

