"""The parameter file (JSON, schema ``kukaid.params/1``): what ``fit`` writes and the rest reads.

Validation is driven by small tables of (field, range) so every error names the field and the
allowed range: the numbers of the fixed sections (:data:`_FIELDS`), the keys those sections may
hold (:data:`_KEYS`; a misspelt field is refused), and the parameters of the diagnosed
``effects`` (:data:`_EFFECT_KEYS`; every other effect parameter is a finite number).  ``metrics``
and ``provenance`` are free-form objects but for ``provenance.preprocess``'s settings the readers
filter new logs with (:data:`_PREPROCESS`), ``uncertainty`` maps any name to a standard deviation.

Physical ceilings: no real KUKA axis comes near them (the KR 1000 titan, the heaviest arm, has
joint torques of order 1e5 N·m and link inertias of order 1e4 kg·m² about its base axis; a linear
unit carrying it, forces of order 1e5 N and a few tonnes), so a value beyond one is a typing or
unit mistake (or 1e300), refused on read with the field and the range, before arithmetic on it
overflows in validate, report, diagnose or run-admittance: |torque| and |force| terms (Fc, Fs, Mx,
My, offset, Maxwell-slip W and zeta0) up to :data:`TORQUE_MAX`, Izz up to :data:`IZZ_MAX`, Fv up to
:data:`FV_MAX`, vs and qd_thr up to :data:`SPEED_MAX`, a Maxwell-slip stiffness up to
:data:`STIFFNESS_MAX`, every effect parameter within +-:data:`EFFECT_MAX` and every standard
deviation up to :data:`STD_MAX` (a number, however badly determined, that squares without overflow).
"""
from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any, Callable, Sequence

from kukaid.errors import ParamFileError
from kukaid.atomic import write_text_atomic
from kukaid.jsonfile import jsonable, read_json
from kukaid.models.effects import COEFFICIENTS, EFFECTS, NAMES, TAG
from kukaid.models.friction import MaxwellSlip
from kukaid.models.torque import TERMS, EffectTerm, JointTorqueModel

SCHEMA = "kukaid.params/1"
INF = math.inf
#: the smallest inertia (Izz) a parameter file holds, kg m^2 (kg on a prismatic axis); the fit's
#: lower bound for Izz is the same number, so a fit that drives Izz down writes it at this bound
IZZ_MIN = 1e-12
#: physical ceilings (see the module docstring), SI: N·m (N on a prismatic axis), kg·m² (kg),
#: N·m·s/rad (N·s/m), rad/s (m/s), N·m/rad (N/m)
TORQUE_MAX = 1e6
IZZ_MAX = 1e6
FV_MAX = 1e6
SPEED_MAX = 1e3
STIFFNESS_MAX = 1e12
EFFECT_MAX = 1e12
STD_MAX = 1e100
_CEILINGS = {TORQUE_MAX, IZZ_MAX, FV_MAX, SPEED_MAX, STIFFNESS_MAX, EFFECT_MAX}

# (section, field) -> (low, high, required)
_FIELDS: dict[tuple[str, str], tuple[float, float, bool]] = {
    ("friction", "Fc"): (0.0, TORQUE_MAX, True),
    ("friction", "Fv"): (0.0, FV_MAX, True),
    ("friction", "Fs"): (0.0, TORQUE_MAX, False),
    ("friction", "vs"): (1e-9, SPEED_MAX, False),
    ("friction", "delta"): (0.05, 10.0, False),
    ("inertial", "Izz"): (IZZ_MIN, IZZ_MAX, True),
    ("inertial", "Mx"): (-TORQUE_MAX, TORQUE_MAX, False),
    ("inertial", "My"): (-TORQUE_MAX, TORQUE_MAX, False),
    ("mode_switch", "qd_thr"): (0.0, SPEED_MAX, False),
}

# the keys a section with fixed keys may hold ("" is the top level); metrics, provenance, the
# keys of uncertainty and the parameters of an effect are free-form
_KEYS: dict[str, tuple[str, ...]] = {
    "": ("schema", "axis", "friction", "inertial", "offset", "maxwell_slip", "mode_switch", "effects",
         "uncertainty", "metrics", "provenance"),
    "friction": ("model", "Fc", "Fv", "Fs", "vs", "delta"),
    "inertial": ("Izz", "Mx", "My"),
    "maxwell_slip": ("k", "W", "zeta0"),
    "mode_switch": ("qd_thr",),
}

# Fs >= Fc for Stribeck friction, to within this relative tolerance (written values are rounded,
# and a fit holding Fs - Fc at its bound 0 may end a rounding step below it)
_FS_FC_RTOL = 1e-6

# effect parameter -> (kind, range or choices); every other parameter of an effect is a number
# (-EFFECT_MAX, EFFECT_MAX), except keys starting with "_" (free comments).  Kinds: "number" (finite, in the
# range), "number|null" (also null), "text" (a string, one of the choices unless None), "std"
# ({coefficient: finite number >= 0 or null}), "friction" (a friction object, signed levels).
_EFFECT_KEYS: dict[str, tuple[str, Any]] = {
    "model": ("text", None),                                # "kukaid.diagnose/1" or the writer's tag
    "unit": ("text", None),                                 # thermal_drift: unit of c (description)
    "stored_as": ("text", ("inertial.My", "offset")),       # native effects held by the rigid body
    "coordinate": ("text", ("temperature", "time", "energy")),  # thermal_drift
    "form": ("text", ("coulomb", "friction")),              # thermal_drift
    "shape": ("text", ("pulse", "decay")),                  # backlash
    "std": ("std", None),                                   # uncertainty of each coefficient
    "friction_ref": ("friction", None),                     # thermal_drift: the friction it scales
    "tau": ("number", (1e-9, EFFECT_MAX)),                  # backlash time constant, s
    "T_ref": ("number|null", (-EFFECT_MAX, EFFECT_MAX)),    # simulator truth: null = ambient
    "mu": ("number|null", (-EFFECT_MAX, EFFECT_MAX)),       # derived Fc_load / |Mx| (null: Mx = 0)
}
# keys an effect needs in any format (the online torque residual reads them); a diagnosis-format
# effect ("model": "kukaid.diagnose/1") needs its term's coefficients and settings (models.effects)
_EFFECT_NEEDS: dict[str, tuple[str, ...]] = {"position_ripple": ("n",)}


def _show(v: Any, limit: int = 60) -> str:
    """``v`` as JSON for a message, shortened to keep the message one readable line."""
    t = json.dumps(v, default=repr)
    return t if len(t) <= limit else t[: limit - 3] + "..."


def _number(where: str, v: Any, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ParamFileError(f"{where} must be a number, got {_show(v)}")
    if not math.isfinite(v):
        raise ParamFileError(f"{where} must be a finite number, got {v}")
    if not lo <= v <= hi:
        beyond = (v > hi and hi in _CEILINGS) or (v < lo and -lo in _CEILINGS)
        why = " (beyond any real KUKA axis: a unit or typing mistake?)" if beyond else ""
        raise ParamFileError(f"{where} = {v} is outside the allowed range [{lo:g}, {hi:g}]{why}")
    return float(v)


#: the fit's pre-processing (provenance.preprocess) that validate, report and diagnose filter new logs
#: with: name -> (low, high, a whole number); "diff" is a word
_PREPROCESS = {"cutoff": (1e-9, 1e6, False), "order": (1, 8, True), "edge": (0, 1e9, True), "decimate": (1, 1e6, True),
               "qd_thr": (0.0, 100.0, False), "reversal_window": (0.0, 3600.0, False)}


def _preprocess(where: str, pre: Any) -> None:
    """``provenance.preprocess`` (free-form but for the settings the readers take): each a number in
    its range, or null."""
    if pre is None:
        return
    pre = _object(where, "provenance.preprocess", pre)
    for k, (lo, hi, whole) in _PREPROCESS.items():
        v = pre.get(k)
        if v is None:
            continue
        if whole and (isinstance(v, bool) or not isinstance(v, int)):
            raise ParamFileError(f"{where}: provenance.preprocess.{k} must be a whole number, got {_show(v)}")
        _number(f"{where}: provenance.preprocess.{k}", v, lo, hi)
    if pre.get("diff") not in (None, "central", "spectral"):
        raise ParamFileError(f"{where}: provenance.preprocess.diff must be \"central\" or \"spectral\", got "
                             f"{_show(pre['diff'])}")


def _object(where: str, name: str, v: Any, what: str = "a JSON object") -> dict:
    if not isinstance(v, dict):
        raise ParamFileError(f"{where}: {name} must be {what}, got {_show(v)}")
    return v


def _known_keys(where: str, sec: str, s: dict, allowed: tuple[str, ...]) -> None:
    for k in s:
        if k not in allowed:
            name = f"{sec}.{k}" if sec else k
            raise ParamFileError(f"{where}: unknown field '{name}' (allowed: {', '.join(allowed)})")


def _friction_ref(where: str, name: str, fr: Any) -> None:
    """A friction object inside an effect: the keys of ``friction``, levels of either sign."""
    fr = _object(where, name, fr, "a friction object {model, Fc, Fv, Fs, vs, delta}")
    _known_keys(where, name, fr, _KEYS["friction"])
    model = fr.get("model", "stribeck")
    if model not in ("stribeck", "coulomb-viscous"):
        raise ParamFileError(f"{where}: {name}.model must be 'stribeck' or 'coulomb-viscous', got {_show(model)}")
    for f in ("Fc", "Fv") + (("Fs", "vs", "delta") if model == "stribeck" else ()):
        if f not in fr:
            raise ParamFileError(f"{where}: missing field {name}.{f}")
    for f in ("Fc", "Fv", "Fs", "vs", "delta"):
        if f in fr:
            lo, hi, _ = _FIELDS[("friction", f)]
            _number(f"{where}: {name}.{f}", fr[f], -hi if f in ("Fc", "Fv", "Fs") else lo, hi)


def _effects(where: str, effects: Any) -> None:
    effects = _object(where, "effects", effects, "an object {name: parameters}")
    for name, e in effects.items():
        if name not in NAMES:
            raise ParamFileError(f"{where}: unknown effect 'effects.{name}' (known: {', '.join(NAMES)})")
        e = _object(where, f"effects.{name}", e, "an object of parameters")
        for k, v in e.items():
            field = f"effects.{name}.{k}"
            if k.startswith("_"):
                continue
            kind, rng = _EFFECT_KEYS.get(k, ("number", (-EFFECT_MAX, EFFECT_MAX)))
            if kind == "text":
                if not isinstance(v, str) or (rng is not None and v not in rng):
                    want = "a string" if rng is None else " or ".join(f"'{c}'" for c in rng)
                    raise ParamFileError(f"{where}: {field} must be {want}, got {_show(v)}")
            elif kind == "std":
                for c, s in _object(where, field, v, "an object {coefficient: standard deviation}").items():
                    if s is not None:
                        _number(f"{where}: {field}.{c}", s, 0.0, STD_MAX)
            elif kind == "friction":
                _friction_ref(where, field, v)
            elif not (v is None and kind == "number|null"):
                _number(f"{where}: {field}", v, *rng)
        need = _EFFECT_NEEDS.get(name, ())
        if e.get("model") == TAG:  # the diagnosis reads these back (kukaid diagnose, effects_torque)
            need = COEFFICIENTS[name] + EFFECTS[name].settings
        for k in need:
            if k not in e:
                raise ParamFileError(f"{where}: missing field effects.{name}.{k}")


def validate_params(d: Any, where: str = "parameter file") -> dict:
    """Check a parameter dictionary against the schema; return it unchanged or raise ParamFileError."""
    if not isinstance(d, dict):
        raise ParamFileError(f"{where}: top level must be a JSON object")
    if d.get("schema") != SCHEMA:
        raise ParamFileError(f"{where}: 'schema' must be \"{SCHEMA}\", got {_show(d.get('schema'))}")
    _known_keys(where, "", d, _KEYS[""])
    for sec in ("friction", "inertial"):
        if sec not in d:
            raise ParamFileError(f"{where}: missing section '{sec}'")
    for sec in ("friction", "inertial", "mode_switch"):
        if sec in d:
            _known_keys(where, sec, _object(where, sec, d[sec]), _KEYS[sec])
    model = d["friction"].get("model", "stribeck")
    if model not in ("stribeck", "coulomb-viscous"):
        raise ParamFileError(f"{where}: friction.model must be 'stribeck' or 'coulomb-viscous', got {_show(model)}")
    for (sec, name), (lo, hi, required) in _FIELDS.items():
        s = d.get(sec) or {}
        need = required or (sec == "friction" and model == "stribeck" and name in ("Fs", "vs", "delta"))
        if name not in s:
            if need:
                raise ParamFileError(f"{where}: missing field {sec}.{name}")
            continue
        _number(f"{where}: {sec}.{name}", s[name], lo, hi)
    fr = d["friction"]
    if model == "stribeck" and fr["Fs"] < fr["Fc"] - _FS_FC_RTOL * abs(fr["Fc"]):
        raise ParamFileError(f"{where}: friction.Fs = {fr['Fs']} must not be below friction.Fc = {fr['Fc']} "
                             f"(Stribeck static friction is at least the Coulomb level)")
    if "offset" in d:
        _number(f"{where}: offset", d["offset"], -TORQUE_MAX, TORQUE_MAX)
    ms = d.get("maxwell_slip")
    if ms is not None:
        if not isinstance(ms, dict) or not all(isinstance(ms.get(x), list) for x in ("k", "W")):
            raise ParamFileError(f"{where}: maxwell_slip must have lists 'k' and 'W'")
        _known_keys(where, "maxwell_slip", ms, _KEYS["maxwell_slip"])
        n = len(ms["k"])
        zeta0 = ms.get("zeta0", [0.0] * n)
        if n == 0 or len(ms["W"]) != n or not isinstance(zeta0, list) or len(zeta0) != n:
            raise ParamFileError(f"{where}: maxwell_slip.k, .W and .zeta0 must be non-empty lists of one length")
        for i in range(n):
            _number(f"{where}: maxwell_slip.k[{i}]", ms["k"][i], 1e-12, STIFFNESS_MAX)
            _number(f"{where}: maxwell_slip.W[{i}]", ms["W"][i], 0.0, TORQUE_MAX)
            _number(f"{where}: maxwell_slip.zeta0[{i}]", zeta0[i], -TORQUE_MAX, TORQUE_MAX)
    ax = d.get("axis")
    if ax is not None and (isinstance(ax, bool) or not isinstance(ax, int) or not 1 <= ax <= 12):
        raise ParamFileError(f"{where}: axis must be an integer 1 to 12, got {_show(ax)}")
    if "effects" in d:
        _effects(where, d["effects"])
    for sec in ("metrics", "provenance"):
        if sec in d:
            _object(where, sec, d[sec])
    _preprocess(where, (d.get("provenance") or {}).get("preprocess"))
    if "uncertainty" in d:
        unc = _object(where, "uncertainty", d["uncertainty"], "an object {parameter: standard deviation}")
        for k, v in unc.items():
            if v is not None:
                _number(f"{where}: uncertainty.{k}", v, 0.0, STD_MAX)
    return d


def load_params(path: str | Path) -> dict:
    """Read and validate a parameter file."""
    return validate_params(read_json(path, ParamFileError), str(path))


def save_params(path: str | Path, d: dict) -> None:
    """Validate and write a parameter file atomically."""
    d = {"schema": SCHEMA, **{k: v for k, v in d.items() if k != "schema"}}
    validate_params(d, str(path))
    write_text_atomic(path, json.dumps(d, indent=2, sort_keys=False) + "\n")


#: the units of a joint type, as the messages about a model of another kind name them
JOINT_UNITS = {"revolute": "rad, N·m", "prismatic": "positions in m, forces in N"}


def check_model_of(d: dict, source: str, axis: int | None = None, joint: str | None = None, use: str = "",
                   error: type[ParamFileError] | None = None) -> None:
    """Refuse a one-axis parameter file used for another axis or another kind of joint: the one
    message every command gives (report, validate, diagnose, run-admittance)::

        params.json: the parameters are of axis A2, not A4
        emps.json: the parameters are of a prismatic axis (A1, positions in m, forces in N), not of a revolute one

    ``axis``: the axis the command works on (None: not checked; a file without ``axis`` fits
    any); ``joint``: that axis's joint type (the log's, or the robot's); ``use``: what the model
    was to do, appended after a colon; ``error``: the error class (an axis asked for by an option
    is a usage error, :class:`~kukaid.errors.OptionError`; exit status 1 otherwise)."""
    file_axis = d.get("axis")
    file_joint = (d.get("provenance") or {}).get("joint") or "revolute"
    tail = f": {use}" if use else ""
    if joint is not None and file_joint != joint:
        name = f"A{file_axis}, " if file_axis is not None else ""
        units = JOINT_UNITS.get(file_joint, f"joint type {file_joint!r}")
        raise ParamFileError(f"{source}: the parameters are of a {file_joint} axis ({name}{units}), not of a {joint} "
                             f"one{tail}")
    if file_axis is not None:
        check_axis(source, (int(file_axis),), axis, tail, error)


def check_axis(source: str, axes: Sequence[int], axis: int | None, tail: str = "",
               error: type[ParamFileError] | None = None) -> None:
    """Refuse an ``axis`` that a parameter file does not model (``axes``: a one-axis file's axis, a
    robot file's A1..An), with the one line every command gives::

        params.json: the parameters are of axis A2, not A4 (--axis 4)
        robot.json: the parameters are of axes A1..A6, not A9 (--axis 9)

    ``tail`` is appended (what the axis was for, or the option that asked for it); ``error`` as
    :func:`check_model_of`'s."""
    if axis is None or int(axis) in axes:
        return
    what = f"axis A{axes[0]}" if len(axes) == 1 else f"axes A{min(axes)}..A{max(axes)}"
    raise (error or ParamFileError)(f"{source}: the parameters are of {what}, not A{axis}{tail}")


def model_from_params(d: dict, joint: str = "revolute") -> JointTorqueModel:
    """The :class:`~kukaid.models.torque.JointTorqueModel` of a (validated) parameter dictionary.

    Mx is a parameter when the file has it or its fit had gravity (a fit with ``--gravity none``
    has none, and a refit adds none); Mx and My never on a prismatic ``joint``.  Effects written
    by ``kukaid diagnose`` become effect terms (gravity_sine and torque_offset the rigid body's My
    and offset); the others are kept in ``stored_effects`` and named in ``ignored_effects``."""
    fr, inert = d.get("friction") or {}, d.get("inertial") or {}
    kind = fr.get("model", "stribeck")
    lin: dict[str, float] = {"Fc": float(fr.get("Fc", 0.0)), "Fv": float(fr.get("Fv", 0.0))}
    if kind == "stribeck":
        lin["Fs"] = float(fr.get("Fs", lin["Fc"]))
    lin["Izz"] = float(inert.get("Izz", 0.0))
    gravity = (d.get("provenance") or {}).get("gravity")
    if joint == "revolute" and ("Mx" in inert or (gravity is not None and gravity != "none")):
        lin["Mx"] = float(inert.get("Mx", 0.0))
    if joint == "revolute" and "My" in inert:
        lin["My"] = float(inert["My"])
    if "offset" in d:
        lin["offset"] = float(d["offset"])
    ms = d.get("maxwell_slip")
    m = JointTorqueModel(kind, lin, float(fr.get("vs", 0.04)), float(fr.get("delta", 1.0)),
                         maxwell_slip=MaxwellSlip(ms["k"], ms["W"]) if ms else None,
                         zeta0=tuple(float(x) for x in ms["zeta0"]) if ms and "zeta0" in ms else None,
                         qd_thr=float((d.get("mode_switch") or {}).get("qd_thr", 0.0017)),
                         stored_effects=dict(d.get("effects") or {}))
    for name, e in m.stored_effects.items():
        if not isinstance(e, dict) or e.get("model") != TAG or name not in EFFECTS:
            m.ignored_effects.append(name)
        elif EFFECTS[name].native:
            lin.setdefault(EFFECTS[name].native, float(e.get(EFFECTS[name].native, 0.0)))
        else:
            m.effects.append(EffectTerm(name, *EFFECTS[name].from_params(e)))
    return m


def model_sections(m: JointTorqueModel, digits: int | None = None) -> dict[str, Any]:
    """The sections of the base terms (friction, inertial, offset, maxwell_slip, mode_switch),
    values rounded to ``digits`` significant digits if given."""
    r: Callable[[float], float] = (lambda x: float(f"{x:.{digits}g}")) if digits else float
    out: dict[str, Any] = {"friction": {"model": m.friction_kind, **{k: r(m.value(k)) for k in TERMS["friction"]
                                                                     if m.has(k)}},
                           "inertial": {k: r(m.lin[k]) for k in TERMS["rigid_body"] if k in m.lin}}
    if "offset" in m.lin:
        out["offset"] = r(m.lin["offset"])
    if m.maxwell_slip is not None:
        out["maxwell_slip"] = {k: [r(x) for x in v] for k, v in m.maxwell_slip.to_dict(m.zeta0).items()}
    out["mode_switch"] = {"qd_thr": m.qd_thr}
    return out


def model_to_params(m: JointTorqueModel, base: dict, added: Sequence[str] = ()) -> dict:
    """A parameter dictionary: ``base`` with the values and effect terms of ``m``.

    ``added`` names the effects a diagnosis added (native ones, My and offset, are stored in the
    rigid body and recorded in ``effects`` with ``stored_as``).  A refit leaves Fs free; Fs below
    Fc (data with no Stribeck rise) is stored as Fs = Fc, the file's Stribeck model having Fs >= Fc."""
    c = m.copy()
    c.lin["Fc"], c.lin["Fv"] = max(c.lin["Fc"], 0.0), max(c.lin["Fv"], 0.0)
    if c.friction_kind == "stribeck":
        c.lin["Fs"] = max(c.lin["Fs"], c.lin["Fc"])
    c.lin["Izz"] = max(c.lin["Izz"], IZZ_MIN)
    sec = model_sections(c)
    d = copy.deepcopy(base)
    for k in ("friction", "inertial"):
        d[k] = {**(d.get(k) or {}), **sec[k]}
    if "offset" in sec:
        d["offset"] = sec["offset"]
    d["uncertainty"] = {**(d.get("uncertainty") or {}),
                        **{k: v for k, v in m.std.items() if "." not in k and math.isfinite(v)}}
    effects = dict(d.get("effects") or {})
    for name, eff in EFFECTS.items():
        if eff.native and eff.native in m.lin and (name in effects or name in added):
            effects[name] = {"model": TAG, eff.native: m.lin[eff.native],
                             "std": {eff.native: m.std.get(eff.native, math.nan)},
                             "stored_as": "inertial.My" if eff.native == "My" else "offset"}
    for e in m.effects:
        std = {k: m.std.get(e.key(k), math.nan) for k in e.coefs}
        effects[e.name] = EFFECTS[e.name].describe(e.nl, e.coefs, std, m)
    d["effects"] = jsonable(effects)
    return d
