"""The config reader fuzzed (tests/fuzz_util.py), and a regression test for each finding of issue 37:
a repeated key kept its last value, NaN and infinity passed, `n_sessions: 1.0` ended in a TypeError,
a YAML alias bomb printed 312 MB of error, unsafe tags were blamed on tab indentation."""

import copy
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from fuzz_util import IsolatedReader, damaged, record
from hypothesis import given, settings
from hypothesis import strategies as st
from workflow_util import ROOT, SNAKEMAKE

from pingpong.common.config import ConfigError, load_config_file, non_finite_keys, validate_config

SCHEMA = ROOT / "config/schema.yaml"
# 9 ** 8 values from 8 lines: each list holds the one before nine times
BOMB = "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"{k}: &{k} [{', '.join([f'*{p}'] * 9)}]\n" for p, k in zip("abcdefg", "bcdefgh", strict=True))


def read_config(path) -> dict:
    """What the workflow makes of a config file: read strictly, then validated with the defaults filled."""
    data = load_config_file(path)
    return validate_config(data, SCHEMA, sources=[(str(path), copy.deepcopy(data))])


def _plainly_read(data: bytes):
    """What the file says, read by PyYAML's plain safe loader (None where it says nothing readable)."""
    try:
        return validate_config(yaml.safe_load(data.decode()), SCHEMA)
    except Exception:  # noqa: BLE001 - any failure: the file says nothing a config could hold
        return None


@pytest.mark.parametrize("source", ["config/config.yaml", "config/paper.yaml"])
def test_fuzz_config(tmp_path, source):
    """Damaged config files: each a clear ConfigError naming the file, or read as what it says.

    A file cut short mostly ends in a broken line: read, with a warning naming the file. A damaged file
    that is still a valid config (cut at a line's end, so that the trailing keys take their defaults; a
    list item or a digit dropped) reads as a different config: YAML cannot tell, so those count as
    silent_wrong, and only where PyYAML's plain loader reads the very same config from the file."""
    original = (ROOT / source).read_bytes()
    expected = read_config(ROOT / source)
    rng = np.random.default_rng(37)
    reader, outcomes, says_so = IsolatedReader(timeout_s=10), [], 0
    try:
        for i in range(200):
            _, data = damaged(original, rng)
            path = tmp_path / f"damaged_{i}.yaml"
            path.write_bytes(data)
            result = reader.call("test_fuzz_config:read_config", path)
            outcome = result.outcome(path, expected)
            if outcome == "silent_wrong":
                assert result.value == _plainly_read(data), f"{path}: read otherwise than it says"
                says_so += 1
            outcomes.append(outcome)
    finally:
        reader.close()
    counts = record(f"config ({Path(source).name})", outcomes)
    assert counts["crash"] == counts["hang"] == counts["unclear"] == 0, counts
    assert counts["silent_wrong"] == says_so  # every one a valid config the damaged file states


def test_repeated_key_is_refused_with_file_line_and_key(tmp_path):
    path = tmp_path / "lab.yaml"
    path.write_text("twin:\n  n_sessions: 2\ntraining:\n  n_folds: 3\ntwin:\n  n_cameras: 3\n")
    with pytest.raises(ConfigError, match=r"lab\.yaml: line 5: key 'twin' repeated \(first on line 1\)"):
        load_config_file(path)
    path.write_text("twin: {n_sessions: 2, n_sessions: 3}\n")
    with pytest.raises(ConfigError, match="line 1: key 'n_sessions' repeated"):
        load_config_file(path)
    path.write_text('{"seed": 1, "seed": 2}')  # JSON, which Snakemake tries first
    with pytest.raises(ConfigError, match=r"lab\.yaml: key\(s\) \['seed'\] repeated"):
        load_config_file(path)


def test_a_repeated_key_stops_the_workflow(tmp_path):
    """Snakemake reads --configfile with a loader that keeps the last value: the Snakefile reads it again."""
    path = tmp_path / "dup.yaml"
    path.write_text("training:\n  grid: {lr: [0.01]}\ntraining:\n  n_folds: 3\n")
    cmd = [*SNAKEMAKE, "-n", "--snakefile", str(ROOT / "Snakefile"), "--configfile", str(path)]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode != 0
    assert f"config file {path}: line 3: key 'training' repeated" in proc.stdout + proc.stderr


def test_schema_errors_name_the_file_and_line_that_set_the_key(tmp_path):
    base, lab = tmp_path / "config.yaml", tmp_path / "lab.yaml"
    base.write_text("twin: {n_sessions: 2}\ntraining: {n_folds: 3}\n")
    lab.write_text("# the lab's\ntwin:\n  n_sessions: 1.0\n  widht: 480\n")
    sources = [(str(base), load_config_file(base)), (str(lab), load_config_file(lab))]
    config = {"twin": {"n_sessions": 1.0, "widht": 480}, "training": {"n_folds": 1}}
    with pytest.raises(ConfigError) as err:
        validate_config(config, SCHEMA, sources=sources)
    assert f"'twin.n_sessions': expected integer, got float 1.0 (in {lab}, line 3)" in str(err.value)
    assert "unknown key(s) ['widht']; allowed here: " in str(err.value)
    assert f"] (in {lab}, line 4)" in str(err.value)
    assert f"'training.n_folds': 1 is less than the minimum of 2 (in {base}, line 2)" in str(err.value)


@pytest.mark.parametrize("value", [".nan", ".NaN", ".inf", "-.Inf", "+.inf"])
def test_nan_and_infinity_are_refused_naming_the_key(tmp_path, value):
    path = tmp_path / "c.yaml"
    path.write_text(f"training:\n  grid:\n    lr: [0.001, {value}]\nuncertainty: {{coverage: 0.9}}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: NaN or infinity at \['training\.grid\.lr\[1\]'\]"):
        load_config_file(path)


def test_nan_from_the_command_line_is_refused_naming_the_key():
    """`--config` values do not come through a file: validate_config checks them."""
    config = {"uncertainty": {"coverage": math.nan}, "robot": {"alpha_grid": [0.0, math.inf]}}
    with pytest.raises(ConfigError) as err:
        validate_config(config, SCHEMA)
    assert "'uncertainty.coverage': NaN or infinity" in str(err.value)
    assert "'robot.alpha_grid[1]': NaN or infinity" in str(err.value)


@given(st.floats(allow_nan=True, allow_infinity=True) | st.integers() | st.text(max_size=5))
@settings(max_examples=200, deadline=None)
def test_non_finite_keys_finds_exactly_the_non_finite_numbers(value):
    tree = {"a": {"b": [1, value]}, "c": value}
    bad = isinstance(value, float) and not math.isfinite(value)
    assert non_finite_keys(tree) == (["a.b[1]", "c"] if bad else [])


@pytest.mark.parametrize("value", ["1.0", "2.5", "true", "'4'"])
def test_counts_must_be_integers(tmp_path, value):
    path = tmp_path / "c.yaml"
    path.write_text(f"twin:\n  n_sessions: {value}\n")
    with pytest.raises(ConfigError, match="config key 'twin.n_sessions': expected integer"):
        read_config(path)


@pytest.mark.parametrize(("key", "value"), [("twin.n_sessions", 10**8), ("twin.width", 10**6),
                                            ("training.batch_size", 10**12),
                                            ("training.grid.rnn_hidden", [10**7])])
def test_counts_are_bounded(key, value):
    section, *rest = key.split(".")
    config = {section: value if not rest else {}}
    node = config[section]
    for part in rest[:-1]:
        node = node.setdefault(part, {})
    if rest:
        node[rest[-1]] = value
    with pytest.raises(ConfigError, match="is greater than the maximum"):
        validate_config(config, SCHEMA)


def test_alias_bomb_is_refused_quickly_and_briefly(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(BOMB)
    start = time.perf_counter()
    with pytest.raises(ConfigError, match=r"bomb\.yaml: its values expand to [\d,]+, more than") as err:
        load_config_file(path)
    assert time.perf_counter() - start < 1 and len(str(err.value)) < 300


def test_a_loaded_alias_bomb_gives_a_short_error():
    """A bomb Snakemake has loaded (shared lists, small in memory) must not print its expansion."""
    bomb = yaml.safe_load(BOMB)
    start = time.perf_counter()
    with pytest.raises(ConfigError, match="its values expand to") as err:
        validate_config({"twin": {"n_sessions": bomb["h"]}, "lab": {"cameras": bomb}}, SCHEMA)
    assert time.perf_counter() - start < 1 and len(str(err.value)) < 300


def test_a_recursive_alias_is_refused(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text("lab:\n  cameras: &c [cam0, *c]\n")
    with pytest.raises(ConfigError, match=r"loop\.yaml: a value holds itself \(a recursive YAML alias\)"):
        load_config_file(path)


@pytest.mark.parametrize("tag", ["!!python/object/apply:os.system", "!!python/name:os.system", "!custom"])
def test_unsafe_tags_are_named(tmp_path, tag):
    path = tmp_path / "evil.yaml"
    path.write_text(f"seed: 1\ntwin: {tag} ['echo hi']\n")
    with pytest.raises(ConfigError) as err:
        load_config_file(path)
    message = str(err.value).replace("tag:yaml.org,2002:", "!!")  # PyYAML's long form of !!
    assert f"evil.yaml, line 2: could not determine a constructor for the tag '{tag}" in message
    assert "tab" not in message


def test_snakemake_refuses_an_unsafe_tag_without_running_it(tmp_path):
    """Snakemake parses --configfile before any of the project's code runs and blames tab indentation (its
    own message, upstream): the payload never runs, nothing is written, and the project's check names it."""
    path = tmp_path / "evil.yaml"
    path.write_text(f"seed: 1\ntwin: !!python/object/apply:os.system ['touch {tmp_path}/ran']\n")
    cmd = [*SNAKEMAKE, "-n", "--snakefile", str(ROOT / "Snakefile"), "--configfile", str(path)]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode != 0 and "not valid JSON or YAML" in proc.stdout + proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["evil.yaml"]
    check = subprocess.run([sys.executable, "-m", "pingpong.common.config", str(path), "--root", str(ROOT)],
                           capture_output=True, text=True)
    assert check.returncode == 1 and "evil.yaml, line 2: could not determine a constructor" in check.stdout


def test_unreadable_and_non_mapping_files_are_refused(tmp_path):
    cases = {"binary.yaml": b"\xff\xfe\x00seed: 1", "list.yaml": b"- 1\n- 2\n", "scalar.yaml": b"7\n",
             "deep.yaml": b"[" * 5000 + b"]" * 5000 + b"\n"}
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ConfigError, match=f"config file {tmp_path / name}"):
            load_config_file(tmp_path / name)
    for text in (b"", b"# a comment only\n"):  # not all defaults: a file cut to nothing says nothing
        (tmp_path / "empty.yaml").write_bytes(text)
        with pytest.raises(ConfigError, match="empty.yaml: holds no keys"):
            load_config_file(tmp_path / "empty.yaml")


SHIPPED = sorted(p.name for p in (ROOT / "config").glob("*.yaml") if p.name != "schema.yaml")


@pytest.mark.parametrize("name", SHIPPED)
def test_the_shipped_configs_pass(name):
    """The strict loader and the new maxima take every config the project ships, as Snakemake reads them."""
    path = ROOT / "config" / name
    config = load_config_file(path)
    assert config == yaml.safe_load(path.read_text())
    validate_config(copy.deepcopy(config), SCHEMA)


def test_a_file_cut_short_warns(tmp_path):
    """A cut that leaves valid YAML reads as a shorter config (the defaults fill the rest): its broken last
    line is the one sign left, and the warning names the file."""
    path = tmp_path / "cut.yaml"
    path.write_text("twin:\n  n_sessions: 2\ntraining:\n  n_folds: 3\n  max_epochs: 1")
    with pytest.warns(UserWarning, match=r"cut\.yaml: its last line has no newline: was the file cut short"):
        config = load_config_file(path)
    assert config == {"twin": {"n_sessions": 2}, "training": {"n_folds": 3, "max_epochs": 1}}
