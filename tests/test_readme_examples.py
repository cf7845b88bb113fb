"""Every Python block of the README's "Bringing your lab's recordings" runs as written."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def lab_examples() -> list[str]:
    text = README.read_text()
    section = text.split("## Bringing your lab's recordings", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, re.S)


def test_the_section_has_an_example_per_format():
    assert len(lab_examples()) == 5


@pytest.mark.parametrize("example", lab_examples(), ids=lambda e: e.splitlines()[0][2:40])
def test_example_runs(example, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(example, "README example", "exec"), {})
