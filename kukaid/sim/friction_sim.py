"""Friction of the simulated axis: Maxwell-slip while quasi-static, exactly Stribeck while sliding.

Model (a generalized Maxwell-slip, GMS-like, with a velocity-dependent saturation)
-------------------------------------------------------------------------------
The friction torque is ``F = sum_i F_i + Fv qd``.  Element i is an elasto-slide element of
stiffness ``k_i`` whose torque follows the joint: ``dF_i = k_i dq`` while ``|F_i| < s_i``, and
sticks at ``+-s_i`` (the element slips) otherwise.  This is eq. (9) of the paper, written with
the element torque as state instead of its position ``zeta_i = q - F_i / k_i``.

The saturation torques are not constant; they blend with speed from the Maxwell-slip values of
Table 2 to the Stribeck magnitude of eq. (1)::

    S(v)  = (1 - b(|v|)) * sum_j W_j + b(|v|) * g(|v|),   g(s) = Fc + (Fs - Fc) exp(-(s/vs)^delta)
    s_i   = (W_i / sum_j W_j) * S(v)
    b(s)  = smoothstep((s - v_blend/2) / (v_blend/2))   (0 below v_blend/2, 1 above v_blend)

Consequences (what the tests check):

* While sliding at constant velocity every element is saturated, so the friction is
  ``S(v) sign(v) + Fv v`` which for ``|v| >= v_blend`` is exactly Stribeck, eq. (1).
* While the joint stands or creeps (``|v| < v_blend / 2``) it is exactly Maxwell-slip with the
  saturations ``W_i``; the torque against position traces hysteresis loops whose friction part is
  bounded by ``sum W``.
* Continuity: the torque is a state (the ``F_i``) that changes only through ``k_i dq`` and through
  clamping to ``s_i(v)``, which is continuous in ``v``; ``v`` is a state of the mechanics.  There is
  no switch in the physics at ``qd_thr`` at all, so no torque jump at a mode switch.

Optional pre-sliding damping (``ms_damping`` = zeta, default 0): element i then is a spring with a
parallel damper ``c_i = 2 zeta sqrt(k_i Izz)`` (LuGre's sigma1), ``F_i = k_i e_i + c_i de_i/dt``,
still clamped to ``+-s_i`` (while clamped the stretch relaxes, so the torque stays continuous and
bounded by ``s_i``); with zeta = 0 this is exactly the Maxwell-slip model above.

``v_blend`` defaults to the paper's ``qd_thr`` (0.0017 rad/s).  Hidden effects that change
friction (``thermal_drift``, ``load_dependent_friction``) act on ``S`` and ``Fv``.
"""
from __future__ import annotations

import numpy as np


def blend(speed: np.ndarray | float, v_blend: float) -> np.ndarray:
    """Weight b of the Stribeck magnitude in the saturation (0: Maxwell-slip, 1: Stribeck)."""
    x = np.clip((np.abs(np.asarray(speed, dtype=float)) - 0.5 * v_blend) / (0.5 * v_blend), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def saturation_total(speed: np.ndarray | float, cfg) -> np.ndarray:
    """Total saturation torque S(|v|) of the elements, N·m (``cfg`` a SimConfig, no effects)."""
    s = np.abs(np.asarray(speed, dtype=float))
    g = cfg.Fc + (cfg.Fs - cfg.Fc) * np.exp(-((s / cfg.vs) ** cfg.delta))
    b = blend(s, cfg.v_blend)
    return (1.0 - b) * cfg.sum_W + b * g


def steady_friction(v: np.ndarray | float, cfg) -> np.ndarray:
    """Friction torque while sliding steadily at ``v`` rad/s (Stribeck for |v| >= v_blend), N·m."""
    v = np.asarray(v, dtype=float)
    return saturation_total(v, cfg) * np.sign(v) + cfg.Fv * v
