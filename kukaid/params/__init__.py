"""The parameter file: the identified model serialised as JSON, validated on read and write
(:mod:`.axis`: one axis, schema ``kukaid.params/1``; :mod:`.robot`: a whole robot from its URDF,
schema ``kukaid.robot_params/1``)."""
from kukaid.params.axis import (SCHEMA, check_axis, check_model_of, load_params, model_from_params, model_sections, model_to_params, save_params,
                                validate_params)
from kukaid.params.robot import SCHEMA as ROBOT_SCHEMA
from kukaid.params.robot import is_robot_params, load_robot_params, save_robot_params, validate_robot_params



def load_any_params(path) -> dict:
    """Read and validate a parameter file of either kind (one axis or a robot), by its schema."""
    from kukaid.errors import ParamFileError
    from kukaid.jsonfile import read_json

    d = read_json(path, ParamFileError)
    if not isinstance(d, dict):
        raise ParamFileError(f"{path}: top level must be a JSON object (a kukaid parameter file)")
    if is_robot_params(d):
        return validate_robot_params(d, str(path))
    if d.get("schema") != SCHEMA:
        raise ParamFileError(f"{path}: not a kukaid parameter file (schema {str(d.get('schema'))[:40]!r}; expected "
                             f"{SCHEMA!r} or {ROBOT_SCHEMA!r})")
    validate_params(d, str(path))
    return d


__all__ = ["SCHEMA", "ROBOT_SCHEMA", "check_axis", "check_model_of", "is_robot_params", "load_any_params", "load_params", "load_robot_params", "model_from_params",
           "model_sections", "model_to_params", "save_params", "save_robot_params", "validate_params", "validate_robot_params"]
