"""A family of plants the admittance estimator was not built on, each with the parameter file an
identification would give it.

The estimator's law is Stribeck sliding friction + Maxwell-slip pre-sliding.  Each member draws a
virtual KR C4 whose truth is spread around the paper's A3 by a seed, with what a real axis has and
the estimator does not model:

=================  ==========================================================================
member             what differs from the estimator's own law
=================  ==========================================================================
``gms``            nothing in the law (truth spread, servo gains, vibration, noise only)
``gms-sensor``     $TORQUE_AXIS_ACT quantised (0.05-0.2 N·m) and one sample late
``gms-gravity``    the parameter file's gravity amplitude off by 3-6 %
``lugre``          LuGre friction (Canudas de Wit et al. 1995): stiction that holds the link
``lugre-posfric``  LuGre, and friction 10-20 % stronger or weaker with position (gear mesh)
``lugre-all``      LuGre, position-dependent friction, the torque sensor and the gravity error
=================  ==========================================================================

Every member's servo settles with an overshoot (a 0.2 degree step: about 20-30 %), and the
parameter file carries identification errors (friction and inertia a few percent off, the
Maxwell-slip saturations 10 % off).  A LuGre plant's file holds the Maxwell-slip elements closest
to its pre-sliding (:func:`kukaid.sim.config.lugre_elements`), as identification would at best.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kukaid.errors import KukaidError
from kukaid.sim.config import SimConfig

FAMILY = ("gms", "gms-sensor", "gms-gravity", "lugre", "lugre-posfric", "lugre-all")


@dataclass(frozen=True)
class Plant:
    """One member: ``name``, the simulator's ``cfg`` (the truth) and the controller's ``params``
    (a ``kukaid.params/1`` dictionary, what an identification of this axis would write)."""

    name: str
    seed: int
    cfg: SimConfig
    params: dict[str, Any]

    @property
    def friction_law(self) -> str:
        return self.cfg.friction_law


def plant(name: str, seed: int = 0) -> Plant:
    """Draw member ``name`` of :data:`FAMILY` from ``seed`` (the same seed, the same plant)."""
    if name not in FAMILY:
        raise KukaidError(f"plant family: unknown member {name!r}; choose one of {', '.join(FAMILY)}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), FAMILY.index(name), 0xfa]))
    u = rng.uniform
    base = SimConfig()
    Fc = base.Fc * u(0.8, 1.25)
    Izz, Mx = base.Izz * u(0.85, 1.2), base.Mx * u(0.8, 1.2)
    kw: dict[str, Any] = dict(
        Fc=Fc, Fs=Fc * u(1.08, 1.3), vs=base.vs * u(0.7, 1.4), Fv=base.Fv * u(0.8, 1.25),
        Izz=Izz, Mx=Mx, ctrl_Izz=Izz * u(0.95, 1.05), ctrl_Mx=Mx * u(0.95, 1.05),
        ms_W=tuple(w * u(0.8, 1.2) for w in base.ms_W), ms_k=tuple(k * u(0.7, 1.4) for k in base.ms_k),
        Kp=u(30.0, 50.0), Kv=u(120.0, 170.0), Ki=u(20.0, 50.0),
        noise_sigma=u(0.3, 0.7), vib_amplitude=u(0.0, 1e-5), vib_freq=u(0.5, 2.0))
    parts = set(name.split("-")[1:])
    if name.startswith("lugre"):
        kw.update(friction_law="lugre", lugre_sigma0=float(math.exp(u(math.log(1e5), math.log(4e5)))),
                  lugre_zeta=u(0.5, 1.5))
    if parts & {"sensor", "all"}:
        kw.update(tau_quant=u(0.05, 0.2), tau_delay=1)
    if parts & {"posfric", "all"}:
        kw.update(fric_pos_amp=u(0.1, 0.2), fric_pos_n=u(20.0, 60.0), fric_pos_phi=u(-math.pi, math.pi))
    cfg = base.replace(**kw)
    gravity_error = 0.0
    if parts & {"gravity", "all"}:
        gravity_error = u(0.03, 0.06) * (1.0 if rng.random() < 0.5 else -1.0)
    return Plant(name, int(seed), cfg, identified_params(cfg, rng, gravity_error))


def identified_params(cfg: SimConfig, rng: np.random.Generator, gravity_error: float = 0.0) -> dict[str, Any]:
    """The parameter file an identification of ``cfg`` would write: the truth with errors of the
    size `kukaid fit` leaves (friction 3-6 %, inertia 3-6 %, Maxwell-slip saturations 10 %), and
    ``gravity_error`` (relative) on the gravity amplitude."""
    p = cfg.truth_params()

    def off(lo: float, hi: float) -> float:
        return 1.0 + rng.uniform(lo, hi) * (1.0 if rng.random() < 0.5 else -1.0)

    f = p["friction"]
    f["Fc"] *= off(0.03, 0.06)
    f["Fs"] = max(f["Fs"] * off(0.03, 0.06), f["Fc"])
    f["Fv"] *= off(0.03, 0.06)
    p["inertial"]["Izz"] *= off(0.03, 0.06)
    p["inertial"]["Mx"] *= off(0.0, 0.02) if gravity_error == 0.0 else 1.0 + gravity_error
    ms = p["maxwell_slip"]
    ms["W"] = [w * off(0.05, 0.1) for w in ms["W"]]
    ms["zeta0"] = [0.0] * len(ms["W"])  # the plant's initial pre-sliding state is not the controller's to know
    p["provenance"] = {"source": "kukaid.sim.family", "note": "truth with identification errors"}
    return p


def gravity_loaded(cfg: SimConfig, gravity: float, inertia: float, friction: float) -> SimConfig:
    """``cfg`` made a gravity-loaded axis (an A2 where the family draws A3s): its gravity ``gravity`` x, its
    inertia ``inertia`` x, its friction (Coulomb, Stribeck, viscous, the Maxwell-slip saturations)
    ``friction`` x; the servo's machine data know it, and the drive takes four times the gravity."""
    g, j, f = float(gravity), float(inertia), float(friction)
    return cfg.replace(Mx=cfg.Mx * g, My=cfg.My * g, ctrl_Mx=cfg.ctrl_Mx * g, Izz=cfg.Izz * j,
                       ctrl_Izz=cfg.ctrl_Izz * j, Fc=cfg.Fc * f, Fs=cfg.Fs * f, Fv=cfg.Fv * f,
                       ms_W=tuple(w * f for w in cfg.ms_W), tau_max=max(cfg.tau_max, 4.0 * abs(cfg.Mx * g)))
