"""Config validation against config/schema.yaml, with defaults filled from the schema.

Errors name the key (as a dotted path) and what was expected, before any job runs.
"""

import copy
from dataclasses import fields

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


def _with_enums(schema: dict, enums: dict) -> dict:
    """The schema with `enum` set at each dotted key of `enums` (names that live in a registry)."""
    for dotted, values in enums.items():
        node = schema
        for key in dotted.split("."):
            node = node["properties"][key]
        node["enum"] = list(values)
    return schema


def validate_config(config: dict, schema_path, enums: dict | None = None) -> dict:
    """Validate `config` in place (filling defaults); raise ConfigError listing every problem.

    enums: dotted key -> allowed values, for keys whose values are registered names (e.g. the
    uncertainty estimators), so that the schema never keeps a second list of them."""
    with open(schema_path) as f:
        schema = _with_enums(yaml.safe_load(f), enums or {})
    validator = _with_defaults(jsonschema.Draft202012Validator)(schema)
    errors = sorted(validator.iter_errors(config), key=lambda e: list(e.absolute_path))
    if errors:
        raise ConfigError("invalid config:\n  " + "\n  ".join(_describe(e) for e in errors))
    return config


class Settings:
    """Base of the typed settings: a frozen dataclass of one validated config section, with no defaults of
    its own (config/schema.yaml holds them, the one source)."""

    @classmethod
    def from_config(cls, section: dict):
        names = {f.name for f in fields(cls)}
        missing, unknown = sorted(names - set(section)), sorted(set(section) - names)
        if missing or unknown:
            raise ConfigError(f"{cls.__name__}: settings missing {missing}, unknown {unknown}; build them "
                              "from a validated config section")
        return cls(**section)


def schema_defaults(schema_path) -> dict:
    """The config that an empty config file gives: every default of the schema (for tests and tools)."""
    return validate_config({}, schema_path)
