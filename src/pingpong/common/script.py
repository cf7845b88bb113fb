"""The bridge between the workflow and the package: every rule runs `workflow/scripts/stage.py`, which
calls `run_rule`, which runs the rule's entry `pingpong.stages.<rule>.main(ctx)`.

Under Snakemake the rule's name comes from the job; from a shell the same script runs as
`python workflow/scripts/stage.py RULE --input name=path --output name=path --params params.json`.
Either way `main(ctx)` gets plain paths and params, and its log goes to the rule's log file.
"""

import argparse
import contextlib
import gc
import importlib
import json
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

import pingpong
from pingpong.common.artifacts import Provenance
from pingpong.common.atomic import sweep_temporaries
from pingpong.common.raw_ownership import recording
from pingpong.common.stages import entry_file, entry_module
from pingpong.common.stderr import fd2_onto


class Named(dict):
    """A dict whose keys read as attributes, and that iterates over its values like Snakemake's lists."""

    def __getattr__(self, key):
        try:
            return self[key]
        except KeyError as err:
            raise AttributeError(key) from err

    def __iter__(self):
        return iter(self.values())


@dataclass
class StageContext:
    stage: str
    input: Named
    output: Named
    params: dict
    log: Path | None

    def optional_input(self, name: str) -> str | None:
        """A named input that may be absent: a path, a list of at most one (Snakemake's conditional
        inputs), or nothing."""
        value = self.input.get(name)
        if isinstance(value, list | tuple):
            return str(value[0]) if value else None
        return str(value) if value else None

    def provenance(self) -> Provenance:
        params = {k: v for k, v in self.params.items() if k != "code"}
        files = [f for v in self.input.values() for f in (v if isinstance(v, list | tuple) else [v])]
        return Provenance.of(self.stage, params, self.params.get("code", ""), files)


def _named(items) -> Named:
    if hasattr(items, "_names"):  # Snakemake's Namedlist
        named = Named({name: items[i] if end is None else items[i:end]
                       for name, (i, end) in items._names.items()})
        if not named:
            named = Named({str(i): v for i, v in enumerate(items)})
        return named
    return Named(items)


def _from_snakemake(smk) -> StageContext:
    return StageContext(
        stage=smk.rule, input=_named(smk.input), output=_named(smk.output),
        params={k: v for k, v in smk.params.items()}, log=Path(smk.log[0]) if smk.log else None,
    )


def _from_argv(argv) -> StageContext:
    ap = argparse.ArgumentParser(description="run one rule's stage outside Snakemake")
    ap.add_argument("rule", help="the rule's name, e.g. detection")
    ap.add_argument("--input", nargs="*", default=[], metavar="NAME=PATH")
    ap.add_argument("--output", nargs="*", default=[], metavar="NAME=PATH")
    ap.add_argument("--params", help="JSON file with the rule's params")
    ap.add_argument("--log")
    a = ap.parse_args(argv)
    pairs = lambda items: Named(kv.split("=", 1) for kv in items)  # noqa: E731
    params = json.loads(Path(a.params).read_text()) if a.params else {}
    return StageContext(a.rule, pairs(a.input), pairs(a.output), params, Path(a.log) if a.log else None)


def pin_threads(threads: int) -> None:
    """Fixed thread counts, so that two runs on any machines give the same bytes.

    OpenCV's parallel loops sum in a scheduling-dependent order (calibrateCamera differed by 1e-7
    between runs with 2 threads, and every later stage with it); torch splits its reductions by its
    thread count, which is the machine's cores unless set. Parallelism comes from Snakemake's jobs.
    """
    cv2 = sys.modules.get("cv2")
    if cv2 is not None:
        cv2.setNumThreads(1)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(max(1, int(threads)))


def check_checkout(root: Path) -> None:
    """The imported `pingpong` must be the checkout's own `src/`: the code hash is computed from there."""
    imported = Path(pingpong.__file__).resolve().parent
    expected = (root / "src" / "pingpong").resolve()
    if imported != expected:
        raise ImportError(f"this job imports pingpong from {imported}, but the workflow's code hash is "
                          f"computed from {expected}: install this checkout (`pip install -e .`) or put "
                          f"its src/ on PYTHONPATH")


def _paths(named: Named) -> list[str]:
    return [f for v in named.values() for f in (v if isinstance(v, list | tuple) else [v])]


def sweep_outputs(ctx: StageContext) -> None:
    """Remove the temporary files that killed writes of this job's outputs left (only those: the atomic
    writes' own names beside each output, `pingpong.common.atomic.sweep_temporaries`); a killed camera
    job leaves one of ~220 MB."""
    for path in _paths(ctx.output):
        sweep_temporaries(path)


def run_rule(smk=None) -> None:
    """Run the rule's entry `main(ctx)` with its logging and stderr (Python's, where tqdm writes, and file
    descriptor 2, where C libraries write) to the log file."""
    ctx = _from_snakemake(smk) if smk is not None else _from_argv(sys.argv[1:])
    script = Path(smk.scriptdir) if smk is not None else Path(sys.argv[0]).resolve().parent
    check_checkout(script.parents[1])  # workflow/scripts/ -> the checkout's root
    entry_file(ctx.stage, script.parents[1])  # a clear error naming the expected file
    main = importlib.import_module(entry_module(ctx.stage)).main
    pin_threads(getattr(smk, "threads", 1))
    # The cycle collector's young generation every 100,000 allocations, not 700: a frame's shapes or a
    # file's JSON make thousands of short-lived objects that refcounting frees anyway. A twin_camera job
    # 23.3-23.5 s instead of 23.8-24.2 s, pose2d's 4.8 s instead of 4.8-6.5 s (two runs each, interleaved).
    gc.set_threshold(100_000, *gc.get_threshold()[1:])
    with contextlib.ExitStack() as stack:
        if ctx.log is not None:
            ctx.log.parent.mkdir(parents=True, exist_ok=True)
            stream = stack.enter_context(open(ctx.log, "w", buffering=1))  # line-buffered: in order with fd 2
            stack.enter_context(contextlib.redirect_stderr(stream))
            stack.enter_context(fd2_onto(stream.fileno()))
        else:
            stream = sys.stderr
        logging.basicConfig(stream=stream, level=logging.INFO, force=True,
                            format="%(asctime)s %(levelname)s %(name)s: %(message)s")
        logging.captureWarnings(True)
        sweep_outputs(ctx)
        try:
            with recording(ctx.stage, _paths(ctx.output)):
                main(ctx)
        except Exception:  # into the log too, where Snakemake's error message sends the reader
            logging.exception("rule %s failed", ctx.stage)
            raise
