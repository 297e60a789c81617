"""A robot from its URDF: the bundled robots and one Pinocchio model built from a file.

Pinocchio (PyPI ``pin``) holds the kinematic tree and the inertials; algorithms (ABA, RNEA, the
joint-torque regressor) run on a model built once and a data object per computation.
"""
from __future__ import annotations

from pathlib import Path

from kukaid.errors import KukaidError

#: robot names bundled with kukaid -> URDF file in kukaid/robots
BUNDLED = {"kr6-r700-sixx": "kr6_r700_sixx.urdf"}


def robot_urdf(robot: str | Path) -> Path:
    """The URDF of ``robot``: a bundled name (``kr6-r700-sixx``) or a path to a URDF file."""
    name = str(robot)
    if name in BUNDLED:
        p = Path(__file__).resolve().parent.parent / "robots" / BUNDLED[name]
        if not p.is_file():
            raise KukaidError(f"robot '{name}': the bundled URDF {p} is missing from this installation")
        return p
    p = Path(name)
    if not p.is_file():
        known = ", ".join(BUNDLED)
        raise KukaidError(f"robot '{name}': no such URDF file and not a bundled robot (known: {known})")
    return p


def load_model(robot: str | Path):
    """A Pinocchio model (fixed base, revolute joints) built once from the robot's URDF."""
    import pinocchio as pin

    path = robot_urdf(robot)
    try:
        model = pin.buildModelFromUrdf(str(path))
    except Exception as e:  # Pinocchio raises RuntimeError/ValueError with multi-line text
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise KukaidError(f"{path}: not a URDF Pinocchio can read ({first})") from None
    if model.nq != model.nv or model.nv == 0:
        raise KukaidError(f"{path}: the robot must have 1 to 12 revolute/prismatic joints with one coordinate each "
                          f"(nq = {model.nq}, nv = {model.nv})")
    if model.nv > 12:
        raise KukaidError(f"{path}: {model.nv} joints; kukaid handles at most 12 axes")
    return model
