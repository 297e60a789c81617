"""The parameter file: the identified model serialised as JSON, validated on read and write
(:mod:`.axis`: one axis, schema ``kukaid.params/1``)."""
from kukaid.params.axis import SCHEMA, load_params, model_from_params, save_params, validate_params

__all__ = ["SCHEMA", "load_params", "model_from_params", "save_params", "validate_params"]
