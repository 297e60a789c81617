"""KUKAVARPROXY: the TCP protocol a KR C4 speaks to read and write KRL variables, and a client.

Written from the protocol itself.  Every integer is a big-endian uint16.

Read request::

    id (2) | length of the rest (2) | mode 0 (1) | name length (2) | name (ASCII)

Write request: the same with mode 1, then value length (2) and value (ASCII).

Reply::

    id (2, echoed) | length of the rest (2) | mode (1) | value length (2) | value (ASCII) | tail (3)

where the last tail byte is 1 on success and 0 on failure.  The real proxy answers *success with
an empty value* for an unknown variable, so an empty value is treated as an error here.

Values come back as KRL text: ``{E6AXIS: A1 0.0, A2 -90.0, ...}`` (degrees), ``12.5`` (REAL),
``42`` (INT), ``TRUE`` (BOOL), ``"text"`` (CHAR[]).  The parsers below never evaluate a returned
string; they match it against a small grammar and bound its size.

The client (:class:`KvpClient`) puts a timeout on every call, reconnects with exponential
back-off (:meth:`KvpClient.reconnect`) and checks liveness by reading the name ``PING``, which the
proxy answers ``PONG``.
"""
from __future__ import annotations

import re
import socket
import struct
import time
from typing import Any

from kukaid.errors import ControllerError

#: Default TCP port of KUKAVARPROXY.
DEFAULT_PORT = 7000
#: Largest value accepted by default, bytes (the protocol allows up to 65535 - 6).
MAX_VALUE_BYTES = 4096
#: Longest variable name accepted, characters.
MAX_NAME_BYTES = 255

MODE_READ = 0
MODE_WRITE = 1


class KvpError(ControllerError):
    """Base class of KUKAVARPROXY errors."""


class KvpConnectionError(KvpError):
    """The proxy could not be reached, or the connection dropped."""


class KvpTimeoutError(KvpConnectionError):
    """The proxy did not answer within the timeout."""


class KvpProtocolError(KvpError):
    """The proxy's reply does not follow the protocol (garbage, wrong id, wrong length)."""


class KvpVariableError(KvpError):
    """The proxy answered, but the variable could not be read or written (status 0, empty value)."""


class KvpValueError(KvpError):
    """A returned value does not parse as the KRL type it should have."""


# -- encoding ---------------------------------------------------------------------------------
def _ascii(text: str, what: str, limit: int) -> bytes:
    try:
        raw = text.encode("ascii")
    except UnicodeEncodeError:
        raise KvpError(f"{what} {text[:40]!r} is not ASCII") from None
    if len(raw) > limit:
        raise KvpError(f"{what} is {len(raw)} bytes long; at most {limit} allowed")
    return raw


def encode_read(msg_id: int, name: str) -> bytes:
    """Bytes of a read request for variable ``name`` with message id ``msg_id`` (0..65535)."""
    raw = _ascii(name, "variable name", MAX_NAME_BYTES)
    if not raw:
        raise KvpError("variable name is empty")
    body = struct.pack(">BH", MODE_READ, len(raw)) + raw
    return struct.pack(">HH", msg_id & 0xFFFF, len(body)) + body


def encode_write(msg_id: int, name: str, value: str) -> bytes:
    """Bytes of a write request setting ``name`` to the KRL text ``value``."""
    raw = _ascii(name, "variable name", MAX_NAME_BYTES)
    if not raw:
        raise KvpError("variable name is empty")
    val = _ascii(value, f"value for {name}", MAX_VALUE_BYTES)
    body = struct.pack(">BH", MODE_WRITE, len(raw)) + raw + struct.pack(">H", len(val)) + val
    return struct.pack(">HH", msg_id & 0xFFFF, len(body)) + body


def encode_reply(msg_id: int, mode: int, value: str | bytes, ok: bool = True) -> bytes:
    """Bytes of a reply (used by the virtual KR C4's server)."""
    val = value.encode("ascii") if isinstance(value, str) else bytes(value)
    body = struct.pack(">BH", mode, len(val)) + val + bytes((0, 1, 1 if ok else 0))
    return struct.pack(">HH", msg_id & 0xFFFF, len(body)) + body


def decode_request(body: bytes) -> tuple[int, str, str | None]:
    """Decode the part of a request after its 4 header bytes: (mode, name, value or None)."""
    if len(body) < 3:
        raise KvpProtocolError(f"request body of {len(body)} bytes is too short")
    mode, nlen = struct.unpack(">BH", body[:3])
    if mode not in (MODE_READ, MODE_WRITE):
        raise KvpProtocolError(f"request mode {mode} is neither 0 (read) nor 1 (write)")
    name_raw = body[3:3 + nlen]
    if len(name_raw) != nlen or nlen == 0:
        raise KvpProtocolError(f"request name length {nlen} does not fit the body ({len(body)} bytes)")
    try:
        name = name_raw.decode("ascii")
    except UnicodeDecodeError:
        raise KvpProtocolError("request name is not ASCII") from None
    rest = body[3 + nlen:]
    if mode == MODE_READ:
        if rest:
            raise KvpProtocolError(f"read request has {len(rest)} stray bytes after the name")
        return mode, name, None
    if len(rest) < 2:
        raise KvpProtocolError("write request has no value length")
    (vlen,) = struct.unpack(">H", rest[:2])
    if len(rest) != 2 + vlen:
        raise KvpProtocolError(f"write request value length {vlen} does not fit the body")
    try:
        value = rest[2:].decode("ascii")
    except UnicodeDecodeError:
        raise KvpProtocolError("write request value is not ASCII") from None
    return mode, name, value


def decode_reply_body(body: bytes, name: str = "?", max_value: int = MAX_VALUE_BYTES) -> tuple[int, str, bool]:
    """Decode the part of a reply after its 4 header bytes: (mode, value, success)."""
    if len(body) < 6:
        raise KvpProtocolError(f"reply to {name}: body of {len(body)} bytes is shorter than the 6-byte minimum")
    mode, vlen = struct.unpack(">BH", body[:3])
    if 3 + vlen + 3 != len(body):
        raise KvpProtocolError(
            f"reply to {name}: value length {vlen} does not match the message length {len(body)} "
            "(expected value length + 6)")
    if vlen > max_value:
        raise KvpProtocolError(f"reply to {name}: value of {vlen} bytes exceeds the {max_value}-byte limit")
    raw = body[3:3 + vlen]
    try:
        value = raw.decode("ascii")
    except UnicodeDecodeError:
        raise KvpProtocolError(f"reply to {name}: value contains non-ASCII bytes (garbage on the link?)") from None
    ok = body[-1] == 1
    return mode, value, ok


# -- KRL value parsing ------------------------------------------------------------------------
_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_NUM_RE = re.compile(rf"^\s*({_NUM})\s*$")
_INT_RE = re.compile(r"^\s*([+-]?\d+)\s*$")
_HEX_RE = re.compile(r"^\s*'H([0-9A-Fa-f]+)'\s*$")
_BIN_RE = re.compile(r"^\s*'B([01]+)'\s*$")
_IDENT = r"[A-Za-z_$][A-Za-z0-9_$]*"
_STRUCT_RE = re.compile(rf"^\s*\{{\s*(?:({_IDENT})\s*:)?(.*)\}}\s*$", re.S)
_FIELD_RE = re.compile(rf"^\s*({_IDENT})\s+(.+?)\s*$", re.S)
_ENUM_RE = re.compile(rf"^#{_IDENT}$")
_STR_RE = re.compile(r'^\s*"([^"]*)"\s*$', re.S)

E6AXIS_FIELDS = ("A1", "A2", "A3", "A4", "A5", "A6", "E1", "E2", "E3", "E4", "E5", "E6")


def _bound(text: str, what: str, max_len: int) -> str:
    if not isinstance(text, str):
        raise KvpValueError(f"{what}: expected text, got {type(text).__name__}")
    if len(text) > max_len:
        raise KvpValueError(f"{what}: value of {len(text)} characters exceeds the {max_len}-character limit")
    if not text.strip():
        raise KvpValueError(f"{what}: empty value")
    return text


def parse_real(text: str, what: str = "REAL", max_len: int = 64) -> float:
    """Parse a KRL REAL (``12.5``, ``-1.2E+02``); refuses nan, inf and anything else."""
    _bound(text, what, max_len)
    m = _NUM_RE.match(text)
    if not m:
        raise KvpValueError(f"{what}: {text[:40]!r} is not a number")
    return float(m.group(1))


def parse_int(text: str, what: str = "INT", max_len: int = 64) -> int:
    """Parse a KRL INT (decimal, ``'H1F'`` hexadecimal or ``'B101'`` binary)."""
    _bound(text, what, max_len)
    for rx, base in ((_INT_RE, 10), (_HEX_RE, 16), (_BIN_RE, 2)):
        m = rx.match(text)
        if m:
            return int(m.group(1), base)
    raise KvpValueError(f"{what}: {text[:40]!r} is not an integer")


def parse_bool(text: str, what: str = "BOOL", max_len: int = 16) -> bool:
    """Parse a KRL BOOL (``TRUE`` / ``FALSE``, any case)."""
    _bound(text, what, max_len)
    t = text.strip().upper()
    if t == "TRUE":
        return True
    if t == "FALSE":
        return False
    raise KvpValueError(f"{what}: {text[:40]!r} is not TRUE or FALSE")


def parse_string(text: str, what: str = "CHAR[]", max_len: int = MAX_VALUE_BYTES) -> str:
    """Parse a KRL string (``"text"``); the quotes are removed."""
    _bound(text, what, max_len)
    m = _STR_RE.match(text)
    if not m:
        raise KvpValueError(f"{what}: {text[:40]!r} is not a quoted string")
    return m.group(1)


def _parse_scalar(token: str, what: str) -> Any:
    if _NUM_RE.match(token):
        return float(token)
    up = token.upper()
    if up in ("TRUE", "FALSE"):
        return up == "TRUE"
    if _ENUM_RE.match(token):
        return token
    m = _STR_RE.match(token)
    if m:
        return m.group(1)
    raise KvpValueError(f"{what}: field value {token[:40]!r} is not a number, BOOL, #ENUM or string")


def parse_struct(text: str, what: str = "STRUC", max_len: int = 1024) -> tuple[str | None, dict[str, Any]]:
    """Parse a flat KRL structure ``{TYPE: F1 v1, F2 v2, ...}`` -> (TYPE or None, {field: value}).

    Numbers become floats, TRUE/FALSE bools, ``#NAME`` stays a string; nested structures and
    anything that is not a plain literal are refused.
    """
    _bound(text, what, max_len)
    m = _STRUCT_RE.match(text)
    if not m:
        raise KvpValueError(f"{what}: {text[:40]!r} is not a KRL structure {{...}}")
    typ, inner = m.group(1), m.group(2)
    if "{" in inner or "}" in inner:
        raise KvpValueError(f"{what}: nested structures are not supported")
    fields: dict[str, Any] = {}
    for part in inner.split(","):
        if not part.strip():
            continue
        fm = _FIELD_RE.match(part)
        if not fm:
            raise KvpValueError(f"{what}: field {part.strip()[:40]!r} is not 'NAME value'")
        key = fm.group(1).upper()
        if key in fields:
            raise KvpValueError(f"{what}: field {key} appears twice")
        fields[key] = _parse_scalar(fm.group(2), f"{what} field {key}")
    if not fields:
        raise KvpValueError(f"{what}: structure has no fields")
    return (typ.upper() if typ else None), fields


def parse_e6axis(text: str, what: str = "E6AXIS", max_len: int = 1024) -> dict[str, float]:
    """Parse an E6AXIS (or AXIS) value into {"A1": deg, ..., "A6": deg, "E1": deg, ...}.

    A1..A6 must be present and numeric; E1..E6 are kept when present.
    """
    typ, fields = parse_struct(text, what, max_len)
    if typ not in (None, "E6AXIS", "AXIS"):
        raise KvpValueError(f"{what}: structure type {typ} is not E6AXIS or AXIS")
    out: dict[str, float] = {}
    for k in E6AXIS_FIELDS:
        if k in fields:
            v = fields[k]
            if not isinstance(v, float):
                raise KvpValueError(f"{what}: field {k} is not a number")
            out[k] = v
        elif k.startswith("A"):
            raise KvpValueError(f"{what}: field {k} is missing")
    return out


def parse_e6pos(text: str, what: str = "E6POS", max_len: int = 1024) -> dict[str, Any]:
    """Parse an E6POS (or POS/FRAME) value: X, Y, Z (mm), A, B, C (deg), S, T, E1..E6."""
    typ, fields = parse_struct(text, what, max_len)
    if typ not in (None, "E6POS", "POS", "FRAME"):
        raise KvpValueError(f"{what}: structure type {typ} is not E6POS, POS or FRAME")
    for k in ("X", "Y", "Z", "A", "B", "C"):
        if not isinstance(fields.get(k), float):
            raise KvpValueError(f"{what}: field {k} is missing or not a number")
    return fields


def format_real(value: float, decimals: int = 6) -> str:
    """KRL text of a REAL (fixed point, ``decimals`` digits)."""
    v = float(value)
    if v != v or v in (float("inf"), float("-inf")):
        raise KvpValueError(f"cannot write a non-finite REAL ({value})")
    return f"{v:.{decimals}f}"


def format_e6axis(values_deg: dict[str, float], decimals: int = 6) -> str:
    """KRL text of an E6AXIS from {"A1": deg, ...}; missing axes are written as 0."""
    parts = [f"{k} {format_real(values_deg.get(k, 0.0), decimals)}" for k in E6AXIS_FIELDS]
    return "{E6AXIS: " + ", ".join(parts) + "}"


# -- client -----------------------------------------------------------------------------------
class KvpClient:
    """A KUKAVARPROXY client with timeouts, reconnection with back-off and liveness checks.

    Parameters
    ----------
    host, port : address of the proxy (port 7000 by default).
    timeout : s, limit on every request/reply exchange (also on connecting).
    max_value : largest reply value accepted, bytes.
    backoff : (first, largest) delay between reconnection attempts, s (doubles each attempt).

    Every error closes the connection when the byte stream can no longer be trusted (timeout,
    garbage, wrong id); the next call reconnects.  A variable error (status 0, empty value)
    leaves the connection open.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, timeout: float = 1.0,
                 max_value: int = MAX_VALUE_BYTES, backoff: tuple[float, float] = (0.05, 1.0)) -> None:
        self.host, self.port = host, int(port)
        self.timeout = float(timeout)
        self.max_value = int(max_value)
        self.backoff = backoff
        self._sock: socket.socket | None = None
        self._id = 0
        self.last_latency = float("nan")
        self.n_requests = 0
        self.n_reconnects = 0

    # -- connection ---------------------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self._sock is not None

    def connect(self) -> None:
        """Open the TCP connection (one attempt); raises :class:`KvpConnectionError`."""
        self.close()
        try:
            s = socket.create_connection((self.host, self.port), timeout=self.timeout)
        except socket.timeout:
            raise KvpTimeoutError(f"KUKAVARPROXY at {self.host}:{self.port}: no answer to connect "
                                  f"within {self.timeout:g} s") from None
        except OSError as e:
            raise KvpConnectionError(f"KUKAVARPROXY at {self.host}:{self.port}: cannot connect "
                                     f"({e.strerror or e})") from None
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = s

    def reconnect(self, max_wait: float = 10.0, should_stop=None) -> None:
        """Reconnect with exponential back-off until a PING is answered, for up to ``max_wait`` s.

        ``should_stop`` (optional callable) ends the attempts early (raises KvpConnectionError).
        """
        t_end = time.monotonic() + max_wait
        delay, cap = self.backoff
        last: Exception | None = None
        while True:
            try:
                self.connect()
                self.ping()
                self.n_reconnects += 1
                return
            except KvpError as e:
                last = e
                self.close()
            now = time.monotonic()
            if now >= t_end or (should_stop is not None and should_stop()):
                raise KvpConnectionError(f"KUKAVARPROXY at {self.host}:{self.port}: could not reconnect "
                                         f"within {max_wait:.3g} s ({last})")
            time.sleep(min(delay, max(t_end - now, 0.0)))
            delay = min(delay * 2.0, cap)

    def close(self) -> None:
        if self._sock is not None:
            try:
                self._sock.close()
            except OSError:
                pass
            self._sock = None

    def __enter__(self) -> "KvpClient":
        if self._sock is None:
            self.connect()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- exchange -----------------------------------------------------------------------------
    def _recv_exact(self, n: int, deadline: float, name: str) -> bytes:
        buf = bytearray()
        assert self._sock is not None
        while len(buf) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise KvpTimeoutError(f"KUKAVARPROXY at {self.host}:{self.port}: no complete reply to "
                                      f"{name} within {self.timeout:g} s")
            self._sock.settimeout(left)
            try:
                chunk = self._sock.recv(n - len(buf))
            except socket.timeout:
                continue
            except OSError as e:
                raise KvpConnectionError(f"KUKAVARPROXY at {self.host}:{self.port}: connection lost "
                                         f"while reading the reply to {name} ({e.strerror or e})") from None
            if not chunk:
                raise KvpConnectionError(f"KUKAVARPROXY at {self.host}:{self.port}: connection closed "
                                         f"by the proxy while waiting for the reply to {name}")
            buf += chunk
        return bytes(buf)

    def _exchange(self, request: bytes, msg_id: int, name: str) -> tuple[int, str, bool]:
        if self._sock is None:
            self.connect()
        assert self._sock is not None
        t0 = time.monotonic()
        deadline = t0 + self.timeout
        try:
            try:
                self._sock.settimeout(self.timeout)
                self._sock.sendall(request)
            except socket.timeout:
                raise KvpTimeoutError(f"KUKAVARPROXY at {self.host}:{self.port}: could not send the "
                                      f"request for {name} within {self.timeout:g} s") from None
            except OSError as e:
                raise KvpConnectionError(f"KUKAVARPROXY at {self.host}:{self.port}: connection lost "
                                         f"while sending the request for {name} ({e.strerror or e})") from None
            head = self._recv_exact(4, deadline, name)
            rid, length = struct.unpack(">HH", head)
            if rid != msg_id:
                text = head[:2].decode("ascii", "replace") if all(32 <= b < 127 for b in head) else ""
                hint = (f"; the reply starts with text ({text!r}...): not a KUKAVARPROXY server (a web server or "
                        "proxy at that address?)" if text else " (garbage or out-of-order reply)")
                raise KvpProtocolError(f"KUKAVARPROXY at {self.host}:{self.port}: reply to {name} has message "
                                       f"id {rid}, expected {msg_id}{hint}")
            if length < 6 or length > self.max_value + 6:
                raise KvpProtocolError(f"KUKAVARPROXY at {self.host}:{self.port}: reply to {name} announces "
                                       f"{length} bytes (allowed 6 to {self.max_value + 6})")
            body = self._recv_exact(length, deadline, name)
            mode, value, ok = decode_reply_body(body, name, self.max_value)
        except KvpError:
            self.close()  # the byte stream cannot be trusted any more
            raise
        self.last_latency = time.monotonic() - t0
        self.n_requests += 1
        return mode, value, ok

    def _next_id(self) -> int:
        self._id = (self._id + 1) & 0xFFFF
        return self._id

    def read(self, name: str) -> str:
        """Read variable ``name``; returns its KRL text.  Empty value or status 0 -> error."""
        msg_id = self._next_id()
        _, value, ok = self._exchange(encode_read(msg_id, name), msg_id, name)
        if not ok:
            raise KvpVariableError(f"KUKAVARPROXY: reading {name} failed (status 0)")
        if value == "":
            raise KvpVariableError(f"KUKAVARPROXY: {name} came back empty (unknown variable?)")
        return value

    def write(self, name: str, value: str) -> str:
        """Write the KRL text ``value`` to variable ``name``; returns the value the proxy echoes."""
        msg_id = self._next_id()
        _, echoed, ok = self._exchange(encode_write(msg_id, name, value), msg_id, name)
        if not ok:
            raise KvpVariableError(f"KUKAVARPROXY: writing {name} failed (status 0)")
        return echoed

    def ping(self) -> None:
        """Liveness check: the proxy answers ``PING`` with ``PONG``."""
        value = self.read("PING")
        if value.strip().strip('"') != "PONG":
            raise KvpProtocolError(f"KUKAVARPROXY at {self.host}:{self.port}: PING answered {value[:20]!r}, not PONG")

    # -- typed reads ----------------------------------------------------------------------------
    def read_real(self, name: str) -> float:
        return parse_real(self.read(name), name)

    def read_int(self, name: str) -> int:
        return parse_int(self.read(name), name)

    def read_bool(self, name: str) -> bool:
        return parse_bool(self.read(name), name)

    def read_string(self, name: str) -> str:
        return parse_string(self.read(name), name, self.max_value)

    def read_axis(self, name: str = "$AXIS_ACT_MEAS") -> dict[str, float]:
        """Read an E6AXIS variable: {"A1": deg, ...}."""
        return parse_e6axis(self.read(name), name)

    def read_pos(self, name: str = "$POS_ACT") -> dict[str, Any]:
        return parse_e6pos(self.read(name), name)
