"""The KRL follower: the robot-side half of ``kukaid run-admittance --backend kvp``.

The PC computes the admittance reference and writes it through KUKAVARPROXY; a KRL program on
the KR C4 moves the axis to it with the controller's own position control (as in the paper: the
PC writes, the robot program follows, about 24 ms a cycle).  Handshake (global variables,
declared in ``KUKAID_FOLLOW.DAT``):

- ``KID_TGT`` REAL: the reference angle of the axis, degrees (written by the PC every cycle);
- ``KID_HB`` INT: the PC's heartbeat, incremented every cycle;
- ``KID_RUN`` BOOL: set TRUE by the PC once the first target and heartbeat are written; set
  FALSE by the PC to stop, or by the program itself when the heartbeat goes stale;
- ``KID_STOP`` INT: why the program stopped (0 running or not started, 1 stopped by the PC,
  2 heartbeat stale, 3 the axis stood outside the window when it started: nothing moved);
- ``KID_CLAMP`` INT: how many targets fell outside the window and were clamped.

Safety on the controller, independent of the PC: the target is clamped to the position window
written into the program, the axis speed and acceleration are limited by ``$VEL_AXIS`` and
``$ACC_AXIS``, and motion stops when ``KID_HB`` has not changed for ``stale_ms`` milliseconds
(the PC crashed, the network or KUKAVARPROXY stopped).  The KRC's own monitoring (software limit
switches, torque and collision monitoring, T1 speed reduction) stays in force.

The virtual KR C4 (``kukaid serve-sim``) emulates this program (clamp, heartbeat, KID_RUN), so
the PC side is tested end to end.  The KRL text is generated here; it has not been run on a
physical controller by the toolkit's tests: run it in T1 first, with the window small.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from kukaid.errors import KukaidError

#: stop reasons written to KID_STOP
STOP_BY_PC, STOP_STALE, STOP_OUTSIDE = 1, 2, 3


#: the shortest heartbeat timeout, ms: run-admittance writes KID_HB once a control cycle (12 or 24 ms), not locked
#: to the IPO clock, so a heartbeat up to two of its cycles old (plus the link's latency) is normal; 12 ms stopped
#: the follower at once (new-user trial 21), and the run then guided a reference the axis no longer followed
MIN_STALE_MS = 60


@dataclass(frozen=True)
class FollowerConfig:
    """The follower's settings: ``axis`` (1-6), position window ``q_min_deg``/``q_max_deg``
    (degrees), ``vel_pct``/``acc_pct`` ($VEL_AXIS/$ACC_AXIS of the axis, % of the machine data's
    maximum: whole numbers 1 to 100, as the KRC's INT variables hold them) and ``stale_ms``
    (heartbeat age that stops motion, ms)."""

    axis: int = 3
    q_min_deg: float = -math.inf
    q_max_deg: float = math.inf
    vel_pct: int = 10
    acc_pct: int = 30
    stale_ms: int = 200

    def __post_init__(self) -> None:
        if not 1 <= int(self.axis) <= 6:
            raise KukaidError(f"KRL follower: axis must be 1 to 6; got {self.axis}")
        if not (math.isfinite(self.q_min_deg) and math.isfinite(self.q_max_deg) and self.q_min_deg < self.q_max_deg):
            raise KukaidError(f"KRL follower: the position window [{self.q_min_deg}, {self.q_max_deg}] degrees "
                              "must be finite with q_min < q_max")
        for name in ("vel_pct", "acc_pct"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v == int(v) and 1 <= v <= 100):  # an INT on the KRC: 8.33 would be rounded
                raise KukaidError(f"KRL follower: {name} = {v} must be a whole number 1 to 100 %")
        if not MIN_STALE_MS <= int(self.stale_ms) <= 5000:
            raise KukaidError(f"KRL follower: stale_ms = {self.stale_ms} must be {MIN_STALE_MS} to 5000 ms (the PC "
                              "writes KID_HB once a control cycle, 12 or 24 ms, not locked to the controller's clock: "
                              "a heartbeat two of its cycles old is a working link)")

    def clamp(self, q_deg: float) -> tuple[float, bool]:
        """The target the program moves to, and whether it was clamped."""
        c = min(max(q_deg, self.q_min_deg), self.q_max_deg)
        return c, c != q_deg


def krl_follower_files(cfg: FollowerConfig, name: str = "KUKAID_FOLLOW") -> dict[str, str]:
    """KRL files of the follower: ``{NAME}.DAT`` (globals) and ``{NAME}.SRC`` (the program).

    Install both in ``KRC:\\R1\\Program``, make KUKAVARPROXY available, select ``{NAME}.SRC`` and
    start it; it waits for ``KID_RUN``, which ``kukaid run-admittance --backend kvp
    --enable-motion`` sets.
    """
    n = name.upper()
    a = int(cfg.axis)
    dat = [f"DEFDAT {n} PUBLIC",
           ";kukaid admittance follower globals (generated; see kukaid.krc.krl_follower)",
           "DECL GLOBAL REAL KID_TGT=0.0",
           "DECL GLOBAL INT KID_HB=0",
           "DECL GLOBAL BOOL KID_RUN=FALSE",
           "DECL GLOBAL INT KID_STOP=0",
           "DECL GLOBAL INT KID_CLAMP=0",
           "DECL E6AXIS KID_GOAL",
           "DECL REAL KID_Q",
           "DECL INT KID_HBL=0",
           "DECL INT KID_HBT=0",
           "DECL INT KID_NOW=0",
           "ENDDAT", ""]
    src = [f"DEF {n}()",
           f";kukaid admittance follower for A{a}: moves to KID_TGT (degrees) written by the PC",
           f";window [{cfg.q_min_deg:.4f}, {cfg.q_max_deg:.4f}] deg on the controller; "
           f"stops when KID_HB is older than {int(cfg.stale_ms)} ms",
           ";run in T1 first; the KRC's own monitoring stays in force",
           "BAS(#INITMOV,0)",
           f"$VEL_AXIS[{a}]={int(cfg.vel_pct)}",
           f"$ACC_AXIS[{a}]={int(cfg.acc_pct)}",
           "$ADVANCE=1",
           "KID_RUN=FALSE",
           "KID_STOP=0",
           "KID_CLAMP=0",
           "KID_GOAL=$AXIS_ACT",
           "PTP KID_GOAL ;exact stop where the axis stands",
           f"KID_TGT=KID_GOAL.A{a}",
           f"IF (KID_TGT>{cfg.q_max_deg:.4f}) OR (KID_TGT<{cfg.q_min_deg:.4f}) THEN",
           f"  KID_STOP={STOP_OUTSIDE} ;the axis stands outside the window: nothing moves (the clamp would drive it in)",
           "ELSE",
           "WAIT FOR KID_RUN",
           "KID_HBL=KID_HB",
           "KID_HBT=$ROB_TIMER",
           "WHILE KID_RUN",
           "  KID_NOW=$ROB_TIMER",
           "  IF (KID_HB<>KID_HBL) OR (KID_NOW<KID_HBT) THEN ;a new heartbeat, or $ROB_TIMER rolled over",
           "    KID_HBL=KID_HB",
           "    KID_HBT=KID_NOW",
           "  ENDIF",
           f"  IF (KID_NOW-KID_HBT)>{int(cfg.stale_ms)} THEN ;never negative: no INT overflow",
           "    KID_RUN=FALSE",
           f"    KID_STOP={STOP_STALE} ;the PC's heartbeat stopped",
           "  ELSE",
           "    KID_Q=KID_TGT",
           f"    IF KID_Q>{cfg.q_max_deg:.4f} THEN",
           f"      KID_Q={cfg.q_max_deg:.4f}",
           "      KID_CLAMP=KID_CLAMP+1",
           "    ENDIF",
           f"    IF KID_Q<{cfg.q_min_deg:.4f} THEN",
           f"      KID_Q={cfg.q_min_deg:.4f}",
           "      KID_CLAMP=KID_CLAMP+1",
           "    ENDIF",
           f"    KID_GOAL.A{a}=KID_Q",
           "    PTP KID_GOAL C_PTP",
           "  ENDIF",
           "ENDWHILE",
           "IF KID_STOP==0 THEN",
           f"  KID_STOP={STOP_BY_PC}",
           "ENDIF",
           "KID_GOAL=$AXIS_ACT",
           "PTP KID_GOAL ;exact stop",
           "ENDIF",
           "END", ""]
    return {f"{n}.DAT": "\n".join(dat), f"{n}.SRC": "\n".join(src)}
