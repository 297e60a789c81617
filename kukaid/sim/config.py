"""Configuration of the virtual KR C4: the true axis (truth), its servo, its sensors, its environment.

:class:`SimConfig` is a frozen dataclass whose defaults are the paper's identified values for A3
of a KR 6 R700 sixx (Table 1 friction, Table 2 Maxwell-slip, Izz = 2.2836 kg·m², Mx = 18.4789 N·m)
and plausible values for what the paper does not give (servo gains, thermal model, vibration).
Every field can be overridden from a JSON file (:func:`load_sim_config`) or with
:meth:`SimConfig.replace`; both validate against the table ``FIELDS`` and raise
:class:`SimConfigError` naming the field and the allowed range.

The JSON file may be flat (field names of :class:`SimConfig`) or shaped like a parameter file
(``kukaid.params/1``: sections ``friction``, ``inertial``, ``maxwell_slip``, ``mode_switch``,
``effects``), or a mix, so a fitted parameter file can serve directly as the truth of a simulation.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from kukaid.errors import SimConfigError
from kukaid.jsonfile import read_json

INF = math.inf
#: friction laws of the plant: "gms" (the estimator's own: Maxwell-slip at rest, exactly Stribeck
#: sliding, :mod:`kukaid.sim.friction_sim`) and "lugre" (Canudas de Wit et al. 1995, independent of it)
FRICTION_LAWS = ("gms", "lugre")


# field -> (kind, low, high, doc).  kind: "float", "int", "bool", "vec" (list of floats), "choice"
# (one of FRICTION_LAWS).
FIELDS: dict[str, tuple[str, float, float, str]] = {
    "axis": ("int", 1, 12, "axis number, KUKA numbering"),
    # truth: friction, eq. (1)
    "Fc": ("float", 0.0, 1e4, "Coulomb friction, N·m"),
    "Fs": ("float", 0.0, 1e4, "static (Stribeck peak) friction, N·m"),
    "vs": ("float", 1e-6, 100.0, "Stribeck velocity, rad/s"),
    "delta": ("float", 0.1, 10.0, "Stribeck shape exponent"),
    "Fv": ("float", 0.0, 1e4, "viscous friction, N·m·s/rad"),
    # truth: Maxwell-slip, eqs. (9)-(10)
    "ms_k": ("vec", 1e-3, 1e8, "Maxwell-slip element stiffnesses, N·m/rad"),
    "ms_W": ("vec", 1e-6, 1e4, "Maxwell-slip element saturation torques, N·m"),
    "ms_zeta0": ("vec", -1.0, 1.0, "Maxwell-slip element positions at reset relative to q0, rad"),
    "ms_damping": ("float", 0.0, 5.0, "pre-sliding damping ratio of the Maxwell-slip elements (c_i = 2 zeta sqrt(k_i Izz))"),
    "v_blend": ("float", 1e-6, 1.0, "speed above which friction is pure Stribeck, rad/s"),
    # truth: the friction law (the estimator's own Maxwell-slip/Stribeck, or LuGre, independent of it)
    "friction_law": ("choice", 0, 0, "friction law of the plant: gms (Maxwell-slip at rest, Stribeck sliding) or lugre"),
    "lugre_sigma0": ("float", 1.0, 1e8, "LuGre bristle stiffness sigma0, N·m/rad"),
    "lugre_zeta": ("float", 0.0, 5.0, "LuGre bristle damping ratio (sigma1 = 2 zeta sqrt(sigma0 Izz))"),
    "fric_pos_amp": ("float", 0.0, 0.9, "position dependence of the friction magnitude: relative amplitude a of 1 + a sin(n q + phi)"),
    "fric_pos_n": ("float", 0.0, 1e3, "position dependence of the friction: order n, rad/rad (n periods per revolution)"),
    "fric_pos_phi": ("float", -10.0, 10.0, "position dependence of the friction: phase phi, rad"),
    # truth: rigid body, eqs. (6)-(8)
    "Izz": ("float", 1e-4, 1e4, "moment of inertia, kg·m²"),
    "Mx": ("float", -1e4, 1e4, "gravity torque amplitude (cos q), N·m"),
    "My": ("float", -1e4, 1e4, "gravity torque amplitude (sin q), N·m"),
    # servo (the KRC's position controller) and its model of the axis (machine data)
    "servo_rate": ("float", 250.0, 20000.0, "position/velocity servo rate, Hz"),
    "substeps": ("int", 1, 50, "physics integration steps per servo cycle"),
    "ipo_period": ("float", 1e-3, 1.0, "interpolation (IPO) cycle of the commanded trajectory, s"),
    "Kp": ("float", 0.0, 1e3, "position loop gain, 1/s"),
    "Kv": ("float", 1.0, 1e4, "velocity loop gain (bandwidth), rad/s"),
    "Ki": ("float", 0.0, 1e3, "velocity loop integral gain, 1/s"),
    "ctrl_Izz": ("float", 1e-4, 1e4, "inertia the controller assumes (feedforward, loop scaling), kg·m²"),
    "ctrl_Mx": ("float", -1e4, 1e4, "gravity amplitude the controller feeds forward, N·m"),
    "tau_max": ("float", 1e-3, 1e5, "motor torque limit at the axis, N·m"),
    # measurement
    "sample_time": ("float", 1e-3, 1.0, "sample interval of $AXIS_ACT_MEAS/$TORQUE_AXIS_ACT, s"),
    "noise_sigma": ("float", 0.0, 100.0, "standard deviation of the torque noise, N·m"),
    "quant_deg": ("float", 0.0, 1.0, "position resolution of $AXIS_ACT_MEAS, degrees (0: none)"),
    "tau_quant": ("float", 0.0, 100.0, "resolution of $TORQUE_AXIS_ACT, N·m (0: none)"),
    "tau_delay": ("int", 0, 10, "samples by which $TORQUE_AXIS_ACT lags the position"),
    "jitter": ("float", 0.0, 0.005, "max. timing jitter of a sample, s (uniform, +-)"),
    # motor temperature (first-order thermal model)
    "T_amb": ("float", -50.0, 200.0, "ambient temperature, °C"),
    "T0": ("float", -50.0, 200.0, "motor temperature at reset, °C (NaN: T_amb)"),
    "R_th": ("float", 1e-4, 1e3, "thermal resistance motor -> ambient, K/W"),
    "C_th": ("float", 1e-3, 1e7, "heat capacity of the motor, J/K"),
    "r_cu": ("float", 0.0, 1e3, "copper loss per squared axis torque, W/(N·m)²"),
    # ambient vibration from A6
    "vibration": ("bool", 0, 1, "ambient vibration from axis 6 on/off"),
    "vib_amplitude": ("float", 0.0, 1e-2, "RMS of the vibration's deflection of the A3 reference, rad"),
    "vib_freq": ("float", 0.05, 100.0, "centre frequency of the vibration, Hz"),
    "vib_zeta": ("float", 0.01, 2.0, "damping ratio of the vibration band-pass"),
}

_PAPER_K = (35894.0, 160065.0, 51893.0)
_PAPER_W = (7.3406, 1.371, 6.288)
_PAPER_ZETA = (-0.00041, -0.00048, 0.00027)


@dataclass(frozen=True)
class SimConfig:
    """Everything the virtual KR C4 needs; defaults are the paper's A3 (see module docstring).

    Truth (SI): ``Fc, Fs, vs, delta, Fv`` (Stribeck, eq. 1); ``ms_k, ms_W, ms_zeta0`` (Maxwell-slip,
    Table 2; ``ms_zeta0`` are element positions relative to the reset position, clamped to
    saturation); ``ms_damping`` (pre-sliding damping ratio of the elements, default 0: pure
    Maxwell-slip); ``v_blend`` (speed above which steady friction is exactly Stribeck);
    ``friction_law`` ("gms", the estimator's own law as above, or "lugre": one bristle state of
    stiffness ``lugre_sigma0`` N·m/rad and damping ratio ``lugre_zeta``, stiction ``Fs``, the
    Maxwell-slip fields unused); ``fric_pos_amp, fric_pos_n, fric_pos_phi`` (friction magnitude
    times 1 + a sin(n q + phi));
    ``Izz, Mx, My`` (rigid body).  Servo: ``servo_rate`` Hz, ``Kp`` 1/s, ``Kv`` rad/s, ``Ki`` 1/s,
    feedforward model ``ctrl_Izz, ctrl_Mx``, torque limit ``tau_max`` N·m.  Measurement:
    ``sample_time`` s, ``noise_sigma`` N·m, ``quant_deg`` degrees, ``tau_quant`` N·m (torque
    resolution), ``tau_delay`` (samples the torque lags the position), ``jitter`` s.  Thermal:
    ``T_amb, T0`` °C, ``R_th`` K/W, ``C_th`` J/K, ``r_cu`` W/(N·m)².  Vibration: ``vibration``,
    ``vib_amplitude`` rad, ``vib_freq`` Hz, ``vib_zeta``.  ``effects``: hidden effects
    {name: parameters}, see :mod:`kukaid.sim.effects`.
    """

    axis: int = 3
    Fc: float = 15.70
    Fs: float = 17.56
    vs: float = 0.04
    delta: float = 2.0
    Fv: float = 14.15
    ms_k: tuple[float, ...] = _PAPER_K
    ms_W: tuple[float, ...] = _PAPER_W
    ms_zeta0: tuple[float, ...] = _PAPER_ZETA
    ms_damping: float = 0.0
    v_blend: float = 0.0017
    friction_law: str = "gms"
    lugre_sigma0: float = 2.0e5
    lugre_zeta: float = 1.0
    fric_pos_amp: float = 0.0
    fric_pos_n: float = 0.0
    fric_pos_phi: float = 0.0
    Izz: float = 2.2836
    Mx: float = 18.4789
    My: float = 0.0
    servo_rate: float = 1000.0
    substeps: int = 2
    ipo_period: float = 0.012
    Kp: float = 40.0
    Kv: float = 150.0
    Ki: float = 30.0
    ctrl_Izz: float = 2.2836
    ctrl_Mx: float = 18.4789
    tau_max: float = 120.0
    sample_time: float = 0.012
    noise_sigma: float = 0.5
    quant_deg: float = 1e-4
    tau_quant: float = 0.0
    tau_delay: int = 0
    jitter: float = 0.0
    T_amb: float = 25.0
    T0: float = math.nan
    R_th: float = 2.0
    C_th: float = 300.0
    r_cu: float = 0.01
    vibration: bool = True
    vib_amplitude: float = 5e-5
    vib_freq: float = 1.0
    vib_zeta: float = 0.3
    effects: dict[str, dict] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _validate(self, "sim config")

    # -- copies ----------------------------------------------------------------------------
    def replace(self, **changes: Any) -> "SimConfig":
        """A validated copy with ``changes`` applied (unknown names raise SimConfigError)."""
        names = {f.name for f in fields(self)}
        for k in changes:
            if k not in names:
                raise SimConfigError(f"sim config: unknown field '{k}' (known: {', '.join(sorted(names))})")
        return replace(self, **changes)

    # -- views -----------------------------------------------------------------------------
    @property
    def sum_W(self) -> float:
        """Maxwell-slip saturation torque, sum of W_i, N·m."""
        return float(sum(self.ms_W))

    @property
    def temp0(self) -> float:
        return self.T_amb if math.isnan(self.T0) else self.T0

    def to_dict(self) -> dict:
        """JSON-able flat dictionary of every field (``load_sim_config`` reads it back)."""
        d = asdict(self)
        for k in ("ms_k", "ms_W", "ms_zeta0"):
            d[k] = list(d[k])
        d["T0"] = None if math.isnan(self.T0) else self.T0
        d["effects"] = json.loads(json.dumps(self.effects))
        return d

    def stribeck(self):
        """The true sliding friction as a :class:`kukaid.models.friction.Stribeck`."""
        from kukaid.models.friction import Stribeck

        return Stribeck(self.Fc, self.Fs, self.vs, self.delta, self.Fv)

    def truth_params(self) -> dict:
        """The truth as a ``kukaid.params/1`` dictionary (friction, inertial, maxwell_slip, effects).

        A LuGre plant has no Maxwell-slip elements: its section holds the elements closest to
        LuGre's pre-sliding (:func:`lugre_elements`), what identification would find at best,
        not a truth the estimator shares."""
        ms = {"k": list(self.ms_k), "W": list(self.ms_W), "zeta0": list(self.ms_zeta0)}
        if self.friction_law == "lugre":
            k, W = lugre_elements(self.lugre_sigma0, self.Fs)
            ms = {"k": k, "W": W, "zeta0": [0.0] * len(k)}
        return {
            "schema": "kukaid.params/1",
            "axis": int(self.axis),
            "friction": {"model": "stribeck", "Fc": self.Fc, "Fs": self.Fs, "vs": self.vs,
                         "delta": self.delta, "Fv": self.Fv},
            "inertial": {"Izz": self.Izz, "Mx": self.Mx, "My": self.My},
            "maxwell_slip": ms,
            "mode_switch": {"qd_thr": self.v_blend},
            "effects": json.loads(json.dumps(self.effects)),
            "provenance": {"source": "virtual-krc4 truth", "friction_law": self.friction_law},
        }


def lugre_elements(sigma0: float, Fs: float, breaks: tuple[float, ...] = (0.5, 1.5, 4.0)) -> tuple[list[float], list[float]]:
    """Maxwell-slip elements (k N·m/rad, W N·m) whose reversal curve matches LuGre's at rest.

    After a stop LuGre's bristles are deflected to ``z = Fs/sigma0``; reversing by ``x`` swings the
    friction by ``R(x) = 2 Fs (1 - exp(-sigma0 x / Fs))`` (initial stiffness 2 sigma0).  The
    elements' swing ``sum min(k_i x, 2 W_i)`` is the piecewise-linear interpolation of R through
    ``x = breaks * Fs/sigma0``, reaching the full swing 2 Fs at the last break.
    """
    x0 = Fs / sigma0
    xs = [0.0] + [b * x0 for b in breaks]
    R = [2.0 * Fs * (1.0 - math.exp(-x / x0)) for x in xs]
    R[-1] = 2.0 * Fs
    slopes = [(R[i + 1] - R[i]) / (xs[i + 1] - xs[i]) for i in range(len(breaks))] + [0.0]
    k = [slopes[i] - slopes[i + 1] for i in range(len(breaks))]
    W = [0.5 * ki * xs[i + 1] for i, ki in enumerate(k)]
    return k, W


def truth_params(cfg: SimConfig) -> dict:
    """Function form of :meth:`SimConfig.truth_params`."""
    return cfg.truth_params()


def _validate(cfg: SimConfig, where: str) -> None:
    for name, (kind, lo, hi, doc) in FIELDS.items():
        v = getattr(cfg, name)
        fw = f"{where}: field '{name}' ({doc})"
        if kind == "choice":
            if v not in FRICTION_LAWS:
                raise SimConfigError(f"{fw} must be one of {', '.join(FRICTION_LAWS)}, got {json.dumps(v, default=str)}")
        elif kind == "bool":
            if not isinstance(v, (bool, int)) or v not in (0, 1, True, False):
                raise SimConfigError(f"{fw} must be true or false, got {json.dumps(v, default=str)}")
            object.__setattr__(cfg, name, bool(v))
        elif kind == "int":
            if isinstance(v, bool) or not isinstance(v, (int, float)) or float(v) != int(v):
                raise SimConfigError(f"{fw} must be an integer, got {json.dumps(v, default=str)}")
            if not lo <= v <= hi:
                raise SimConfigError(f"{fw} = {v} is outside the allowed range [{lo}, {hi}]")
            object.__setattr__(cfg, name, int(v))
        elif kind == "float":
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                if name == "T0" and v is None:
                    object.__setattr__(cfg, name, math.nan)
                    continue
                raise SimConfigError(f"{fw} must be a number, got {json.dumps(v, default=str)}")
            if name == "T0" and math.isnan(v):
                continue
            if not math.isfinite(v) or not lo <= v <= hi:
                raise SimConfigError(f"{fw} = {v} is outside the allowed range [{lo}, {hi}]")
            object.__setattr__(cfg, name, float(v))
        else:  # vec
            if isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) == 0:
                raise SimConfigError(f"{fw} must be a non-empty list of numbers, got {json.dumps(v, default=str)}")
            out = []
            for i, x in enumerate(v):
                if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                    raise SimConfigError(f"{where}: field '{name}[{i}]' must be a finite number, got {json.dumps(x, default=str)}")
                if not lo <= x <= hi:
                    raise SimConfigError(f"{where}: field '{name}[{i}]' = {x} is outside the allowed range [{lo}, {hi}]")
                out.append(float(x))
            object.__setattr__(cfg, name, tuple(out))
    if cfg.Fs < cfg.Fc:  # as a parameter file's reader refuses it (kukaid.params.axis)
        raise SimConfigError(f"{where}: field 'Fs' = {cfg.Fs:g} must not be below field 'Fc' = {cfg.Fc:g} "
                             "(Stribeck static friction is at least the Coulomb level)")
    n = len(cfg.ms_k)
    if len(cfg.ms_W) != n or len(cfg.ms_zeta0) != n:
        raise SimConfigError(f"{where}: fields 'ms_k', 'ms_W' and 'ms_zeta0' must have one length "
                             f"(got {len(cfg.ms_k)}, {len(cfg.ms_W)}, {len(cfg.ms_zeta0)})")
    if cfg.jitter >= 0.5 * cfg.sample_time:
        raise SimConfigError(f"{where}: field 'jitter' = {cfg.jitter} must be less than half the sample time "
                             f"({cfg.sample_time})")
    if cfg.sample_time * cfg.servo_rate < 1 - 1e-9:
        raise SimConfigError(f"{where}: field 'sample_time' = {cfg.sample_time} is shorter than a servo cycle")
    if not isinstance(cfg.effects, dict):
        raise SimConfigError(f"{where}: field 'effects' must be an object {{name: parameters}}")
    from kukaid.sim.effects import validate_effects

    eff = validate_effects(cfg.effects, where)
    if "thermal_drift" in eff and eff["thermal_drift"].get("T_ref") is None:
        eff["thermal_drift"]["T_ref"] = cfg.T_amb
    object.__setattr__(cfg, "effects", eff)
    # the discrete velocity loop: gain ctrl_Izz Kv / Izz per servo cycle must stay well below 2
    loop = cfg.ctrl_Izz * cfg.Kv / cfg.Izz / cfg.servo_rate
    if loop > 1.0:
        raise SimConfigError(f"{where}: field 'Kv' = {cfg.Kv} makes the servo unstable for Izz = {cfg.Izz} "
                             f"(ctrl_Izz Kv / (Izz servo_rate) = {loop:.2f} > 1); set ctrl_Izz near Izz, lower Kv or raise servo_rate")


# -- JSON ----------------------------------------------------------------------------------
# parameter-file sections -> SimConfig fields
_SECTION_MAP = {
    "friction": {"Fc": "Fc", "Fs": "Fs", "vs": "vs", "delta": "delta", "Fv": "Fv"},
    "inertial": {"Izz": "Izz", "Mx": "Mx", "My": "My"},
    "maxwell_slip": {"k": "ms_k", "W": "ms_W", "zeta0": "ms_zeta0"},
    "mode_switch": {"qd_thr": "v_blend"},
}
_IGNORED = {"schema", "uncertainty", "metrics", "provenance", "offset", "comment", "_comment"}


def sim_config_from_dict(d: Any, where: str = "sim config", base: SimConfig | None = None) -> SimConfig:
    """Build a :class:`SimConfig` from a (flat or parameter-file shaped) dictionary of overrides."""
    if not isinstance(d, dict):
        raise SimConfigError(f"{where}: top level must be a JSON object")
    names = {f.name for f in fields(SimConfig)}
    changes: dict[str, Any] = {}
    for key, val in d.items():
        if key in _SECTION_MAP:
            if not isinstance(val, dict):
                raise SimConfigError(f"{where}: section '{key}' must be an object")
            for sub, sv in val.items():
                if key == "friction" and sub == "model":
                    if sv != "stribeck":
                        raise SimConfigError(f"{where}: field 'friction.model' must be \"stribeck\" for the "
                                             f"simulator, got {json.dumps(sv)}")
                    continue
                if sub not in _SECTION_MAP[key]:
                    raise SimConfigError(f"{where}: unknown field '{key}.{sub}' (known: "
                                         f"{', '.join(_SECTION_MAP[key])})")
                changes[_SECTION_MAP[key][sub]] = sv
        elif key == "offset":
            eff = dict(changes.get("effects", d.get("effects") or {}))
            eff.setdefault("torque_offset", {"offset": val})
            changes["effects"] = eff
        elif key in _IGNORED:
            continue
        elif key in names:
            if key == "effects" and "effects" in changes and isinstance(val, dict):
                changes["effects"] = {**changes["effects"], **val}
            else:
                changes[key] = val
        else:
            raise SimConfigError(f"{where}: unknown field '{key}' (known: {', '.join(sorted(names))}, "
                                 f"or sections {', '.join(_SECTION_MAP)})")
    try:
        return (base or SimConfig()).replace(**changes)
    except SimConfigError as e:
        msg = str(e)
        if where != "sim config" and msg.startswith("sim config: "):
            msg = f"{where}: " + msg[len("sim config: "):]
        raise SimConfigError(msg) from None


def load_sim_config(path: str | Path) -> SimConfig:
    """Read a JSON file of overrides of the paper defaults; validated, errors name file and field."""
    # a one-axis parameter file is a configuration too (the plant of a fit)
    return sim_config_from_dict(read_json(path, SimConfigError, schemas=("kukaid.params/1",)), str(path))
