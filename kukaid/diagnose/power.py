"""Hidden-effect experiments on the virtual KR C4, for the power study, the tests and the demo.

:func:`hidden_effect_logs` simulates the friction and inertia experiments with chosen effects
hidden in the simulator's physics; :func:`initial_fit` identifies the model as identification does
(without the effects: what a user would have before diagnosing).  The truth used here is away from
the paper's values on purpose (see :data:`TRUTH`).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

#: Simulator truth for the power study: deliberately not the paper's Table 1 / Izz / Mx.
TRUTH: dict[str, float] = {"Fc": 12.4, "Fs": 14.1, "vs": 0.055, "delta": 1.4, "Fv": 10.8, "Izz": 1.85, "Mx": 23.7}

#: Thermal study: the motor starts warm and cools during each experiment (small thermal time
#: constant), so the temperature changes by about 10 K: the documented size of ``thermal_drift``.
THERMAL_CONDITIONS: dict[str, float] = {"T0": 40.0, "C_th": 60.0}


def experiments(short: bool = False):
    """The friction sweep and the sine (inertia) experiment used by the study (Trajectory objects).

    The inertia sine has the paper's 4 s period; the friction ramps are gentle (1 rad/s²).
    ``short`` gives a smaller pair for fast tests.
    """
    from kukaid import excite

    if short:
        tf = excite.friction(n_speeds=4, v_min=0.08, v_max=0.8, plateau=1.5, settle=0.3, lead=0.5, acc=1.0,
                             ramp_min=0.6)
        ti = excite.inertia(period=4.0, n_periods=3, amplitude=0.8, ramp_periods=0.5, lead=0.5, tail=0.5)
    else:
        tf = excite.friction(n_speeds=5, v_min=0.05, v_max=0.8, plateau=2.0, settle=0.3, lead=0.5, acc=1.0,
                             ramp_min=0.6)
        ti = excite.inertia(period=4.0, n_periods=3, amplitude=0.8, ramp_periods=0.5, lead=0.5, tail=0.5)
    return tf, ti


def sim_config(effects: dict[str, dict] | None = None, noise: float = 0.5, **overrides: Any):
    """SimConfig with :data:`TRUTH`, torque noise ``noise`` N·m and the hidden ``effects``."""
    from kukaid.sim import SimConfig

    kw: dict[str, Any] = dict(TRUTH)
    kw.update(noise_sigma=noise, effects=dict(effects or {}))
    if effects and "thermal_drift" in effects:
        kw.update(THERMAL_CONDITIONS)
    kw.update(overrides)
    return SimConfig().replace(**kw)


def draw_effects(sizes: dict[str, float], rng: np.random.Generator) -> dict[str, dict]:
    """Simulator parameters of each named effect at the given size (N·m)."""
    from kukaid.sim.effects import draw_effect

    out = {name: draw_effect(name, size, rng, mx=TRUTH["Mx"]) for name, size in sizes.items()}
    if "thermal_drift" in out:
        out["thermal_drift"]["T_ref"] = THERMAL_CONDITIONS["T0"]
    return out


def hidden_effect_logs(effects: dict[str, dict] | None = None, seed: int = 0, noise: float = 0.5,
                       short: bool = False, **overrides: Any) -> list:
    """Simulate the friction and inertia experiments with ``effects`` hidden; returns two AxisLogs."""
    from kukaid.sim import VirtualKRC4

    cfg = sim_config(effects, noise, **overrides)
    tf, ti = experiments(short)
    out = []
    for k, traj in enumerate((tf, ti)):
        sim = VirtualKRC4(cfg, seed=int(seed) * 2 + k, axis=3)
        out.append(sim.run(traj))
    return out


def initial_fit(logs: Sequence[Any]) -> dict:
    """The model a user has before diagnosing: ``kukaid fit`` (friction + Izz/Mx, joint) on ``logs``
    (the first the friction experiment, the rest inertia experiments), without effects."""
    from kukaid.identify import fit_axis

    p = fit_axis(friction=[logs[0]], inertia=list(logs[1:]))
    p.pop("effects", None)
    return p
