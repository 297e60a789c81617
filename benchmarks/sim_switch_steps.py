"""Torque steps of the virtual KR C4 at dynamic/quasi-static switches (acceptance (c) of issue 2).

Run:  python benchmarks/sim_switch_steps.py

Noise-free torque (so the table shows physics, not noise), truth away from the paper's defaults,
moves with raised-cosine velocity ramps, switches found where |qd| (differenced positions)
crosses qd_thr = 0.0017 rad/s.  For each sample interval the table gives the largest torque
step within 50 ms of a switch, by kind: stop (entering standstill), start in the direction of the
previous move, reversal start (first move opposite to the previous one).  Compare with
3 sigma = 1.5 N·m of the default noise.  A discontinuity in the model would give a step that does
not shrink with the sample interval; the presliding stiffness (sum k ~ 2.5e5 N·m/rad) gives a
torque rate of about k qd_thr ~ 420 N·m/s at the switch, i.e. several N·m per 12 ms sample when
a move starts against the previous direction.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from sim_helpers import Builder  # noqa: E402

from kukaid.sim import SimConfig, VirtualKRC4  # noqa: E402

TRUTH = dict(Fc=12.0, Fs=16.0, vs=0.02, delta=1.2, Fv=9.0, Mx=25.0, Izz=1.7)
MOVES = (0.05, 0.3, -0.3, 0.01, 0.3, -0.02, -0.2, 0.6)


def steps(sample_time: float) -> dict[str, float]:
    cfg = SimConfig(**TRUTH, noise_sigma=0.0, sample_time=sample_time, quant_deg=0.0)
    b = Builder(0.2).hold(0.5)
    starts = []
    prev = None
    for v in MOVES:
        starts.append("reversal" if prev is not None and np.sign(v) != np.sign(prev) else "start")
        b.move(v, 0.3, ramp=0.3).hold(0.6)
        prev = v
    log = VirtualKRC4(cfg, seed=3).run(b.build())
    tm, tau, q = log.time, log.tau[:, 0], log.q[:, 0]
    dyn = np.abs(np.gradient(q, tm)) >= 0.0017
    sw = np.flatnonzero(dyn[1:] != dyn[:-1])
    d = np.abs(np.diff(tau))
    out = {"stop": 0.0, "start": 0.0, "reversal": 0.0}
    k = 0
    for i in sw:
        m = np.abs(tm[:-1] - tm[i]) < 0.05
        if dyn[i + 1]:
            # a move begins: which one (count starts in order, skip chatter within a move)
            j = min(int(np.searchsorted(np.cumsum([0.5] + [0.9 + 0.6] * len(MOVES)), tm[i])) - 1, len(MOVES) - 1)
            kind = starts[max(j, 0)]
            k += 1
        else:
            kind = "stop"
        out[kind] = max(out[kind], float(d[m].max()))
    return out


def main() -> None:
    print(f"{'sample s':>9} {'stop N·m':>9} {'start N·m':>10} {'reversal N·m':>13}   (3 sigma = 1.5 N·m)")
    for ts in (0.012, 0.004, 0.001):
        s = steps(ts)
        print(f"{ts:>9.3f} {s['stop']:>9.2f} {s['start']:>10.2f} {s['reversal']:>13.2f}")


if __name__ == "__main__":
    main()
