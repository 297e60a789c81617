"""The parameter file: the identified model serialised as JSON, validated on read and write
(:mod:`.axis`: one axis, schema ``kukaid.params/1``; :mod:`.robot`: a whole robot from its URDF,
schema ``kukaid.robot_params/1``)."""
from kukaid.params.axis import (SCHEMA, check_model_of, load_params, model_from_params, model_sections, model_to_params, save_params,
                                validate_params)
from kukaid.params.robot import SCHEMA as ROBOT_SCHEMA
from kukaid.params.robot import is_robot_params, load_robot_params, save_robot_params, validate_robot_params

__all__ = ["SCHEMA", "ROBOT_SCHEMA", "check_model_of", "is_robot_params", "load_params", "load_robot_params", "model_from_params",
           "model_sections", "model_to_params", "save_params", "save_robot_params", "validate_params", "validate_robot_params"]
