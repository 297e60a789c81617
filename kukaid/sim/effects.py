"""Hidden effects of the virtual KR C4: physics the paper's model does not contain.

``kukaid diagnose`` has to find them.  Each effect is switched on by putting its name with its
parameters into ``SimConfig.effects``; :data:`EFFECTS` documents every parameter (unit, allowed
range, default) and what the effect's ``size`` (N·m) means, and :func:`draw_effect` returns
parameters for a requested size, drawing the effect's other parameters (phase, frequency, time
constant, sign) at random from documented ranges.

The effects act inside the simulated physics (not added to the measurement afterwards): the link
feels them, the servo compensates them, so the motor torque ($TORQUE_AXIS_ACT) shows them.

=========================  ==================================================================
name                       torque on the link (N·m), and what ``size`` is
=========================  ==================================================================
gravity_sine               ``My sin(q)``; size = ``|My|`` (amplitude)
torque_offset              ``offset`` (constant); size = ``|offset|``
position_ripple            ``A sin(n q + phi)``; size = ``A`` (amplitude)
thermal_drift              all friction (Stribeck level, Fv, Maxwell-slip saturations) scaled by
                           ``1 + kappa (T - T_ref)``, T the motor temperature (°C, rises with
                           dissipated power); size = ``|kappa|`` * 3 K * 20 N·m, the change of
                           the sliding friction (about 20 N·m) for a 3 K temperature rise, which
                           is what the default friction experiment (115 s) causes (inertia 22 s:
                           1.9 K; validation 46 s: 1.7 K; a 10-minute friction experiment: 12 K)
load_dependent_friction    Coulomb level (and Maxwell-slip saturations) grow by ``c |Mx cos q|``;
                           size = ``c |Mx|``, the extra friction at ``|cos q| = 1`` (Mx of the
                           simulation; :func:`draw_effect` takes it, default the paper's 18.4789)
backlash                   after every reversal of the motion direction (|qd| above ``v_on``,
                           also the first move after standstill in the new direction) the gear
                           teeth cross the dead zone and hit: a smooth pulse
                           ``A s/tau exp(1 - s/tau) sign(qd)``, s the time since the reversal;
                           size = ``A`` (peak, reached at s = tau)
=========================  ==================================================================
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

#: Reference values of the documented sizes (the paper's Mx is only the default of ``draw_effect``).
MX_REF = 18.4789
THERMAL_DT_REF = 3.0  # K (rise during the default 115 s friction experiment)
THERMAL_F_REF = 20.0  # N·m

#: name -> {"params": {param: (low, high, default, doc)}, "size": doc, "draw": doc}
EFFECTS: dict[str, dict[str, Any]] = {
    "gravity_sine": {
        "params": {"My": (-200.0, 200.0, None, "sine gravity amplitude, N·m: torque My sin(q)")},
        "size": "|My|, N·m (amplitude)",
        "draw": "My = +-size (random sign)",
    },
    "torque_offset": {
        "params": {"offset": (-200.0, 200.0, None, "constant torque, N·m")},
        "size": "|offset|, N·m",
        "draw": "offset = +-size (random sign)",
    },
    "position_ripple": {
        "params": {
            "A": (0.0, 200.0, None, "ripple amplitude, N·m"),
            "n": (0.1, 500.0, 12.0, "ripple order, rad/rad: n periods per revolution of the axis (n/(2 pi) "
                                    "per radian)"),
            "phi": (-2 * math.pi, 2 * math.pi, 0.0, "phase, rad"),
        },
        "size": "A, N·m (amplitude)",
        "draw": "n integer uniform in [4, 30] rad/rad, phi uniform in [-pi, pi]",
    },
    "thermal_drift": {
        "params": {
            "kappa": (-0.2, 0.2, None, "relative friction change per kelvin, 1/K"),
            "T_ref": (-50.0, 200.0, None, "temperature at which friction is the nominal one, °C (default T_amb)"),
        },
        "size": "|kappa| * 3 K * 20 N·m: friction change after the 3 K rise of a default friction experiment, N·m",
        "draw": "kappa = -size / 60 (friction falls as the lubricant warms), T_ref = T_amb",
    },
    "load_dependent_friction": {
        "params": {"c": (0.0, 5.0, None, "extra Coulomb friction per N·m of |Mx cos q|, dimensionless")},
        "size": "c * |Mx| N·m: extra friction at |cos q| = 1 (Mx of the simulation)",
        "draw": "c = size / |Mx|",
    },
    "backlash": {
        "params": {
            "A": (0.0, 200.0, None, "peak of the impact transient, N·m"),
            "tau": (0.005, 2.0, 0.1, "time to the peak (and decay time) of the transient, s"),
            "v_on": (1e-5, 1.0, 0.01, "speed above which a direction of motion counts, rad/s"),
        },
        "size": "A, N·m (peak of the transient after a reversal)",
        "draw": "tau uniform in [0.06, 0.15] s, v_on = 0.01 rad/s",
    },
}


def _err(msg: str):
    from kukaid.errors import SimConfigError

    return SimConfigError(msg)


def validate_effects(effects: dict, where: str = "sim config") -> dict:
    """Check ``{name: parameters}`` against :data:`EFFECTS`; return a copy with defaults filled."""
    out: dict[str, dict] = {}
    for name, p in effects.items():
        if name not in EFFECTS:
            raise _err(f"{where}: unknown effect '{name}' (known: {', '.join(EFFECTS)})")
        if not isinstance(p, dict):
            raise _err(f"{where}: effect '{name}' must be an object of parameters")
        spec = EFFECTS[name]["params"]
        for k in p:
            if k not in spec:
                raise _err(f"{where}: unknown parameter 'effects.{name}.{k}' (known: {', '.join(spec)})")
        q: dict[str, Any] = {}
        for k, (lo, hi, default, doc) in spec.items():
            v = p.get(k, default)
            if v is None:
                if name == "thermal_drift" and k == "T_ref":
                    q[k] = None
                    continue
                raise _err(f"{where}: missing parameter 'effects.{name}.{k}' ({doc})")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise _err(f"{where}: parameter 'effects.{name}.{k}' must be a finite number, got {json.dumps(v, default=str)}")
            if not lo <= v <= hi:
                raise _err(f"{where}: parameter 'effects.{name}.{k}' = {v} is outside the allowed range [{lo}, {hi}]")
            q[k] = float(v)
        out[name] = q
    return out


def draw_effect(name: str, size: float, rng: np.random.Generator | int | None = None, mx: float = MX_REF) -> dict:
    """Parameters of effect ``name`` whose torque size (see :data:`EFFECTS`) is ``size`` N·m.

    Parameters
    ----------
    name : one of :data:`EFFECTS`.
    size : N·m, >= 0; the documented size of the effect (amplitude or peak).
    rng : numpy Generator (or seed) for the parameters not fixed by the size (sign, phase, ...).
    mx : gravity amplitude Mx of the simulation, N·m (sets the size of load_dependent_friction).
    """
    if name not in EFFECTS:
        raise _err(f"effect: unknown effect '{name}' (known: {', '.join(EFFECTS)})")
    size = float(size)
    if not math.isfinite(size) or size < 0:
        raise _err(f"effect '{name}': size must be a finite number >= 0 N·m, got {size}")
    rng = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
    sign = 1.0 if rng.random() < 0.5 else -1.0
    if name == "gravity_sine":
        return {"My": sign * size}
    if name == "torque_offset":
        return {"offset": sign * size}
    if name == "position_ripple":
        return {"A": size, "n": float(rng.integers(4, 31)), "phi": float(rng.uniform(-math.pi, math.pi))}
    if name == "thermal_drift":
        return {"kappa": -size / (THERMAL_DT_REF * THERMAL_F_REF)}
    if name == "load_dependent_friction":
        if not (math.isfinite(mx) and mx != 0):
            raise _err(f"effect 'load_dependent_friction': needs a gravity load, got Mx = {mx}")
        return {"c": size / abs(mx)}
    # backlash
    return {"A": size, "tau": float(rng.uniform(0.06, 0.15)), "v_on": 0.01}
