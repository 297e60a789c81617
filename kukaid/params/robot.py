"""The robot parameter file (JSON, ``"schema": "kukaid.robot_params/1"``): a whole robot identified
from its URDF (``kukaid fit LOG... --robot``), validated on read and write.

Fields
------
robot : {name, urdf (bundled name or absolute path), urdf_relative (the same URDF from the parameter
    file's folder, written beside an absolute path: the file still finds it when the project moves),
    sha256 of the URDF, joints, links}.
axes : [1..n], KUKA numbering of the URDF's joints in order.
torque_side : "joint" or "motor".
base_parameters : {names, values (the estimate used to predict), least_squares (weighted least
    squares), sigma (standard deviation of the least-squares values), independent, dependent, R
    (beta = pi[independent] + R pi[dependent])}.
standard_parameters : {link: {m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz}} of the physically
    consistent estimate (kg, kg·m, kg·m² at the joint frame), or null.
friction : {model, vs, offset, values {A1.Fc: ...}, least_squares, sigma}.
drive : {ratio, coupling} or null.   settings : the fit's settings.   metrics, provenance : objects.
effects : {name: {its settings, coefficients, ...}} added by ``kukaid diagnose -o``
    (:mod:`kukaid.models.robot_effects`: ``counterbalance@A2``, ``payload``, ...); predicted with.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from kukaid.atomic import write_text_atomic
from kukaid.errors import ParamFileError
from kukaid.jsonfile import jsonable, read_json

SCHEMA = "kukaid.robot_params/1"
LINK_KEYS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def _fail(where: str, what: str) -> None:
    raise ParamFileError(f"{where}: {what}")


def _numbers(where: str, name: str, v: Any, size: int | None = None, nonneg: bool = False,
             allow_null: bool = False) -> None:
    if not isinstance(v, list):
        _fail(where, f"'{name}' must be a list of numbers")
    if size is not None and len(v) != size:
        _fail(where, f"'{name}' must have {size} entries, has {len(v)}")
    for i, x in enumerate(v):
        if x is None and allow_null:
            continue
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            _fail(where, f"'{name}[{i}]' must be a finite number, got {json.dumps(x)[:40]}")
        if nonneg and x < 0:
            _fail(where, f"'{name}[{i}]' must be >= 0, got {x}")


def _object(where: str, name: str, v: Any) -> dict:
    if not isinstance(v, dict):
        _fail(where, f"'{name}' must be a JSON object")
    return v


def _refined(d: dict) -> bool:
    """A file ``kukaid diagnose -o`` refined (its provenance says so)."""
    prov = d.get("provenance")
    return isinstance(prov, dict) and isinstance(prov.get("diagnose"), dict)


def validate_robot_params(d: Any, where: str = "robot parameter file") -> dict:
    """Check a robot parameter dictionary; raise :class:`ParamFileError` naming the field."""
    if not isinstance(d, dict):
        _fail(where, "top level must be a JSON object")
    if d.get("schema") != SCHEMA:
        _fail(where, f"'schema' must be \"{SCHEMA}\", got {json.dumps(d.get('schema'))[:60]}")
    for key in ("robot", "axes", "base_parameters", "friction", "settings"):
        if key not in d:
            _fail(where, f"missing field '{key}'")
    rob = _object(where, "robot", d["robot"])
    if not isinstance(rob.get("urdf"), str) or not rob["urdf"]:
        _fail(where, "'robot.urdf' must be a bundled robot name or the path of a URDF")
    if not isinstance(rob.get("urdf_relative", ""), str):
        _fail(where, "'robot.urdf_relative' must be a path (relative to the parameter file's folder)")
    axes = d["axes"]
    if not isinstance(axes, list) or not axes or axes != list(range(1, len(axes) + 1)):
        _fail(where, f"'axes' must be [1, 2, ..., n], got {json.dumps(axes)[:60]}")
    n = len(axes)
    if d.get("torque_side", "joint") not in ("joint", "motor"):
        _fail(where, "'torque_side' must be \"joint\" or \"motor\"")
    bp = _object(where, "base_parameters", d["base_parameters"])
    for key in ("names", "values", "independent", "dependent", "R"):
        if key not in bp:
            _fail(where, f"missing field 'base_parameters.{key}'")
    b = len(bp["independent"]) if isinstance(bp["independent"], list) else -1  # one value per independent column
    _numbers(where, "base_parameters.independent", bp["independent"])
    _numbers(where, "base_parameters.values", bp["values"], b)
    if not isinstance(bp["names"], list) or len(bp["names"]) != b:
        _fail(where, f"'base_parameters.names' must have {b} entries")
    for key in ("least_squares", "sigma"):
        if key in bp:
            _numbers(where, f"base_parameters.{key}", bp[key], b, nonneg=key == "sigma", allow_null=True)
    if not isinstance(bp["R"], list) or len(bp["R"]) != b:
        _fail(where, f"'base_parameters.R' must have {b} rows")
    nd = len(bp["dependent"]) if isinstance(bp["dependent"], list) else -1
    _numbers(where, "base_parameters.dependent", bp["dependent"])
    if b + nd != 10 * n:
        _fail(where, f"base_parameters: {b} independent + {nd} dependent must be 10 per axis ({10 * n})")
    if sorted(bp["independent"] + bp["dependent"]) != list(range(10 * n)):  # each standard parameter once
        _fail(where, f"'base_parameters.independent' and 'dependent' must together number the {10 * n} standard "
                     f"parameters 0 to {10 * n - 1}, each once")
    for i, row in enumerate(bp["R"]):
        _numbers(where, f"base_parameters.R[{i}]", row, nd)
    std = d.get("standard_parameters")
    if std is not None:
        _object(where, "standard_parameters", std)
        if len(std) != n:
            _fail(where, f"'standard_parameters' must have one entry per link ({n}), has {len(std)}")
        for link, p in std.items():
            _object(where, f"standard_parameters.{link}", p)
            for k in LINK_KEYS:
                if k not in p:
                    _fail(where, f"missing field 'standard_parameters.{link}.{k}'")
            _numbers(where, f"standard_parameters.{link}", [p[k] for k in LINK_KEYS])
            if p["m"] <= 0:
                _fail(where, f"'standard_parameters.{link}.m' must be > 0 (a mass), got {p['m']}")
    fr = _object(where, "friction", d["friction"])
    if fr.get("model") not in ("coulomb-viscous", "stribeck"):
        _fail(where, "'friction.model' must be \"coulomb-viscous\" or \"stribeck\"")
    vals = _object(where, "friction.values", fr.get("values"))
    _numbers(where, "friction.values", list(vals.values()))
    for k, v in vals.items():
        if not k.startswith(("A", "M")):
            _fail(where, f"'friction.values' key {k!r} is not 'A<axis>.<parameter>'")
        head = k.split(".", 1)[0]
        if not (head[1:].isdigit() and 1 <= int(head[1:]) <= n):
            _fail(where, f"'friction.values' key {k!r}: the robot has axes A1..A{n}")
        # the fit keeps them >= 0 (a friction, an inertia), to its solver's tolerance on the bound (-1e-8); a file
        # diagnose refined refits a joint's own friction beside its effects, where it is a correction (beside the
        # coupled wrist's motor friction A5.Fv came out -0.0056 N·m·s/rad), so a fit's own file alone is held to it
        if k.endswith((".Fc", ".Fv", ".rotor_inertia")) and v < -1e-6 and not _refined(d):
            _fail(where, f"'friction.values.{k}' must be >= 0, got {v:g}")
    if fr["model"] == "stribeck":
        vs = fr.get("vs")
        if isinstance(vs, bool) or not isinstance(vs, (int, float)) or not vs > 0:
            _fail(where, f"'friction.vs' must be a number > 0 for Stribeck friction, got {json.dumps(vs)}")
    rng = fr.get("qd_range")
    if rng is not None:
        if not isinstance(rng, list) or len(rng) != n:
            _fail(where, f"'friction.qd_range' must be one [low, high] per axis ({n})")
        for i, r in enumerate(rng):
            _numbers(where, f"friction.qd_range[{i}]", r, 2)
            if not r[0] <= 0 <= r[1]:
                _fail(where, f"'friction.qd_range[{i}]' must be [low, high] with low <= 0 <= high, got {r}")
    st = _object(where, "settings", d["settings"])
    for key in ("v_smooth", "deadband"):
        vsm = st.get(key)
        if isinstance(vsm, list):  # one per joint
            if len(vsm) != n or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                                    or v < 0 for v in vsm):
                _fail(where, f"'settings.{key}' must be a number >= 0 or one per axis ({n}), got {json.dumps(vsm)[:60]}")
    for key, lo in (("cutoff", 0.0), ("vs", 0.0), ("prior_weight", None), ("reversal_window", None),
                    ("v_smooth", None), ("deadband", None)):
        v = st.get(key)
        if key in ("v_smooth", "deadband") and isinstance(v, list):
            continue
        if v is None and key in ("cutoff", "vs"):
            continue
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                              or (v <= lo if lo is not None else v < 0)):
            _fail(where, f"'settings.{key}' must be a finite number {'>' if lo is not None else '>='} 0, "
                         f"got {json.dumps(v)[:40]}")
    if "order" in st and (isinstance(st["order"], bool) or not isinstance(st["order"], int)
                          or not 1 <= st["order"] <= 8):
        _fail(where, f"'settings.order' must be an integer 1 to 8, got {json.dumps(st['order'])[:40]}")
    for key in ("offset", "consistent", "rotor", "spring"):
        if key in st and not isinstance(st[key], bool):
            _fail(where, f"'settings.{key}' must be true or false")
    drive = d.get("drive")
    if drive is None and (st.get("rotor") or d.get("torque_side", "joint") == "motor"):
        _fail(where, "'drive' must be an object {ratio, coupling}: the file's rotor inertias or motor-side torques "
                     "go through it")
    if drive is not None:
        _object(where, "drive", drive)
        _numbers(where, "drive.ratio", drive.get("ratio"), n)
        if not isinstance(drive.get("coupling"), list) or len(drive["coupling"]) != n:
            _fail(where, f"'drive.coupling' must be an {n}x{n} matrix")
        for i, row in enumerate(drive["coupling"]):
            _numbers(where, f"drive.coupling[{i}]", row, n)
        if any(r == 0 for r in drive["ratio"]):
            _fail(where, "'drive.ratio' must not contain 0")
    for sec in ("metrics", "provenance"):
        if sec in d and d[sec] is not None:
            _object(where, sec, d[sec])
    if d.get("effects") is not None:
        _effects(where, d["effects"], n)
    return d


#: an effect's settings that are words, and the words allowed (every other setting is a number)
_EFFECT_WORDS = {"load": ("gravity", "rigid"), "form": ("coulomb", "friction", "coulomb_viscous")}


def _effects(where: str, effects: Any, n: int) -> None:
    from kukaid.models.robot_effects import KINDS, n_coefficients, parse

    for name, e in _object(where, "effects", effects).items():
        try:
            kind, j = parse(name)
        except ValueError as x:
            _fail(where, f"'effects': {x}")
        if j is not None and j >= n:
            _fail(where, f"'effects.{name}': the robot has {n} axes")
        e = _object(where, f"effects.{name}", e)
        keys = KINDS[kind][0]
        for k in keys + tuple(k for k in ("kappa",) if k in e):
            if k not in e:
                _fail(where, f"missing field 'effects.{name}.{k}'")
            words = _EFFECT_WORDS.get(k)
            if words and e[k] not in words:
                _fail(where, f"'effects.{name}.{k}' must be one of {', '.join(words)}, got {json.dumps(e[k])[:40]}")
            if not words:
                _numbers(where, f"effects.{name}.{k}", [e[k]])
        _numbers(where, f"effects.{name}.coefficients", e.get("coefficients"), n_coefficients(kind, e))


def is_robot_params(d: Any) -> bool:
    return isinstance(d, dict) and d.get("schema") == SCHEMA


def load_robot_params(path: str | Path) -> dict:
    """Read and validate a robot parameter file."""
    return validate_robot_params(read_json(path, ParamFileError), str(path))


def check_fitted_urdf(d: dict, sha256: str, path: Any) -> None:
    """Refuse a URDF (at ``path``, its ``sha256``) other than the one the robot parameter file ``d`` was
    fitted with (its ``robot.sha256``; a file without one is taken as it is): edited since the fit, it
    describes another robot than the parameters do."""
    sha = d["robot"].get("sha256")
    if sha and sha != sha256:
        raise ParamFileError(f"{path}: this URDF is not the one the parameters were fitted with "
                             f"(sha256 {sha256[:12]}... against {sha[:12]}...)")


def find_urdf(d: dict, path: str | Path, urdf: str | Path | None = None, required: bool = True) -> dict:
    """``d``, a robot parameter file read from ``path``, with ``robot.urdf`` a URDF that is there:
    ``urdf`` when given (``--urdf``); else the stored one (a bundled robot, or a path that exists);
    else, the project having moved, ``robot.urdf_relative`` or a file of the stored one's name taken
    from the parameter file's folder, if it is the same URDF (its sha256 the stored one).

    Raises
    ------
    ParamFileError : none is there (naming the URDF and ``--urdf``; not ``required``: ``d`` as it
        is), or ``urdf`` is another URDF than the one the parameters were fitted with.
    """
    from kukaid.models.urdf import BUNDLED, urdf_sha256

    rob = d["robot"]
    stored, sha = rob["urdf"], rob.get("sha256")
    if urdf is None and (stored in BUNDLED or Path(stored).is_file()):
        return d
    here = Path(path).resolve().parent
    if urdf is not None:
        found = Path(urdf)
        if not found.is_file():
            raise ParamFileError(f"--urdf {urdf}: no such file")
        if sha and urdf_sha256(found) != sha:
            raise ParamFileError(f"--urdf {urdf}: not the URDF {path} was fitted with (its robot.sha256 is "
                                 f"{sha[:12]}..., this file's {urdf_sha256(found)[:12]}...)")
    else:
        near = [here / rob["urdf_relative"]] if rob.get("urdf_relative") else []
        near.append(here / Path(stored).name)
        found = next((c for c in near if c.is_file() and (not sha or urdf_sha256(c) == sha)), None)
        if found is None and not required:
            return d
        if found is None:
            raise ParamFileError(f"{path}: its URDF {stored} (robot.urdf) is not there, nor the same file beside the "
                                 "parameter file; give its new place with --urdf PATH")
    return {**d, "robot": {**rob, "urdf": str(found.resolve())}}


def save_robot_params(path: str | Path, d: dict) -> None:
    """Validate and write a robot parameter file atomically (with ``robot.urdf_relative``, the URDF
    from the file's folder, beside an absolute ``robot.urdf``)."""
    import os

    d = jsonable({"schema": SCHEMA, **{k: v for k, v in d.items() if k != "schema"}})
    rob = d.get("robot")
    if isinstance(rob, dict) and isinstance(rob.get("urdf"), str) and Path(rob["urdf"]).is_absolute():
        try:
            d["robot"] = {**rob, "urdf_relative": os.path.relpath(rob["urdf"], Path(path).resolve().parent)}
        except ValueError:  # another drive (Windows): no relative path
            pass
    validate_robot_params(d, str(path))
    write_text_atomic(path, json.dumps(d, indent=1) + "\n")
