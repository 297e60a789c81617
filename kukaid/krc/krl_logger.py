"""The KRL ring-buffer logger: exact 12 ms sampling on the controller, read in blocks over KUKAVARPROXY.

Polling ``$AXIS_ACT_MEAS`` and ``$TORQUE_AXIS_ACT[i]`` from a PC loses samples to network
jitter.  Instead, a SUB (submit-interpreter) program on the KR C4 samples ``$AXIS_ACT_MEAS``,
``$TORQUE_AXIS_ACT[i]`` and ``$MOT_TEMP[i]`` every interpolation cycle (12 ms, timed with the
millisecond counter ``$ROB_TIMER``), formats each sample as text into the current block, and
publishes full blocks in a ring of global CHAR arrays.  ``kukaid capture --backend kvp --mode
ring`` reads the blocks through KUKAVARPROXY and acknowledges them.

Handshake (global variables, declared in ``KUKAID_LOG.DAT``):

- ``KID_CFG[]``  CHAR: ``"kukaid-ring/1 axes=3 nb=8 bs=8"`` (layout; read once by capture);
- ``KID_B1[]`` .. ``KID_B{nb}[]`` CHAR: the ring slots; block ``k`` (counting from 1) lives in slot
  ``(k - 1) MOD nb + 1`` and reads ``"k|T,q..,tau..,temp..;T,...;"``;
- ``KID_WR`` INT: number of blocks published by the logger (only the logger writes it);
- ``KID_RD`` INT: number of blocks consumed by the PC -- **the only variable capture writes**
  (besides nothing else: capture is read-only towards the robot in every other respect);
- ``KID_OVF`` INT: blocks dropped because the ring was full (the PC fell behind); the gap is
  visible in the ``$ROB_TIMER`` stamps and marked in the log.

Sample text: ``T`` = ``$ROB_TIMER`` (ms, INT), then per logged axis the position (degrees,
4 decimals), then per axis the torque (N·m, 3 decimals), then per axis the motor temperature
(as ``$MOT_TEMP`` gives it, 1 decimal), comma separated, ended by ``;``.

The virtual KR C4 (``kukaid serve-sim``) emulates this program exactly (same variables, same
text), so the capture side is tested end to end.  The KRL text itself is generated here; it has
not been run on a physical controller by the toolkit's tests (check SWRITE formats on your KSS).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from kukaid.errors import ControllerError, KukaidError

SCHEMA = "kukaid-ring/1"
IPO_MS = 12
#: decimals of position (deg), torque (N·m) and temperature in the sample text
DECIMALS = (4, 3, 1)


@dataclass(frozen=True)
class RingLayout:
    """Layout of the ring buffer: logged axes, number of blocks ``nb``, samples per block ``bs``."""

    axes: tuple[int, ...] = (3,)
    nb: int = 8
    bs: int = 8

    def __post_init__(self) -> None:
        axes = tuple(int(a) for a in self.axes)
        if not axes or len(set(axes)) != len(axes) or not all(1 <= a <= 6 for a in axes):
            raise KukaidError(f"KRL logger: axes must be distinct robot axes 1 to 6; got {list(axes)}")
        if not 2 <= self.nb <= 32:
            raise KukaidError(f"KRL logger: number of blocks must be 2 to 32; got {self.nb}")
        if not 1 <= self.bs <= 32:
            raise KukaidError(f"KRL logger: samples per block must be 1 to 32; got {self.bs}")
        object.__setattr__(self, "axes", axes)
        if self.block_chars > 4000:
            raise KukaidError(f"KRL logger: a block of {self.bs} samples of {len(axes)} axes needs "
                              f"{self.block_chars} characters, more than the 4000 one KUKAVARPROXY reply "
                              f"carries here; use fewer samples per block (at most "
                              f"{(4000 - 8) // self.sample_chars})")

    @property
    def sample_chars(self) -> int:
        """Upper bound of the text length of one sample."""
        return 11 + len(self.axes) * (11 + 10 + 7)

    @property
    def block_chars(self) -> int:
        """Size of one ring slot (CHAR array), characters."""
        return 8 + self.bs * self.sample_chars

    def config_text(self) -> str:
        return f"{SCHEMA} axes={','.join(map(str, self.axes))} nb={self.nb} bs={self.bs}"


_CFG_RE = re.compile(r"^kukaid-ring/1 axes=([0-9,]+) nb=(\d+) bs=(\d+)$")


def parse_config(text: str) -> RingLayout:
    """Parse ``KID_CFG`` (without quotes) into a :class:`RingLayout`."""
    m = _CFG_RE.match(text.strip())
    if not m:
        raise ControllerError(f"KRL logger: KID_CFG is {text[:60]!r}, not a {SCHEMA} layout "
                              "(is the kukaid logger SUB program installed and running?)")
    axes = tuple(int(a) for a in m.group(1).split(",") if a)
    return RingLayout(axes=axes, nb=int(m.group(2)), bs=int(m.group(3)))


def format_sample(timer_ms: int, q_deg: Iterable[float], tau: Iterable[float], temp: Iterable[float]) -> str:
    """Text of one sample exactly as the SUB program writes it (used by the virtual KR C4)."""
    dq, dt, dc = DECIMALS
    parts = [str(int(timer_ms))]
    parts += [f"{v:.{dq}f}" for v in q_deg]
    parts += [f"{v:.{dt}f}" for v in tau]
    parts += [f"{v:.{dc}f}" for v in temp]
    return ",".join(parts) + ";"


def slot_name(k: int, layout: RingLayout) -> str:
    """Global variable holding block number ``k`` (k >= 1)."""
    return f"KID_B{(k - 1) % layout.nb + 1}"


def parse_block(text: str, k: int, layout: RingLayout) -> np.ndarray:
    """Parse block ``k`` -> array (n, 1 + 3A): timer ms, q deg (A), tau (A), temp (A).

    Raises ControllerError naming the block and sample when the text is malformed or the block
    number does not match (the slot was overwritten).
    """
    head, sep, body = text.partition("|")
    if not sep or not head.strip().isdigit():
        raise ControllerError(f"KRL logger: block {k} ({slot_name(k, layout)}) has no 'k|' header")
    if int(head) != k:
        raise ControllerError(f"KRL logger: slot {slot_name(k, layout)} holds block {int(head)}, expected {k} "
                              "(the ring was overwritten)")
    a = len(layout.axes)
    rows = []
    for j, s in enumerate(x for x in body.split(";") if x.strip()):
        fields = s.split(",")
        if len(fields) != 1 + 3 * a:
            raise ControllerError(f"KRL logger: block {k} sample {j + 1} has {len(fields)} fields, "
                                  f"expected {1 + 3 * a}")
        try:
            vals = [float(f) for f in fields]
        except ValueError:
            raise ControllerError(f"KRL logger: block {k} sample {j + 1} is not numeric: {s[:60]!r}") from None
        if not np.all(np.isfinite(vals)):
            raise ControllerError(f"KRL logger: block {k} sample {j + 1} has a non-finite value")
        rows.append(vals)
    if len(rows) > layout.bs:
        raise ControllerError(f"KRL logger: block {k} has {len(rows)} samples, more than bs={layout.bs}")
    return np.asarray(rows, dtype=float).reshape(-1, 1 + 3 * a)


# -- KRL text ---------------------------------------------------------------------------------
def krl_logger_files(layout: RingLayout, name: str = "KUKAID_LOG") -> dict[str, str]:
    """KRL files of the logger: ``{NAME}.DAT`` (globals) and ``{NAME}.SUB`` (the submit program).

    Install both in ``KRC:\\R1\\Program``, select ``{NAME}.SUB`` as an extra submit interpreter
    (or call ``KID_SAMPLE()`` from the cyclic part of ``SPS.SUB``), and make KUKAVARPROXY
    available.  Capture reads ``KID_CFG``, ``KID_WR``, the slots, ``KID_OVF``, and writes
    ``KID_RD`` only.
    """
    n = name.upper()
    a = len(layout.axes)
    dq, dt, dc = DECIMALS
    fmts = ["%d"] + [f",%.{dq}f"] * a + [f",%.{dt}f"] * a + [f",%.{dc}f"] * a
    vals = ["$ROB_TIMER"]
    vals += [f"$AXIS_ACT_MEAS.A{ax}" for ax in layout.axes]
    vals += [f"$TORQUE_AXIS_ACT[{ax}]" for ax in layout.axes]
    vals += [f"$MOT_TEMP[{ax}]" for ax in layout.axes]
    # SWRITE takes at most 10 variables: a sample of 4 to 6 axes is written by consecutive SWRITEs (the
    # offset runs on), ended by ';'
    writes = [f"  SWRITE(KID_CUR[],KID_ST,KID_OFS,\"{''.join(fmts[i:i + 10])}{';' if i + 10 >= len(vals) else ''}\","
              f"{','.join(vals[i:i + 10])})" for i in range(0, len(vals), 10)]
    slot = layout.block_chars
    dat = [f"DEFDAT {n} PUBLIC",
           ";kukaid ring-buffer logger globals (generated; see kukaid.krc.krl_logger)",
           "DECL GLOBAL CHAR KID_CFG[64]",
           f'KID_CFG[]="{layout.config_text()}"',
           "DECL GLOBAL INT KID_WR=0",
           "DECL GLOBAL INT KID_RD=0",
           "DECL GLOBAL INT KID_OVF=0",
           "DECL INT KID_N=0",
           "DECL INT KID_LAST=0",
           "DECL INT KID_NOW=0",
           "DECL INT KID_OFS=0",
           "DECL STATE_T KID_ST",
           "DECL BOOL KID_OK ;StrClear and StrCopy are functions: their result is assigned",
           f"DECL CHAR KID_CUR[{slot}]"]
    dat += [f"DECL GLOBAL CHAR KID_B{i}[{slot}]" for i in range(1, layout.nb + 1)]
    dat += ["ENDDAT", ""]

    sub = [f"DEF {n}()",
           ";kukaid ring-buffer logger: samples every interpolation cycle (12 ms by $ROB_TIMER)",
           ";read-only towards the robot motion: it only writes its own KID_* globals",
           "KID_INIT()",
           "LOOP",
           "  KID_SAMPLE()",
           "ENDLOOP",
           "END",
           "",
           "DEF KID_INIT()",
           "  KID_WR=0",
           "  KID_RD=0",
           "  KID_OVF=0",
           "  KID_N=0",
           "  KID_LAST=$ROB_TIMER",
           "  KID_NEWBLOCK()",
           "END",
           "",
           "DEF KID_NEWBLOCK()",
           "  KID_OFS=0",
           "  KID_OK=StrClear(KID_CUR[])",
           "  SWRITE(KID_CUR[],KID_ST,KID_OFS,\"%d|\",KID_WR+1)",
           "END",
           "",
           "DEF KID_SAMPLE()",
           "  KID_NOW=$ROB_TIMER",
           "  IF KID_NOW<KID_LAST THEN ;$ROB_TIMER rolled over (after 2**31 ms): sample now, the cycle from here",
           "    KID_LAST=KID_NOW",
           "  ELSE",
           f"    IF (KID_NOW-KID_LAST)<{IPO_MS} THEN ;never negative: no INT overflow",
           "      RETURN",
           "    ENDIF",
           f"    IF (KID_NOW-KID_LAST)>={2 * IPO_MS} THEN",
           "      KID_LAST=KID_NOW ;missed cycles: resynchronise (the gap shows in the stamps)",
           "    ELSE",
           f"      KID_LAST=KID_LAST+{IPO_MS} ;at most KID_NOW: no INT overflow",
           "    ENDIF",
           "  ENDIF",
           *writes,
           "  KID_N=KID_N+1",
           f"  IF KID_N>={layout.bs} THEN",
           "    KID_N=0",
           f"    IF (KID_WR-KID_RD)<{layout.nb} THEN",
           f"      SWITCH (KID_WR MOD {layout.nb})+1"]
    for i in range(1, layout.nb + 1):
        sub += [f"      CASE {i}", f"        KID_OK=StrCopy(KID_B{i}[],KID_CUR[])"]
    sub += ["      ENDSWITCH",
            "      KID_WR=KID_WR+1",
            "    ELSE",
            "      KID_OVF=KID_OVF+1 ;ring full: the PC fell behind, this block is dropped",
            "    ENDIF",
            "    KID_NEWBLOCK()",
            "  ENDIF",
            "END",
            ""]
    return {f"{n}.DAT": "\n".join(dat), f"{n}.SUB": "\n".join(sub)}
