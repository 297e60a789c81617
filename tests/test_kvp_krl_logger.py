"""The KRL ring-buffer logger text and its CLI."""
from __future__ import annotations

import subprocess

import numpy as np
import pytest

from kukaid.errors import ControllerError, KukaidError
from kukaid.krc.krl_logger import RingLayout, format_sample, krl_logger_files, parse_block, parse_config


def test_logger_text_declares_the_handshake_and_samples_every_ipo_cycle():
    layout = RingLayout(axes=(2, 3), nb=4, bs=5)
    files = krl_logger_files(layout)
    dat, sub = files["KUKAID_LOG.DAT"], files["KUKAID_LOG.SUB"]
    assert dat.startswith("DEFDAT KUKAID_LOG PUBLIC") and dat.rstrip().endswith("ENDDAT")
    for g in ("KID_CFG[64]", "KID_WR", "KID_RD", "KID_OVF", "KID_B1[", "KID_B4["):
        assert "DECL GLOBAL" in dat and g in dat
    assert "KID_B5[" not in dat
    assert 'KID_CFG[]="kukaid-ring/1 axes=2,3 nb=4 bs=5"' in dat
    assert "IF (KID_NOW-KID_LAST)<12 THEN" in sub
    assert "$AXIS_ACT_MEAS.A2,$AXIS_ACT_MEAS.A3,$TORQUE_AXIS_ACT[2],$TORQUE_AXIS_ACT[3],$MOT_TEMP[2],$MOT_TEMP[3]" in sub
    assert '"%d,%.4f,%.4f,%.3f,%.3f,%.1f,%.1f;"' in sub
    assert sub.count("CASE ") == 4 and "KID_OVF=KID_OVF+1" in sub
    # the only robot-side writes are the logger's own globals
    import re

    targets = [m.group(1) for ln in sub.splitlines() if (m := re.match(r"^\s*([$\w]+)(?:\[\])?\s*=", ln))]
    assert targets and all(t.startswith("KID_") for t in targets), targets


def test_config_and_block_round_trip():
    layout = parse_config("kukaid-ring/1 axes=3 nb=8 bs=2")
    assert layout == RingLayout(axes=(3,), nb=8, bs=2)
    text = "9|" + format_sample(1000, [12.34567], [-3.2104], [305.14]) + format_sample(1012, [12.4], [-3.0], [305.1])
    arr = parse_block(text, 9, layout)
    np.testing.assert_array_equal(arr, [[1000, 12.3457, -3.210, 305.1], [1012, 12.4, -3.0, 305.1]])
    with pytest.raises(ControllerError, match="not a kukaid-ring/1 layout"):
        parse_config("hello")
    with pytest.raises(ControllerError, match="sample 1 has 3 fields, expected 4"):
        parse_block("9|1,2,3;", 9, layout)
    with pytest.raises(ControllerError, match="more than bs=2"):
        parse_block("9|" + "1,2,3,4;" * 3, 9, layout)
    with pytest.raises(KukaidError, match="axes must be distinct"):
        RingLayout(axes=(3, 3))


def test_cli_writes_files_and_refuses_overwrite(tmp_path, kukaid_cmd):
    r = subprocess.run([*kukaid_cmd, "krl-logger", "--axis", "3", "-o", str(tmp_path)], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "KUKAID_LOG.SUB").read_text().startswith("DEF KUKAID_LOG()")
    r = subprocess.run([*kukaid_cmd, "krl-logger", "--axis", "3", "-o", str(tmp_path)], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 1 and "already exists" in r.stderr


@pytest.mark.parametrize("axes", [(3,), (1, 2, 3), (1, 2, 3, 4), (1, 2, 3, 4, 5, 6)])
def test_each_swrite_of_the_logger_takes_at_most_ten_variables(axes):
    """New-user trial 17: `krl-logger --axis 1 ... --axis 6` wrote one SWRITE of 19 variables; KRL's
    SWRITE(String, State, Offset, Format, Var1 <, ..., Var10>) takes at most 10, so the logger of 4 to 6
    axes would not compile on a KR C4.  A sample is now written by consecutive SWRITEs (the offset runs
    on), their formats and variables together those of one sample."""
    import re

    sub = krl_logger_files(RingLayout(axes=axes, nb=4, bs=2))["KUKAID_LOG.SUB"]
    body = sub.split("DEF KID_SAMPLE()")[1]
    calls = re.findall(r'SWRITE\(KID_CUR\[\],KID_ST,KID_OFS,"([^"]*)",([^)]*(?:\)[^)]*)*?)\)\s*$', body, re.M)
    assert calls, body
    fmts, args = zip(*calls)
    args = [a.split(",") for a in args]
    assert all(len(a) <= 10 and len(a) == f.count("%") for f, a in zip(fmts, args)), calls
    n = len(axes)
    assert "".join(fmts) == "%d" + ",%.4f" * n + ",%.3f" * n + ",%.1f" * n + ";"
    assert sum(args, []) == (["$ROB_TIMER"] + [f"$AXIS_ACT_MEAS.A{a}" for a in axes]
                             + [f"$TORQUE_AXIS_ACT[{a}]" for a in axes] + [f"$MOT_TEMP[{a}]" for a in axes])


def test_the_loggers_string_functions_have_their_results_assigned():
    """Trial 19: StrClear and StrCopy are KRL functions (they return BOOL); the logger called them as
    statements (`StrClear(KID_CUR[])`), which KRL takes only inside an expression. Their results now
    go to a declared BOOL."""
    import re

    files = krl_logger_files(RingLayout(axes=(1, 2, 3), nb=4, bs=2))
    sub, dat = files["KUKAID_LOG.SUB"], files["KUKAID_LOG.DAT"]
    calls = [ln.strip() for ln in sub.splitlines() if re.search(r"\bStr(Clear|Copy)\(", ln)]
    assert len(calls) == 5 and all(re.match(r"^KID_OK=Str(Clear|Copy)\(", c) for c in calls), calls
    assert re.search(r"^DECL BOOL KID_OK\b", dat, re.M)


def _int32(x: int) -> int:
    """KRL INT arithmetic, taken to stop on an overflow (the safe assumption)."""
    assert -2**31 <= x < 2**31, f"INT overflow: {x}"
    return x


def test_the_krl_programs_time_stays_right_across_the_timer_rollover():
    """Trial 19: $ROB_TIMER (an INT of milliseconds) rolls over after about 24.8 days of uptime; the
    logger's `$ROB_TIMER-KID_LAST` and the follower's `$ROB_TIMER-KID_HBT` then subtract across it (an INT
    overflow). Both now read the timer once, restart their reference at a rollover and subtract only
    values in order. Their logic, run here in checked 32-bit arithmetic across the rollover: no
    overflow, a sample every 12 ms, the heartbeat watch going on."""
    from kukaid.krc.krl_follower import FollowerConfig, krl_follower_files

    sub = krl_logger_files(RingLayout(axes=(3,)))["KUKAID_LOG.SUB"]
    fol = krl_follower_files(FollowerConfig(q_min_deg=0.0, q_max_deg=60.0))["KUKAID_FOLLOW.SRC"]
    for text in (sub, fol):
        assert "$ROB_TIMER-" not in text and "KID_NOW=$ROB_TIMER" in text
    assert "IF KID_NOW<KID_LAST THEN" in sub and "IF (KID_HB<>KID_HBL) OR (KID_NOW<KID_HBT) THEN" in fol
    last, taken = 2**31 - 120, []                  # the logger's KID_SAMPLE, every 4 ms of controller time
    for t in range(2**31 - 122, 2**31 + 120, 4):
        now = t - 2**32 if t >= 2**31 else t
        if now < last:
            last = now
        elif _int32(now - last) < 12:
            continue
        else:
            last = now if _int32(now - last) >= 24 else _int32(last + 12)
        taken.append(now)
    steps = np.diff(np.array(taken, dtype=np.int64) % 2**32)
    assert len(taken) >= 20 and set(steps.tolist()) <= {4, 8, 12}   # a sample a 12 ms cycle; at the rollover one early
    hbt, stale = 2**31 - 100, False                # the follower's watch, the heartbeat last seen there
    for t in range(2**31 - 100, 2**31 + 400, 12):
        now = t - 2**32 if t >= 2**31 else t
        if now < hbt:
            hbt = now
        stale = stale or _int32(now - hbt) > 200
    assert stale                                   # no heartbeat for 500 ms: still seen, across the rollover
