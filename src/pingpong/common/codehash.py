"""The code hash of a stage: its script plus every pingpong module it imports, transitively.

Snakemake reruns a job when its params change but does not track imported modules, so each
rule passes this hash in `params:`. Following the imports (rather than a hand-kept list of
modules per stage) means that editing a module reruns exactly the stages that use it.
"""

import ast
import functools
import hashlib
from pathlib import Path

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


@functools.cache
def code_hash(script: str, root: str = ".") -> str:
    """SHA-256 over `script` and the source of every pingpong module it reaches by imports."""
    root_path = Path(root).resolve()
    src = root_path / "src"
    seen: dict[str, Path] = {}
    todo = [root_path / script]
    files = [root_path / script]
    while todo:
        for name in _imported_modules(todo.pop(), src):
            if name in seen:
                continue
            f = _module_file(src, name)
            seen[name] = f
            if f is not None:
                todo.append(f)
                files.append(f)
    h = hashlib.sha256()
    for f in sorted(set(files)):
        h.update(str(f.relative_to(root_path)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]
