"""A robot from its URDF: the bundled robots and one Pinocchio model built from a file.

Pinocchio (PyPI ``pin``) holds the kinematic tree and the inertials; algorithms (ABA, RNEA, the
joint-torque regressor) run on a model built once and a data object per computation.
"""
from __future__ import annotations

import os
import re
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from kukaid.errors import ParamFileError

#: robot names bundled with kukaid -> URDF file in kukaid/robots
BUNDLED = {"kr6-r700-sixx": "kr6_r700_sixx.urdf"}


def robot_urdf(robot: str | Path) -> Path:
    """The URDF of ``robot``: a bundled name (``kr6-r700-sixx``) or a path to a URDF file."""
    name = str(robot)
    if name in BUNDLED:
        p = Path(__file__).resolve().parent.parent / "robots" / BUNDLED[name]
        if not p.is_file():
            raise ParamFileError(f"robot '{name}': the bundled URDF {p} is missing from this installation")
        return p
    p = Path(name)
    if not p.is_file():
        known = ", ".join(BUNDLED)
        raise ParamFileError(f"robot '{name}': no such robot (a .urdf file or one of: {known})")
    return p


def urdf_sha256(path: str | Path) -> str:
    """The SHA-256 of a URDF file's bytes (a robot parameter file's ``robot.sha256``)."""
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def load_model(robot: str | Path):
    """A Pinocchio model (fixed base, one coordinate per joint) built once from the robot's URDF.

    The URDF parser's own complaints (printed by C++ on the process's stderr) are caught and
    reported in the one-line :class:`KukaidError` instead."""
    import pinocchio as pin

    path = robot_urdf(robot)
    try:
        with _captured_stderr() as said:
            model = pin.buildModelFromUrdf(str(path))
    except Exception as e:  # Pinocchio raises RuntimeError/ValueError with multi-line text
        from kukaid.jsonfile import file_kind

        kind = file_kind(path)  # a parameter file or a log given as --robot: said what it is
        if kind is not None and not kind.startswith("a URDF"):
            raise ParamFileError(f"{path}: is {kind}, not a URDF (the robot's description, XML)") from None
        first = (str(e).strip() or said() or type(e).__name__).splitlines()[0]
        raise ParamFileError(f"{path}: not a URDF Pinocchio can read ({first})") from None
    if model.nq != model.nv or model.nv == 0:
        raise ParamFileError(f"{path}: the robot must have 1 to 12 revolute/prismatic joints with one coordinate each "
                          f"(nq = {model.nq}, nv = {model.nv})")
    if model.nv > 12:
        raise ParamFileError(f"{path}: {model.nv} joints; kukaid handles at most 12 axes")
    return model


@contextmanager
def _captured_stderr():
    """Redirect the process's file descriptor 2 (C++ output too) into a temporary file; yields a
    function returning what was written."""
    import tempfile

    text = ""
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # no real stderr (e.g. captured by a test runner)
        yield lambda: text
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), fd)
        try:
            yield lambda: text
        finally:
            os.dup2(saved, fd)
            os.close(saved)
            tmp.seek(0)
            text = tmp.read().decode("utf-8", "replace").strip()


def gear_ratios(robot: str | Path, joint_names: tuple[str, ...]) -> np.ndarray:
    """Gear ratios (motor turns per joint turn) of the joints ``joint_names`` from the URDF's
    ``<transmission>`` elements (``mechanicalReduction``); 1 where the URDF gives none."""
    import xml.etree.ElementTree as ET

    path = robot_urdf(robot)
    ratio = np.ones(len(joint_names))
    try:
        # comments dropped first: URDF parsers accept "--" inside a comment, XML (and ElementTree) does not
        root = ET.fromstring(re.sub(r"<!--.*?-->", "", path.read_text(), flags=re.S))
    except (ET.ParseError, OSError, UnicodeDecodeError):
        return ratio
    for tr in root.iter("transmission"):
        joint, red = tr.find("joint"), tr.find(".//mechanicalReduction")
        if joint is not None and red is not None and joint.get("name") in joint_names:
            try:
                ratio[joint_names.index(joint.get("name"))] = float(red.text)
            except (TypeError, ValueError):
                raise ParamFileError(f"{path}: transmission {tr.get('name')}: mechanicalReduction must be a number, "
                                  f"got {red.text!r}") from None
    return ratio
