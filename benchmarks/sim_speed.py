"""Speed of the virtual KR C4: simulated seconds per wall-clock second, 10-minute friction experiment.

Run:  python benchmarks/sim_speed.py [--minutes 10] [--repeat 2]

Prints the kernel in use (numba or pure Python), the first-call time (JIT compile or cache load),
and for each repetition the simulated duration, the wall time and the real-time factor.
Target (issue 2): at least 200 times faster than real time on a 2-core machine.
"""
from __future__ import annotations

import argparse
import time
import types

import numpy as np


def friction_trajectory(minutes: float):
    """A friction experiment of about ``minutes`` minutes: kukaid.excite.friction if present."""
    try:
        from kukaid import excite

        one = excite.friction()
        cycles = max(1, int(np.ceil(minutes * 60.0 / one.duration)))
        traj = excite.friction(cycles=cycles)
        return traj, "kukaid.excite.friction(cycles=%d)" % cycles
    except Exception:  # the excite module is another engineer's; fall back to our own schedule
        pass
    dt = 0.012
    speeds = np.geomspace(0.01, 1.0, 10)
    span = 1.2
    t, q, tt, qq = [0.0], [0.0], 0.0, 0.0
    while tt < minutes * 60:
        for v in speeds:
            for sgn in (1, -1):
                T = span / v
                n = int(T / dt)
                for _ in range(n):
                    tt += dt
                    qq += sgn * v * dt
                    t.append(tt)
                    q.append(qq)
                for _ in range(int(1.0 / dt)):
                    tt += dt
                    t.append(tt)
                    q.append(qq)
                if tt >= minutes * 60:
                    break
            if tt >= minutes * 60:
                break
    return types.SimpleNamespace(t=np.array(t), q=np.array(q), kind="friction", params={}), "own schedule"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()

    from kukaid.sim import SimConfig, VirtualKRC4
    from kukaid.sim import kernel

    t0 = time.perf_counter()
    k = kernel.get_kernel()
    sim = VirtualKRC4(SimConfig(), seed=0)
    sim.advance(0.05)  # first call: numba compile or on-disk cache load
    first = time.perf_counter() - t0
    kind = "numba" if k is not kernel.servo_block else "pure Python"
    traj, source = friction_trajectory(args.minutes)
    print(f"kernel: {kind}; first call (import + compile/cache load): {first:.2f} s")
    print(f"trajectory: {source}, {traj.t[-1] - traj.t[0]:.1f} s, servo {SimConfig().servo_rate:g} Hz x "
          f"{SimConfig().substeps} physics sub-steps")
    print(f"{'run':>3} {'simulated s':>12} {'wall s':>8} {'x real time':>12}")
    for r in range(args.repeat):
        sim = VirtualKRC4(SimConfig(), seed=r)
        w0 = time.perf_counter()
        log = sim.run(traj)
        w = time.perf_counter() - w0
        print(f"{r:>3} {log.duration:>12.1f} {w:>8.2f} {log.duration / w:>12.0f}")


if __name__ == "__main__":
    main()
