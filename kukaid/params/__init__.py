"""The parameter file: the identified model serialised as JSON, validated on read and write
(:mod:`.axis`: one axis, schema ``kukaid.params/1``; :mod:`.robot`: a whole robot from its URDF,
schema ``kukaid.robot_params/1``)."""
from kukaid.params.axis import (SCHEMA, check_axis, check_model_of, load_params, model_from_params, model_sections, model_to_params, save_params,
                                validate_params)
from kukaid.params.robot import SCHEMA as ROBOT_SCHEMA
from kukaid.params.robot import find_urdf, is_robot_params, load_robot_params, save_robot_params, validate_robot_params



def load_any_params(path, urdf=None, need_urdf: bool = True) -> dict:
    """Read and validate a parameter file of either kind (one axis or a robot), by its schema; a
    robot file's URDF found (:func:`kukaid.params.robot.find_urdf`; ``urdf``: ``--urdf``, refused
    for a one-axis file; ``need_urdf`` False: a robot file whose URDF is not found is read as it is)."""
    from kukaid.errors import OptionError, ParamFileError
    from kukaid.jsonfile import read_json

    d = read_json(path, ParamFileError)
    if not isinstance(d, dict):
        raise ParamFileError(f"{path}: top level must be a JSON object (a kukaid parameter file)")
    if is_robot_params(d):
        return find_urdf(validate_robot_params(d, str(path)), path, urdf, need_urdf)
    if urdf is not None:
        raise OptionError(f"--urdf is for a robot parameter file (fit --robot); {path} is of one axis")
    if d.get("schema") != SCHEMA:
        raise ParamFileError(f"{path}: not a kukaid parameter file (schema {str(d.get('schema'))[:40]!r}; expected "
                             f"{SCHEMA!r} or {ROBOT_SCHEMA!r})")
    validate_params(d, str(path))
    return d


__all__ = ["SCHEMA", "ROBOT_SCHEMA", "check_axis", "check_model_of", "find_urdf", "is_robot_params", "load_any_params", "load_params", "load_robot_params", "model_from_params",
           "model_sections", "model_to_params", "save_params", "save_robot_params", "validate_params", "validate_robot_params"]
