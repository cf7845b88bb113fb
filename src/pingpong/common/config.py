"""Config validation against config/schema.yaml, with defaults filled from the schema.

Errors name the key (as a dotted path) and what was expected, before any job runs.
"""

import copy

import jsonschema
import yaml


class ConfigError(ValueError):
    pass


def _with_defaults(validator_class):
    """A validator that also fills `default` values into the instance (jsonschema's documented recipe)."""
    validate_props = validator_class.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if isinstance(instance, dict):
            for key, sub in properties.items():
                if "default" in sub:
                    instance.setdefault(key, copy.deepcopy(sub["default"]))
        yield from validate_props(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_class, {"properties": set_defaults})


def _describe(err: jsonschema.ValidationError) -> str:
    key = ".".join(str(p) for p in err.absolute_path) or "<top level>"
    if err.validator == "additionalProperties":
        allowed = sorted(err.schema.get("properties", {}))
        extra = sorted(set(err.instance) - set(allowed))
        return f"config key '{key}': unknown key(s) {extra}; allowed here: {allowed}"
    if err.validator == "type":
        return (f"config key '{key}': expected {err.validator_value}, "
                f"got {type(err.instance).__name__} {err.instance!r}")
    return f"config key '{key}': {err.message}"


def validate_config(config: dict, schema_path) -> dict:
    """Validate `config` in place (filling defaults); raise ConfigError listing every problem."""
    with open(schema_path) as f:
        schema = yaml.safe_load(f)
    validator = _with_defaults(jsonschema.Draft202012Validator)(schema)
    errors = sorted(validator.iter_errors(config), key=lambda e: list(e.absolute_path))
    if errors:
        raise ConfigError("invalid config:\n  " + "\n  ".join(_describe(e) for e in errors))
    return config
