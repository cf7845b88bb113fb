"""The code hash of a stage: the rules' script, the rule's entry and every pingpong module they import,
transitively (docs/architecture.md, "Code hashes").

Snakemake reruns a job when its params change but does not track imported modules, so each
rule passes this hash in `params:`. Following the imports (rather than a hand-kept list of
modules per stage) means that editing a module reruns exactly the stages that use it.
"""

import ast
import functools
import hashlib
from pathlib import Path

from pingpong.common.stages import STAGE_SCRIPT, entry_file

PACKAGE = "pingpong"


def _module_file(src: Path, dotted: str) -> Path | None:
    base = src.joinpath(*dotted.split("."))
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _imported_modules(path: Path, src: Path) -> set[str]:
    """Dotted names of the pingpong modules (and their parent packages) that `path` imports."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    here = path.relative_to(src).with_suffix("").parts if path.is_relative_to(src) else ()
    is_init = path.name == "__init__.py"
    if is_init:
        here = here[:-1]  # a package's __init__ stands for the package itself
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import inside the package
                pkg = list(here[: len(here) - node.level + is_init])
                mod = ".".join(pkg + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names.add(mod)
            names.update(f"{mod}.{a.name}" for a in node.names)
    out = set()
    for name in names:
        parts = name.split(".")
        if parts[0] == PACKAGE:
            out.update(".".join(parts[: i + 1]) for i in range(len(parts)))
    return out


def stage_code_hash(rule: str, root: str = ".") -> str:
    """The code hash of a rule: the stage script, the rule's entry module and everything they import."""
    return code_hash(STAGE_SCRIPT, entry_file(rule, root), root=root)


@functools.cache
def code_files(*scripts: str, root: str = ".") -> tuple[Path, ...]:
    """`scripts` and every pingpong module they reach by imports, sorted."""
    root_path = Path(root).resolve()
    src = root_path / "src"
    seen: dict[str, Path] = {}
    todo = [root_path / s for s in scripts]
    files = list(todo)
    while todo:
        for name in _imported_modules(todo.pop(), src):
            if name in seen:
                continue
            f = _module_file(src, name)
            seen[name] = f
            if f is not None:
                todo.append(f)
                files.append(f)
    return tuple(sorted(set(files)))


def code_hash(*scripts: str, root: str = ".") -> str:
    """SHA-256 over `scripts` and the source of every pingpong module they reach by imports."""
    root_path = Path(root).resolve()
    h = hashlib.sha256()
    for f in code_files(*scripts, root=root):
        h.update(str(f.relative_to(root_path)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]
