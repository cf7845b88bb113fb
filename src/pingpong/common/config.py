"""Config validation against config/schema.yaml, with defaults filled from the schema.

Errors name the key (as a dotted path) and what was expected, before any job runs.

Snakemake reads config files with a lenient YAML loader: a repeated key keeps its last value, aliases
expand without bound, and an unknown tag is reported as mixed tab indentation. So the Snakefile reads
every config file again with `load_config_file`, which refuses those naming the file, line and key or tag.
"""

import copy
import json
import math
import warnings
from dataclasses import fields
from pathlib import Path

import jsonschema
import yaml


class ConfigError(ValueError):
    pass


# The most values a config file may expand to through YAML aliases: the largest config (config/paper.yaml
# with the defaults) holds a few hundred; an alias bomb billions.
MAX_CONFIG_VALUES = 100_000


class _StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing repeated keys (YAML forbids them; PyYAML keeps the last)."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            line = key_node.start_mark.line + 1
            if isinstance(key, list | dict):  # unhashable: yaml's own error would name no key
                raise yaml.constructor.ConstructorError(None, None, "a mapping key must be a scalar",
                                                        key_node.start_mark)
            if key in seen:
                raise ConfigError(f"line {line}: key '{key}' repeated (first on line {seen[key]}); "
                                  "a YAML mapping holds each key once")
            seen[key] = line
        return super().construct_mapping(node, deep=deep)


def _json_pairs(pairs):
    keys = [k for k, _ in pairs]
    repeated = sorted({k for k in keys if keys.count(k) > 1})
    if repeated:
        raise ConfigError(f"key(s) {repeated} repeated in one JSON object")
    return dict(pairs)


def _json_constant(name):
    raise ConfigError(f"{name} is not a number a config may hold")


def _load_yaml(text: str, name: str):
    loader = _StrictLoader(text)
    loader.name = name  # the file in the marks of yaml's messages
    try:
        node = loader.get_single_node()
        return None if node is None else loader.construct_document(node)  # aliases stay shared: cheap
    finally:
        loader.dispose()


def load_config_file(path) -> dict:
    """A config file (JSON, else YAML, as Snakemake tries them) read strictly: a repeated key, an unknown
    or unsafe tag, aliases that expand past MAX_CONFIG_VALUES, NaN or infinity, or a top level that is not
    a mapping raise ConfigError naming the file (and the line, key or tag). A YAML file whose last line
    has no newline warns: cut short, it would read as a valid shorter config."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"config file {path}: cannot read it as UTF-8 text: {err}") from err
    try:
        try:
            data = json.loads(text, object_pairs_hook=_json_pairs, parse_constant=_json_constant)
            is_yaml = False
        except json.JSONDecodeError:
            data, is_yaml = _load_yaml(text, str(path)), True
        _check_size(data)
    except ConfigError as err:
        raise ConfigError(f"config file {path}: {err}") from None
    except yaml.constructor.ConstructorError as err:  # an unsafe or unknown tag (Snakemake blames tabs)
        where = f", line {err.problem_mark.line + 1}" if err.problem_mark else ""
        raise ConfigError(f"config file {path}{where}: {err.problem}; a config holds plain YAML values only "
                          "(mappings, lists, strings, numbers, booleans, null)") from None
    except yaml.YAMLError as err:
        raise ConfigError(f"config file {path}: not valid YAML: {_short(str(err), 600)}") from None
    except RecursionError:
        raise ConfigError(f"config file {path}: nested too deeply to be a config") from None
    if data is None:  # Snakemake refuses it too; all defaults would be a plausible wrong config
        raise ConfigError(f"config file {path}: holds no keys (empty, or comments only); expected a mapping")
    if not isinstance(data, dict):
        raise ConfigError(f"config file {path}: expected a mapping of keys at the top level, "
                          f"got {type(data).__name__}")
    bad = non_finite_keys(data)
    if bad:
        raise ConfigError(f"config file {path}: NaN or infinity at {bad}; config values must be finite")
    if is_yaml and not text.endswith("\n"):  # YAML cut short reads as a valid shorter file; editors end lines
        warnings.warn(f"config file {path}: its last line has no newline: was the file cut short? Its last "
                      "keys may be missing (their defaults then apply)", stacklevel=2)
    return data


def check_config_files(paths) -> list[tuple[str, dict]]:
    """Each config file read strictly (`load_config_file`) for its errors (Snakemake has read them already);
    returns (path, data) in the order given, the `sources` that validate_config names in its errors."""
    return [(str(path), load_config_file(path)) for path in paths]


def _source_of(keys: list, sources) -> str:
    """' (in FILE, line N)': the last of `sources` (later files win) that sets the deepest prefix of `keys`,
    and the line where it does."""
    best, depth = "", 0
    for path, data in sources:
        node, d = data, 0
        for key in keys:
            if not isinstance(node, dict | list) or (isinstance(node, dict) and key not in node) or \
                    (isinstance(node, list) and not (isinstance(key, int) and key < len(node))):
                break
            node, d = node[key], d + 1
        if d and d >= depth:
            best, depth = path, d
    if not best:
        return ""
    line = _line_of(best, keys[:depth])
    return f" (in {best}, line {line})" if line else f" (in {best})"


def _line_of(path: str, keys: list) -> int | None:
    """The line (from 1) of config file `path` that sets the value at `keys` (a key's line, or a list item's);
    read again only for an error's message, so a file that no longer composes gives None."""
    try:
        node = yaml.compose(Path(path).read_text(encoding="utf-8"), Loader=yaml.SafeLoader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    line = None
    for key in keys:
        if isinstance(node, yaml.MappingNode):
            found = [(k, v) for k, v in node.value if k.value == str(key)]
            if not found:
                break
            line, node = found[0][0].start_mark.line + 1, found[0][1]
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
            line = node.start_mark.line + 1
        else:
            break
    return line


def _value_count(value, counts: dict) -> int:
    """The number of values `value` holds, shared lists and mappings counted each time they appear (as a
    YAML alias expands); a container that holds itself raises ConfigError."""
    if not isinstance(value, dict | list):
        return 1
    if id(value) in counts:
        if counts[id(value)] is None:
            raise ConfigError("a value holds itself (a recursive YAML alias)")
        return counts[id(value)]
    counts[id(value)] = None
    children = value.values() if isinstance(value, dict) else value
    counts[id(value)] = 1 + sum(_value_count(child, counts) for child in children)
    return counts[id(value)]


def _check_size(config) -> None:
    """Refuse a config that holds itself or expands (through YAML aliases) past MAX_CONFIG_VALUES:
    jsonschema would walk every value and quote them all in its messages (312 MB for an alias bomb)."""
    size = _value_count(config, {})
    if size > MAX_CONFIG_VALUES:
        raise ConfigError(f"its values expand to {size:,}, more than the {MAX_CONFIG_VALUES:,} a config may "
                          "hold (an alias bomb?)")


def non_finite_keys(value, key: str = "") -> list[str]:
    """The dotted keys (list items as [i]) whose values are NaN or infinite numbers."""
    if isinstance(value, float):
        return [] if math.isfinite(value) else [key or "<top level>"]
    if isinstance(value, dict):
        return [k for name, v in value.items()
                for k in non_finite_keys(v, f"{key}.{name}" if key else str(name))]
    if isinstance(value, list | tuple):
        return [k for i, v in enumerate(value) for k in non_finite_keys(v, f"{key}[{i}]")]
    return []


def _short(text: str, limit: int = 300) -> str:
    """`text` cut to `limit` characters: a message quotes the value, which may be huge."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text):,} characters)"


def _with_defaults(validator_class):
    """A validator that also fills `default` values into the instance (jsonschema's documented recipe)."""
    validate_props = validator_class.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if isinstance(instance, dict):
            for key, sub in properties.items():
                if "default" in sub:
                    instance.setdefault(key, copy.deepcopy(sub["default"]))
        yield from validate_props(validator, properties, instance, schema)

    # an integer is an int: jsonschema's default also takes 1.0, which range() and array shapes refuse
    checker = validator_class.TYPE_CHECKER.redefine(
        "integer", lambda _, value: isinstance(value, int) and not isinstance(value, bool))
    return jsonschema.validators.extend(validator_class, {"properties": set_defaults}, type_checker=checker)


def _describe(err: jsonschema.ValidationError) -> str:
    key = ".".join(str(p) for p in err.absolute_path) or "<top level>"
    if err.validator == "additionalProperties":
        allowed = sorted(err.schema.get("properties", {}))
        extra = sorted(set(err.instance) - set(allowed))
        return f"config key '{key}': unknown key(s) {extra}; allowed here: {allowed}"
    if err.validator == "type":
        return (f"config key '{key}': expected {err.validator_value}, "
                f"got {type(err.instance).__name__} {_short(repr(err.instance), 80)}")
    return f"config key '{key}': {_short(err.message)}"


def _error_keys(err: jsonschema.ValidationError) -> list:
    """The keys down to the value in error (for an unknown key, down to that key)."""
    keys = list(err.absolute_path)
    if err.validator == "additionalProperties" and isinstance(err.instance, dict):
        extra = sorted(set(err.instance) - set(err.schema.get("properties", {})))
        keys += extra[:1]
    return keys


def _with_enums(schema: dict, enums: dict) -> dict:
    """The schema with `enum` set at each dotted key of `enums` (names that live in a registry)."""
    for dotted, values in enums.items():
        node = schema
        for key in dotted.split("."):
            node = node["properties"][key]
        node["enum"] = list(values)
    return schema


def validate_config(config: dict, schema_path, enums: dict | None = None, sources=()) -> dict:
    """Validate `config` in place (filling defaults); raise ConfigError listing every problem.

    enums: dotted key -> allowed values, for keys whose values are registered names (e.g. the
    uncertainty estimators), so that the schema never keeps a second list of them.
    sources: (file, data) of the config files merged into `config`, in order; each problem names the
    file that set the key (values given on the command line have none)."""
    with open(schema_path) as f:
        schema = _with_enums(yaml.safe_load(f), enums or {})
    try:
        _check_size(config)
    except ConfigError as err:
        raise ConfigError(f"invalid config: {err}") from None
    validator = _with_defaults(jsonschema.Draft202012Validator)(schema)
    problems = [f"config key '{k}': NaN or infinity; config values must be finite"
                for k in non_finite_keys(config)]
    errors = sorted(validator.iter_errors(config), key=lambda e: list(e.absolute_path))
    problems += [_describe(e) + _source_of(_error_keys(e), sources) for e in errors]
    if problems:
        raise ConfigError("invalid config:\n  " + "\n  ".join(problems))
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


def _merged(base: dict, update: dict) -> dict:
    """`update` over `base`, mappings merged key by key (as Snakemake merges config files)."""
    out = dict(base)
    for key, value in update.items():
        both = isinstance(value, dict) and isinstance(out.get(key), dict)
        out[key] = _merged(out[key], value) if both else value
    return out


def check_main(argv=None) -> int:
    """`python -m pingpong.common.config FILE...`: each config file read strictly and validated over
    config/config.yaml, as the workflow would, each problem naming its file and line; under source: lab,
    the lab's recordings under raw/ checked against it as the workflow does at each start (headers and a
    sample: pingpong.io.lab_preflight). Snakemake itself refuses a --configfile with an unsafe or unknown
    tag before the workflow's code runs, blaming tab indentation: this names the tag and line.
    (Registered names, e.g. robot.estimator, are checked by the workflow: their enums live in registries.)"""
    import argparse

    ap = argparse.ArgumentParser(description=check_main.__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--root", type=Path, default=Path("."), help="the checkout (holds config/)")
    args = ap.parse_args(argv)
    try:
        sources = check_config_files([args.root / "config/config.yaml", *args.files])
        config = {}
        for _, data in sources:
            config = _merged(config, data)
        validate_config(config, args.root / "config/schema.yaml", sources=sources)
    except ConfigError as err:
        print(err)
        return 1
    if config["source"] == "lab":
        from pingpong.io.lab_preflight import lab_preflight  # reads videos: only a lab's check needs it

        problems = lab_preflight(args.root, config["lab"], config["perception"])
        if problems:
            print("the lab's recordings under raw/ do not match the config:\n  - " + "\n  - ".join(problems))
            return 1
    print(f"config ok: {', '.join(map(str, args.files))}"
          + (" (and the lab's recordings' headers under raw/)" if config["source"] == "lab" else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(check_main())
