"""KUKAVARPROXY protocol: byte-exact requests and replies, reassembly, error cases, KRL values."""
from __future__ import annotations

import socket
import struct
import threading
import time

import pytest

from kukaid.errors import ControllerError
from kukaid.krc.kvp import (KvpClient, KvpConnectionError, KvpProtocolError, KvpTimeoutError, KvpValueError,
                           KvpVariableError, decode_reply_body, decode_request, encode_read, encode_reply,
                           encode_write, format_e6axis, parse_bool, parse_e6axis, parse_e6pos, parse_int,
                           parse_real, parse_string, parse_struct)


# -- byte-exact encoding -----------------------------------------------------------------------
def test_read_request_ov_pro_is_byte_exact():
    assert encode_read(1, "$OV_PRO") == bytes.fromhex("00 01 00 0A 00 00 07 24 4F 56 5F 50 52 4F")


def test_write_request_is_byte_exact():
    # id 0x0102, mode 1, name "$OV_PRO" (7), value "50" (2): rest = 1 + 2 + 7 + 2 + 2 = 14
    assert encode_write(0x0102, "$OV_PRO", "50") == bytes.fromhex(
        "01 02 00 0E 01 00 07 24 4F 56 5F 50 52 4F 00 02 35 30")


def test_reply_is_byte_exact_and_decodes():
    raw = encode_reply(1, 0, "100", ok=True)
    assert raw == bytes.fromhex("00 01 00 09 00 00 03 31 30 30 00 01 01")
    assert decode_reply_body(raw[4:]) == (0, "100", True)
    assert encode_reply(7, 0, "", ok=False) == bytes.fromhex("00 07 00 06 00 00 00 00 01 00")


def test_request_round_trip_and_id_wraps():
    mode, name, value = decode_request(encode_write(65535, "KID_RD", "17")[4:])
    assert (mode, name, value) == (1, "KID_RD", "17")
    assert encode_read(65536 + 5, "X")[:2] == b"\x00\x05"


def test_request_rejects_non_ascii_and_empty_names():
    with pytest.raises(ControllerError, match="not ASCII"):
        encode_read(1, "$ÄXIS")
    with pytest.raises(ControllerError, match="empty"):
        encode_read(1, "")


def test_reply_body_length_mismatch_is_a_protocol_error():
    body = encode_reply(1, 0, "12.5")[4:]
    with pytest.raises(KvpProtocolError, match="does not match"):
        decode_reply_body(body[:-1] + b"\x01\x01")
    with pytest.raises(KvpProtocolError, match="shorter"):
        decode_reply_body(b"\x00\x00")


# -- a scripted proxy --------------------------------------------------------------------------
class Scripted:
    """One-connection TCP server on 127.0.0.1:0; ``script(request_index, msg_id)`` -> chunks to send."""

    def __init__(self, script):
        self.script = script
        self.lsock = socket.socket()
        self.lsock.bind(("127.0.0.1", 0))
        self.lsock.listen(1)
        self.lsock.settimeout(5)
        self.port = self.lsock.getsockname()[1]
        self.requests: list[bytes] = []
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        try:
            conn, _ = self.lsock.accept()
        except OSError:
            return
        conn.settimeout(5)
        with conn:
            i = 0
            while True:
                try:
                    head = conn.recv(4)
                    if len(head) < 4:
                        return
                    (length,) = struct.unpack(">H", head[2:])
                    body = b""
                    while len(body) < length:
                        body += conn.recv(length - len(body))
                except OSError:
                    return
                self.requests.append(head + body)
                msg_id = struct.unpack(">H", head[:2])[0]
                for chunk in self.script(i, msg_id):
                    if chunk is None:
                        return  # hang up
                    if isinstance(chunk, float):
                        time.sleep(chunk)
                        continue
                    conn.sendall(chunk)
                i += 1

    def close(self):
        self.lsock.close()
        self.thread.join(timeout=5)


@pytest.fixture
def scripted():
    servers = []

    def make(script):
        s = Scripted(script)
        servers.append(s)
        return s

    yield make
    for s in servers:
        s.close()


def test_client_sends_exact_bytes_and_reads_value(scripted):
    srv = scripted(lambda i, mid: [encode_reply(mid, 0, "100")])
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        assert c.read("$OV_PRO") == "100"
    assert srv.requests[0] == bytes.fromhex("00 01 00 0A 00 00 07 24 4F 56 5F 50 52 4F")


def test_split_reply_is_reassembled(scripted):
    def script(i, mid):
        raw = encode_reply(mid, 0, "{E6AXIS: A1 1.5, A2 -90.0, A3 90.0, A4 0.0, A5 0.0, A6 0.0}")
        out = []
        for b in raw:  # one byte at a time, with pauses
            out += [bytes((b,)), 0.001]
        return out

    srv = scripted(script)
    with KvpClient("127.0.0.1", srv.port, timeout=3) as c:
        ax = c.read_axis("$AXIS_ACT_MEAS")
    assert ax["A1"] == 1.5 and ax["A2"] == -90.0


def test_coalesced_replies_are_separated(scripted):
    def script(i, mid):
        if i == 0:  # both replies in one segment
            return [encode_reply(mid, 0, "1.25") + encode_reply(mid + 1, 0, "-3.5")]
        return []

    srv = scripted(script)
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        assert c.read_real("$TORQUE_AXIS_ACT[3]") == 1.25
        assert c.read_real("$TORQUE_AXIS_ACT[2]") == -3.5


def test_wrong_id_is_refused_and_connection_reset(scripted):
    srv = scripted(lambda i, mid: [encode_reply(mid + 7, 0, "100")])
    c = KvpClient("127.0.0.1", srv.port, timeout=2)
    with pytest.raises(KvpProtocolError, match="message id 8, expected 1"):
        c.read("$OV_PRO")
    assert not c.connected  # the stream cannot be trusted any more


def test_status_zero_is_an_error(scripted):
    srv = scripted(lambda i, mid: [encode_reply(mid, 0, "", ok=False)])
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        with pytest.raises(KvpVariableError, match="status 0"):
            c.read("$NO_SUCH")
        assert c.connected  # a variable error keeps the link


def test_empty_value_is_an_error(scripted):
    srv = scripted(lambda i, mid: [encode_reply(mid, 0, "", ok=True)])
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        with pytest.raises(KvpVariableError, match="empty"):
            c.read("$UNKNOWN_VAR")


def test_oversize_value_is_refused(scripted):
    srv = scripted(lambda i, mid: [encode_reply(mid, 0, "9" * 300)])
    c = KvpClient("127.0.0.1", srv.port, timeout=2, max_value=256)
    with pytest.raises(KvpProtocolError, match="announces 306 bytes"):
        c.read("BIG")


def test_garbage_bytes_give_a_clear_error(scripted):
    srv = scripted(lambda i, mid: [b"\xde\xad\xbe\xef garbage \x00\xff" * 4])
    c = KvpClient("127.0.0.1", srv.port, timeout=1)
    with pytest.raises(KvpProtocolError, match="message id"):
        c.read("$OV_PRO")
    web = scripted(lambda i, mid: [b"HTTP/1.1 400 Bad Request\r\n\r\n"])  # a web server or proxy at that address
    with pytest.raises(KvpProtocolError, match="not a KUKAVARPROXY server"):
        KvpClient("127.0.0.1", web.port, timeout=1).read("$OV_PRO")


def test_non_ascii_value_is_a_protocol_error(scripted):
    srv = scripted(lambda i, mid: [encode_reply(mid, 0, b"12\xff5")])
    c = KvpClient("127.0.0.1", srv.port, timeout=1)
    with pytest.raises(KvpProtocolError, match="non-ASCII"):
        c.read("$OV_PRO")


def test_slow_reply_times_out(scripted):
    srv = scripted(lambda i, mid: [0.5, encode_reply(mid, 0, "100")])
    c = KvpClient("127.0.0.1", srv.port, timeout=0.1)
    with pytest.raises(KvpTimeoutError, match="within 0.1 s"):
        c.read("$OV_PRO")


def test_hang_up_is_a_connection_error(scripted):
    srv = scripted(lambda i, mid: [None])
    c = KvpClient("127.0.0.1", srv.port, timeout=1)
    with pytest.raises(KvpConnectionError, match="closed"):
        c.read("$OV_PRO")


def test_connection_refused_is_a_clear_error():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(KvpConnectionError, match=f"127.0.0.1:{port}: cannot connect"):
        KvpClient("127.0.0.1", port, timeout=0.5).connect()


def test_write_returns_echo_and_ping(scripted):
    def script(i, mid):
        return [encode_reply(mid, 1 if i == 0 else 0, "5" if i == 0 else "PONG")]

    srv = scripted(script)
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        assert c.write("KID_RD", "5") == "5"
        c.ping()
    assert srv.requests[0][4] == 1


# -- KRL values --------------------------------------------------------------------------------
def test_parse_e6axis():
    text = "{E6AXIS: A1 0.0, A2 -90.0, A3 90.0, A4 0.0, A5 0.0, A6 0.0, E1 0.0, E2 0.0, E3 0.0, E4 0.0, E5 0.0, E6 0.0}"
    ax = parse_e6axis(text)
    assert ax["A2"] == -90.0 and ax["A3"] == 90.0 and ax["E6"] == 0.0 and len(ax) == 12
    assert parse_e6axis(format_e6axis({"A3": 12.3456})) ["A3"] == 12.3456
    assert parse_e6axis("{A1 1, A2 2, A3 3.5E+01, A4 4, A5 5, A6 -6.}")["A3"] == 35.0


def test_parse_e6axis_refuses_bad_input():
    with pytest.raises(KvpValueError, match="A6 is missing"):
        parse_e6axis("{E6AXIS: A1 0.0, A2 0.0, A3 0.0, A4 0.0, A5 0.0}")
    with pytest.raises(KvpValueError, match="not a number"):
        parse_e6axis("{E6AXIS: A1 __import__('os'), A2 0, A3 0, A4 0, A5 0, A6 0}")
    with pytest.raises(KvpValueError, match="nested"):
        parse_struct("{A {B 1}}")
    with pytest.raises(KvpValueError, match="exceeds"):
        parse_e6axis("{A1 " + "1" * 5000 + "}")
    with pytest.raises(KvpValueError, match="not E6AXIS"):
        parse_e6axis("{E6POS: X 1, Y 2, Z 3, A 0, B 0, C 0}")
    with pytest.raises(KvpValueError, match="twice"):
        parse_struct("{A1 1, A1 2}")


def test_parse_e6pos_and_scalars():
    pos = parse_e6pos('{E6POS: X 100.5, Y -2, Z 300, A 0, B 90, C 0, S 2, T 35, E1 0}')
    assert pos["X"] == 100.5 and pos["S"] == 2.0
    assert parse_real(" -1.25E+02 ") == -125.0
    for bad in ("nan", "inf", "1_000", "0x10", "", "1.2.3", "1e5e5"):
        with pytest.raises(KvpValueError):
            parse_real(bad)
    assert parse_int("42") == 42 and parse_int("'H1F'") == 31 and parse_int("'B101'") == 5
    with pytest.raises(KvpValueError):
        parse_int("4.2")
    assert parse_bool("TRUE") is True and parse_bool("false") is False
    with pytest.raises(KvpValueError):
        parse_bool("1")
    assert parse_string('"kukaid-ring/1 axes=3"') == "kukaid-ring/1 axes=3"
    assert parse_struct("{MYSTRUC: MODE #FAST, ON TRUE, NAME \"x\"}") == (
        "MYSTRUC", {"MODE": "#FAST", "ON": True, "NAME": "x"})


# -- properties ----------------------------------------------------------------------------------
from hypothesis import given, settings, strategies as st  # noqa: E402

_printable = st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), min_size=1, max_size=60)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(msg_id=st.integers(0, 65535), name=_printable, value=st.one_of(st.none(), _printable), ok=st.booleans())
def test_encode_decode_round_trip(msg_id, name, value, ok):
    req = encode_read(msg_id, name) if value is None else encode_write(msg_id, name, value)
    rid, length = struct.unpack(">HH", req[:4])
    assert rid == msg_id and length == len(req) - 4
    assert decode_request(req[4:]) == ((0, name, None) if value is None else (1, name, value))
    rep = encode_reply(msg_id, 0 if value is None else 1, value or "", ok)
    assert struct.unpack(">HH", rep[:4]) == (msg_id, len(rep) - 4)
    assert decode_reply_body(rep[4:]) == (0 if value is None else 1, value or "", ok)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(x=st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6))
def test_real_and_e6axis_text_round_trip(x):
    from kukaid.krc.kvp import format_real

    assert parse_real(format_real(x)) == pytest.approx(x, abs=1e-6)
    assert parse_e6axis(format_e6axis({"A3": x}))["A3"] == pytest.approx(x, abs=1e-6)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(text=st.text(max_size=200))
def test_value_parsers_never_crash_on_arbitrary_text(text):
    for fn in (parse_real, parse_int, parse_bool, parse_string, parse_e6axis, parse_e6pos):
        try:
            fn(text)
        except KvpValueError:
            pass
