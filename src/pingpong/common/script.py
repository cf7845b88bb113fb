"""The bridge between a workflow script and the package: one entry for Snakemake and the shell.

Under Snakemake a script calls `run_stage(main, snakemake)`; from a shell the same script runs as
`python workflow/scripts/x.py --input name=path --output name=path --params params.json`.
Either way `main(ctx)` gets plain paths and params, and its log goes to the rule's log file.
"""

import argparse
import contextlib
import json
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

from pingpong.common.artifacts import Provenance


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


def _from_argv(stage: str, argv) -> StageContext:
    ap = argparse.ArgumentParser(description=f"run the '{stage}' stage outside Snakemake")
    ap.add_argument("--input", nargs="*", default=[], metavar="NAME=PATH")
    ap.add_argument("--output", nargs="*", default=[], metavar="NAME=PATH")
    ap.add_argument("--params", help="JSON file with the rule's params")
    ap.add_argument("--log")
    a = ap.parse_args(argv)
    pairs = lambda items: Named(kv.split("=", 1) for kv in items)  # noqa: E731
    params = json.loads(Path(a.params).read_text()) if a.params else {}
    return StageContext(stage, pairs(a.input), pairs(a.output), params, Path(a.log) if a.log else None)


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


def run_stage(main, smk=None, stage: str | None = None) -> None:
    """Run `main(ctx)` with its logging (and stderr, where tqdm writes) going to the log file."""
    ctx = _from_snakemake(smk) if smk is not None else _from_argv(stage or main.__module__, sys.argv[1:])
    pin_threads(getattr(smk, "threads", 1))
    with contextlib.ExitStack() as stack:
        if ctx.log is not None:
            ctx.log.parent.mkdir(parents=True, exist_ok=True)
            stream = stack.enter_context(open(ctx.log, "w"))
            stack.enter_context(contextlib.redirect_stderr(stream))
        else:
            stream = sys.stderr
        logging.basicConfig(stream=stream, level=logging.INFO, force=True,
                            format="%(asctime)s %(levelname)s %(name)s: %(message)s")
        logging.captureWarnings(True)
        main(ctx)
