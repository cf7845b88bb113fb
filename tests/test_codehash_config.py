"""Stage code hashes follow imports; config validation names the key and the expected type."""

import re
from pathlib import Path

import pytest
from workflow_util import copy_checkout, snakemake

from pingpong.common.codehash import code_files, code_hash, stage_code_hash
from pingpong.common.config import ConfigError, validate_config
from pingpong.common.script import check_checkout
from pingpong.common.stages import STAGE_SCRIPT, entry_file

ROOT = Path(__file__).resolve().parents[1]


def _tree(tmp_path):
    files = {
        "workflow/scripts/detect.py": "from pingpong.perception import detect\n",
        "workflow/scripts/twin.py": "import pingpong.twin.ball as ball\n",
        "src/pingpong/__init__.py": "",
        "src/pingpong/perception/__init__.py": "",
        "src/pingpong/perception/detect.py": "from .mask import hsv\nfrom ..common import util\n",
        "src/pingpong/perception/mask.py": "hsv = 1\n",
        "src/pingpong/common/__init__.py": "",
        "src/pingpong/common/util.py": "x = 1\n",
        "src/pingpong/twin/__init__.py": "",
        "src/pingpong/twin/ball.py": "g = 9.81\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    return tmp_path


def _hash(root, script):
    code_files.cache_clear()
    return code_hash(script, root=str(root))


def test_hash_follows_absolute_and_relative_imports(tmp_path):
    root = _tree(tmp_path)
    detect0, twin0 = _hash(root, "workflow/scripts/detect.py"), _hash(root, "workflow/scripts/twin.py")
    (root / "src/pingpong/perception/mask.py").write_text("hsv = 2\n")  # reached via `from .mask`
    detect1 = _hash(root, "workflow/scripts/detect.py")
    assert detect1 != detect0 and _hash(root, "workflow/scripts/twin.py") == twin0
    (root / "src/pingpong/common/util.py").write_text("x = 2\n")  # reached via `from ..common`
    assert _hash(root, "workflow/scripts/detect.py") != detect1
    (root / "src/pingpong/twin/ball.py").write_text("g = 9.80665\n")
    assert _hash(root, "workflow/scripts/twin.py") != twin0


def test_any_edit_to_the_script_changes_the_hash(tmp_path):
    root = _tree(tmp_path)
    before = _hash(root, "workflow/scripts/twin.py")
    (root / "workflow/scripts/twin.py").write_text("import pingpong.twin.ball as ball  # edited\n")
    assert _hash(root, "workflow/scripts/twin.py") != before


def workflow_rules() -> list[str]:
    """Every rule of the workflow, read from its rule files."""
    return [name for smk in sorted((ROOT / "workflow/rules").glob("*.smk"))
            for name in re.findall(r"^rule (\w+):", smk.read_text(), re.M)]


def _stage_files(rule):
    return code_files(STAGE_SCRIPT, entry_file(rule, ROOT), root=str(ROOT))


def test_every_rules_hash_covers_the_script_and_its_entry():
    rules = workflow_rules()
    assert len(rules) > 25 and "detection" in rules
    for rule in rules:
        files = {str(f.relative_to(ROOT)) for f in _stage_files(rule)}
        expected = {STAGE_SCRIPT, f"src/pingpong/stages/{rule}.py", "src/pingpong/common/script.py"}
        assert expected <= files, rule
    # an entry's own imports are covered: detection reaches the detector, not the twin
    files = {f.name for f in _stage_files("detection")}
    assert "detection.py" in files and "mcap_io.py" in files and "render.py" not in files


def test_a_rule_without_an_entry_is_named():
    with pytest.raises(FileNotFoundError, match="rule 'no_such_rule' has no entry: expected "
                                                r"src/pingpong/stages/no_such_rule\.py"):
        stage_code_hash("no_such_rule", str(ROOT))


def test_a_job_importing_another_checkouts_package_stops(tmp_path):
    check_checkout(ROOT)  # this checkout's own package (installed editable, or on PYTHONPATH)
    with pytest.raises(ImportError, match="imports pingpong from .* but the workflow's code hash is"):
        check_checkout(tmp_path)


SCHEMA = ROOT / "config/schema.yaml"


def test_defaults_are_filled_from_the_schema():
    config = validate_config({}, SCHEMA)
    assert config["source"] == "twin" and isinstance(config["seed"], int)
    assert config["twin"]["n_cameras"] == 4


def test_unknown_key_is_named():
    with pytest.raises(ConfigError, match=r"config key 'twin': unknown key\(s\) \['n_sesions'\]"):
        validate_config({"twin": {"n_sesions": 3}}, SCHEMA)


def test_wrong_type_names_key_and_type():
    with pytest.raises(ConfigError, match=r"config key 'seed': expected integer, got str 'abc'"):
        validate_config({"seed": "abc"}, SCHEMA)


def test_shipped_configs_are_valid():
    import yaml

    names = [p.relative_to(ROOT / "config") for p in sorted((ROOT / "config").glob("**/*.yaml"))
             if p.name != "schema.yaml" and "robot" not in p.parts]
    shipped = {"config.yaml", "paper.yaml", "paper_hits.yaml", "twin_homoscedastic.yaml"}
    assert shipped <= {str(n) for n in names}
    for name in names:
        path = ROOT / "config" / name
        validate_config(yaml.safe_load(path.read_text()) or {}, SCHEMA)


def test_the_workflow_refuses_a_rule_with_another_rules_hash(tmp_path):
    root = copy_checkout(tmp_path)
    rules = root / "workflow/rules/perception.smk"
    rules.write_text(rules.read_text().replace('code=code("detection")', 'code=code("pose2d")', 1))
    proc = snakemake(root, "-n", configfile="config/config.yaml", check=False)
    assert proc.returncode != 0
    assert "detection (a rule) must pass code('detection') as params.code" in proc.stdout + proc.stderr


def test_registered_names_are_the_config_enum():
    from pingpong.uncertainty.names import ESTIMATORS

    enums = {"robot.estimator": [*ESTIMATORS, None]}
    assert validate_config({"robot": {"estimator": "cqr"}}, SCHEMA, enums)["robot"]["estimator"] == "cqr"
    with pytest.raises(ConfigError, match="config key 'robot.estimator': 'nope' is not one of"):
        validate_config({"robot": {"estimator": "nope"}}, SCHEMA, enums)


def test_the_rules_conda_environment_lists_the_projects_requirements():
    import tomllib

    import yaml

    env = yaml.safe_load((ROOT / "workflow/envs/pingpong.yaml").read_text())
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert pip == project["dependencies"] and "python=3.11" in env["dependencies"]
