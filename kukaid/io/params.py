"""The parameter file (JSON, schema ``kukaid.params/1``): what ``fit`` writes and the rest reads.

Validation is driven by a small table of (field, range) so every error names the field and the
allowed range.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from kukaid.errors import ParamFileError
from kukaid.io.atomic import write_text_atomic
from kukaid.io.jsonfile import read_json
from kukaid.models.friction import MaxwellSlip, friction_from_dict
from kukaid.models.joint import AxisModel, RigidBody

SCHEMA = "kukaid.params/1"
INF = math.inf

# (section, field) -> (low, high, required)
_FIELDS: dict[tuple[str, str], tuple[float, float, bool]] = {
    ("friction", "Fc"): (0.0, INF, True),
    ("friction", "Fv"): (0.0, INF, True),
    ("friction", "Fs"): (0.0, INF, False),
    ("friction", "vs"): (1e-9, INF, False),
    ("friction", "delta"): (0.05, 10.0, False),
    ("inertial", "Izz"): (1e-12, INF, True),
    ("inertial", "Mx"): (-INF, INF, False),
    ("inertial", "My"): (-INF, INF, False),
    ("mode_switch", "qd_thr"): (0.0, INF, False),
}


def _number(where: str, v: Any, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ParamFileError(f"{where} must be a number, got {json.dumps(v)}")
    if not math.isfinite(v) or not lo <= v <= hi:
        raise ParamFileError(f"{where} = {v} is outside the allowed range [{lo}, {hi}]")
    return float(v)


def validate_params(d: Any, where: str = "parameter file") -> dict:
    """Check a parameter dictionary against the schema; return it unchanged or raise ParamFileError."""
    if not isinstance(d, dict):
        raise ParamFileError(f"{where}: top level must be a JSON object")
    if d.get("schema") != SCHEMA:
        raise ParamFileError(f"{where}: 'schema' must be \"{SCHEMA}\", got {json.dumps(d.get('schema'))}")
    for sec in ("friction", "inertial"):
        if not isinstance(d.get(sec), dict):
            raise ParamFileError(f"{where}: missing section '{sec}'")
    model = d["friction"].get("model", "stribeck")
    if model not in ("stribeck", "coulomb-viscous"):
        raise ParamFileError(f"{where}: friction.model must be 'stribeck' or 'coulomb-viscous', got {json.dumps(model)}")
    for (sec, name), (lo, hi, required) in _FIELDS.items():
        s = d.get(sec) or {}
        need = required or (sec == "friction" and model == "stribeck" and name in ("Fs", "vs", "delta"))
        if name not in s:
            if need:
                raise ParamFileError(f"{where}: missing field {sec}.{name}")
            continue
        _number(f"{where}: {sec}.{name}", s[name], lo, hi)
    if "offset" in d:
        _number(f"{where}: offset", d["offset"], -INF, INF)
    ms = d.get("maxwell_slip")
    if ms is not None:
        if not isinstance(ms, dict) or not all(isinstance(ms.get(x), list) for x in ("k", "W")):
            raise ParamFileError(f"{where}: maxwell_slip must have lists 'k' and 'W'")
        n = len(ms["k"])
        if n == 0 or len(ms["W"]) != n or len(ms.get("zeta0", [0.0] * n)) != n:
            raise ParamFileError(f"{where}: maxwell_slip.k, .W and .zeta0 must be non-empty lists of one length")
        for i in range(n):
            _number(f"{where}: maxwell_slip.k[{i}]", ms["k"][i], 1e-12, INF)
            _number(f"{where}: maxwell_slip.W[{i}]", ms["W"][i], 0.0, INF)
    ax = d.get("axis")
    if ax is not None and (isinstance(ax, bool) or not isinstance(ax, int) or not 1 <= ax <= 12):
        raise ParamFileError(f"{where}: axis must be an integer 1 to 12, got {json.dumps(ax)}")
    if "effects" in d and not isinstance(d["effects"], dict):
        raise ParamFileError(f"{where}: effects must be an object {{name: parameters}}")
    return d


def load_params(path: str | Path) -> dict:
    """Read and validate a parameter file."""
    return validate_params(read_json(path, ParamFileError), str(path))


def save_params(path: str | Path, d: dict) -> None:
    """Validate and write a parameter file atomically."""
    d = {"schema": SCHEMA, **{k: v for k, v in d.items() if k != "schema"}}
    validate_params(d, str(path))
    write_text_atomic(path, json.dumps(d, indent=2, sort_keys=False) + "\n")


def model_from_params(d: dict) -> AxisModel:
    """Build the :class:`AxisModel` a (validated) parameter dictionary describes."""
    inert = d["inertial"]
    rigid = RigidBody(Izz=float(inert["Izz"]), Mx=float(inert.get("Mx", 0.0)), My=float(inert.get("My", 0.0)),
                      offset=float(d.get("offset", 0.0)))
    ms = d.get("maxwell_slip")
    return AxisModel(
        rigid=rigid,
        friction=friction_from_dict(d["friction"]),
        maxwell_slip=MaxwellSlip(ms["k"], ms["W"]) if ms else None,
        qd_thr=float((d.get("mode_switch") or {}).get("qd_thr", 0.0017)),
        effects=dict(d.get("effects") or {}),
    )
