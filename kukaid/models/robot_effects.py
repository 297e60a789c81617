"""Effects a robot parameter file carries beyond its URDF and per-joint friction, named by
``kukaid diagnose`` (``effects`` of ``kukaid.robot_params/1``): each a term linear in its
coefficients for fixed settings, written once here for the diagnosis' candidates, its refit and
every prediction of the file.

Terms on joint j, with their settings (s: joint j's Coulomb column, the file's when a file
predicts, the diagnosis' filtered one while a candidate is judged):

- ``counterbalance@A<j>``: c0 gas_spring(q_j; q0_rad, lever_ratio, kappa), a gas spring.
- ``payload``: the last link's m, m c change (its regressor columns, c0..c3), on every joint.
- ``load_dependent_friction@A<j>``: c0 |L_j| s, L_j the file's gravity (``load`` "gravity") or
  rigid-body torque ("rigid").
- ``thermal_friction@A<j>``: c0 T_j s (``form`` "coulomb"), c0 T_j F_j, F_j the file's friction
  torque ("friction"), or c0 T_j s + c1 T_j qd_j ("coulomb_viscous": the Coulomb and the viscous
  friction each changing with temperature at a rate of its own); T_j the log's motor temperature,
  degC.
- ``position_ripple@A<j>``: c0 sin(n q_j) + c1 cos(n q_j).
- ``coupled_wrist_friction``: the friction of the wrist's motors 5 and 6 on their own velocities
  (joint units) ``m5 = qd5 + c54 qd4``, ``m6 = qd6 + c64 qd4 + c65 qd5`` (a KUKA wrist's gearing
  couples A4's motion into the A5 and A6 drives), ``f_k = c_Fc,k tanh(m_k / v_smooth) + c_Fv,k m_k``,
  seen at the joints through the coupling's transpose: A4 gets ``c54 f5 + c64 f6``, A5
  ``f5 + c65 f6``, A6 ``f6`` (coefficients Fc5, Fv5, Fc6, Fv6, N·m and N·m·s/rad; on every joint,
  zero off the wrist). A per-joint friction cannot hold it: A4 feels a friction that switches
  with the other motors' velocities.
- ``gear_elasticity@A<j>``: c0 (tau_rb(link state) - tau_rb(q)) / compliance on every joint, to
  first order in the compliance c0 = 1/k (rad/(N·m)): a spring between joint j's motor (where the
  encoder is) and its link, so the link lags the measured position by ``tau_j / k``, its velocity
  and acceleration by the spring torque's derivatives over k; the rigid body (the file's) is
  evaluated at that link state, the torque ``tau_j`` the file's rigid-body torque of joint j.

An effect's entry in the file: its settings and ``coefficients`` (the c above). A friction
effect's ``v_smooth`` is the Coulomb transition the diagnosis judged it with (its term through a
transition of its own); a file predicts it with its own Coulomb column s.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from kukaid.models import effects as E

#: polytropic exponent of a gas spring when a file does not say
CB_KAPPA = 1.3
#: kind -> (settings it needs, number of coefficients)
KINDS = {
    "counterbalance": (("q0_rad", "lever_ratio"), 1),
    "payload": ((), 4),
    "load_dependent_friction": (("load",), 1),
    "thermal_friction": (("form",), 1),
    "position_ripple": (("n",), 2),
    "coupled_wrist_friction": (("c54", "c64", "c65", "v_smooth"), 4),
    "gear_elasticity": ((), 1),
}
#: the compliance a gear elasticity's columns are differenced at, rad/(N·m) (a link shift of 1e-4
#: rad at 100 N·m): small against any gear's, large against rounding
ELASTIC_STEP = 1e-6
#: effects on every joint, named without a joint
JOINTLESS = ("payload", "coupled_wrist_friction")


def n_coefficients(kind: str, spec: dict) -> int:
    """The number of coefficients of an effect of ``kind`` with settings ``spec`` (a thermal
    friction's "coulomb_viscous" form has two, every other form its kind's)."""
    if kind == "thermal_friction" and spec.get("form") == "coulomb_viscous":
        return 2
    return KINDS[kind][1]


def gas_spring(q: np.ndarray, q0: float, ratio: float, kappa: float = CB_KAPPA) -> np.ndarray:
    """Torque shape of a gas spring (per unit force scale, lever b = 1 m, a = ratio), N·m per N."""
    x = np.asarray(q, float) - q0
    a, b = ratio, 1.0
    s = np.sqrt(a * a + b * b - 2 * a * b * np.cos(x))
    s0 = math.hypot(a, b)
    return (s0 / np.maximum(s, 1e-9)) ** kappa * a * b * np.sin(x) / np.maximum(s, 1e-9)


@dataclass
class EffectSignals:
    """What the effects read, over N samples of n joints: positions rad (N, n), the file's Coulomb
    column and friction torque (N, n), its gravity and rigid-body torque N·m (N, n), the last link's
    m, m c regressor columns (N, n, 4), motor temperatures degC (N, n) or None, velocities rad/s
    (N, n; the fit's filtered ones) or None, sample times s (N,) or None (``log_rows``: samples per
    recording, when there are several), and ``rigid_at(j, dq, dqd, dqdd)``: the file's rigid-body
    torque (N, n) with joint j's position, velocity and acceleration moved by these (N,), or None."""

    q: np.ndarray
    sign: np.ndarray
    friction: np.ndarray
    gravity: np.ndarray
    rigid: np.ndarray
    payload: np.ndarray
    temp: np.ndarray | None = None
    qd: np.ndarray | None = None
    time: np.ndarray | None = None
    rigid_at: Any = None
    log_rows: tuple = ()


def elastic_columns(j: int, time: np.ndarray, rigid: np.ndarray, rigid_at, rows: Sequence[int] = ()) -> np.ndarray:
    """(N, n, 1): a gear elasticity of joint j per unit compliance (N·m per rad/(N·m)): the file's
    rigid-body torque at the link's state (the measured position less ``c tau_j``, the velocity and
    acceleration less ``c`` times the torque's first and second time derivatives, ``tau_j`` the
    rigid-body torque ``rigid[:, j]``) less at the measured state, over ``c``, by a central
    difference at :data:`ELASTIC_STEP`. ``time`` s (N,); ``rows``: samples per recording (each its own
    time derivative; default one)."""
    t, tau = np.asarray(time, float), np.asarray(rigid, float)[:, j]
    d1, d2 = np.empty_like(tau), np.empty_like(tau)
    at = 0
    for r in (list(rows) or [tau.size]):
        sl = slice(at, at + int(r))
        if int(r) >= 3:
            d1[sl] = np.gradient(tau[sl], t[sl])
            d2[sl] = np.gradient(d1[sl], t[sl])
        else:
            d1[sl], d2[sl] = 0.0, 0.0
        at += int(r)
    c = ELASTIC_STEP
    return ((rigid_at(j, -c * tau, -c * d1, -c * d2) - rigid_at(j, c * tau, c * d1, c * d2)) / (2 * c))[:, :, None]


def wrist_mix(n: int, spec: dict) -> np.ndarray:
    """(2, n): the wrist's motors 5 and 6 velocities (joint units) from the joint velocities,
    ``m = mix @ qd``: ``m5 = qd5 + c54 qd4``, ``m6 = qd6 + c64 qd4 + c65 qd5`` (the last three
    joints of the robot are A4-A6)."""
    a4, a5, a6 = n - 3, n - 2, n - 1
    mix = np.zeros((2, n))
    mix[0, a5], mix[0, a4] = 1.0, float(spec["c54"])
    mix[1, a6], mix[1, a4], mix[1, a5] = 1.0, float(spec["c64"]), float(spec["c65"])
    return mix


def wrist_columns(coulomb: np.ndarray, motor_qd: np.ndarray, mix: np.ndarray) -> np.ndarray:
    """(N, n, 4) the coupled wrist friction's columns: the motors' Coulomb ``coulomb`` (N, 2) and
    viscous ``motor_qd`` (N, 2, rad/s) columns through the coupling's transpose (``mix``: (2, n),
    :func:`wrist_mix`), in the order Fc5, Fv5, Fc6, Fv6."""
    X = np.stack([coulomb[:, 0], motor_qd[:, 0], coulomb[:, 1], motor_qd[:, 1]], axis=1)   # (N, 4)
    T = np.repeat(mix, 2, axis=0)                                                            # (4, n)
    return X[:, None, :] * T.T[None, :, :]


def parse(name: str) -> tuple[str, int | None]:
    """``'counterbalance@A2'`` -> ``('counterbalance', 1)`` (0-based joint); ``'payload'`` -> (.., None).
    Raises ValueError for a name that is not an effect of this module."""
    m = re.fullmatch(r"([a-z_]+)(?:@A([1-9][0-9]*))?", name)
    if not m or m.group(1) not in KINDS or (m.group(1) in JOINTLESS) != (m.group(2) is None):
        raise ValueError(f"unknown robot effect {name!r} (known: {', '.join(k if k in JOINTLESS else k + '@A<j>' for k in KINDS)})")
    return m.group(1), None if m.group(2) is None else int(m.group(2)) - 1


def columns(name: str, spec: dict, s: EffectSignals) -> np.ndarray:
    """The effect's columns: (N, c) on its joint, or (N, n, c) for a term on every joint (payload)."""
    kind, j = parse(name)
    if kind == "payload":
        return s.payload
    if kind == "gear_elasticity":
        if s.rigid_at is None or s.time is None:
            raise ValueError(f"{name} needs the file's rigid body and the sample times")
        return elastic_columns(j, s.time, s.rigid, s.rigid_at, s.log_rows)
    if kind == "coupled_wrist_friction":
        if s.qd is None:
            raise ValueError(f"{name} needs the joint velocities")
        mix = wrist_mix(s.q.shape[1], spec)
        vm = s.qd @ mix.T
        return wrist_columns(np.tanh(vm / max(float(spec["v_smooth"]), 1e-9)), vm, mix)
    if kind == "counterbalance":
        return gas_spring(s.q[:, j], spec["q0_rad"], spec["lever_ratio"], spec.get("kappa", CB_KAPPA))[:, None]
    if kind == "load_dependent_friction":
        L = s.gravity[:, j] if spec["load"] == "gravity" else s.rigid[:, j]
        return (np.abs(L) * s.sign[:, j])[:, None]
    if kind == "thermal_friction":
        if s.temp is None:
            raise ValueError(f"{name} needs the log's motor temperature channel (temp)")
        if spec["form"] == "coulomb_viscous":
            if s.qd is None:
                raise ValueError(f"{name} needs the joint velocities")
            return np.column_stack([s.temp[:, j] * s.sign[:, j], s.temp[:, j] * s.qd[:, j]])
        return (s.temp[:, j] * (s.sign[:, j] if spec["form"] == "coulomb" else s.friction[:, j]))[:, None]
    return E.PositionRipple().columns(_Joint(s.q[:, j]), spec, None)


@dataclass
class _Joint:
    q: np.ndarray


def torque(effects: dict, s: EffectSignals) -> np.ndarray:
    """(N, n) N·m: the sum of the effects ``{name: entry}``, each its columns times its coefficients."""
    out = np.zeros_like(s.q)
    for name, spec in (effects or {}).items():
        c = np.asarray(spec["coefficients"], float)
        B = columns(name, spec, s)
        if B.ndim == 3:
            out += B @ c
        else:
            out[:, parse(name)[1]] += B @ c
    return out


def describe(name: str, spec: dict) -> str:
    """One line of an effect for a table: its name, settings and coefficients."""
    kind, _ = parse(name)
    keys = KINDS[kind][0] + (("kappa",) if kind == "counterbalance" and "kappa" in spec else ())
    parts = [f"{k} {spec[k]:.4g}" if isinstance(spec[k], (int, float)) else f"{k} {spec[k]}" for k in keys]
    parts.append("coefficients " + ", ".join(f"{c:.4g}" for c in spec["coefficients"]))
    return f"{name}: {'; '.join(parts)}"
