"""Every Python block of docs/readers.md (the worked examples the README's lab section points to) runs as
written."""

import re
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "docs/readers.md"


def lab_examples() -> list[str]:
    return re.findall(r"```python\n(.*?)```", EXAMPLES.read_text(), re.S)


def test_the_section_has_an_example_per_format():
    assert len(lab_examples()) == 5


@pytest.mark.parametrize("example", lab_examples(), ids=lambda e: e.splitlines()[0][2:40])
def test_example_runs(example, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(example, "README example", "exec"), {})
