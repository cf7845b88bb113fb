"""How a rule's name leads to its code: every rule runs one script, which runs the entry named like
the rule (docs/architecture.md, "Where each rule's code lives"). Kept free of imports: the Snakefile
and every job read it."""

from pathlib import Path

STAGE_SCRIPT = "workflow/scripts/stage.py"  # relative to the checkout's root
ENTRY_PACKAGE = "pingpong.stages"


def entry_module(rule: str) -> str:
    """The dotted name of the module whose `main(ctx)` runs the rule."""
    if not rule.isidentifier():
        raise ValueError(f"'{rule}' is not a rule name (expected a Python identifier)")
    return f"{ENTRY_PACKAGE}.{rule}"


def entry_file(rule: str, root: str | Path = ".") -> str:
    """The entry module's path relative to `root` (the checkout); an error naming it when it is missing."""
    relative = Path("src", *entry_module(rule).split(".")).with_suffix(".py")
    if not (Path(root) / relative).is_file():
        raise FileNotFoundError(f"rule '{rule}' has no entry: expected {relative} with a main(ctx)")
    return str(relative)
