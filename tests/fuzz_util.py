"""The readers' fuzz harness: damaged inputs through a reader in a child process, each outcome classified.

A reader may crash the interpreter (a C library's heap corrupted by a header it trusted) or hang (a
decoder told to allocate 30000 x 30000 pixels): either would kill or stall the test run, so every call
runs in a forked child that is replaced when it dies or overruns its time. The child answers each call
with what the reader returned (a summary the caller compares), raised or warned.

Outcomes, as the fuzz table counts them:
- `clean_error`: an error of the project's reader type (a ValueError or OSError subclass raised by the
  project's code) whose message names the file;
- `warning`: returned, with a warning that names the file;
- `unaffected`: returned what the undamaged file gives, without a word;
- `silent_wrong`: returned something else, without a word (acceptable only where the format cannot tell,
  e.g. a changed pixel of a JPEG: the caller decides);
- `unclear`: any other exception (a library's own, or one that does not name the file);
- `crash`: the child died (a signal, an abort); `hang`: it overran the time limit.
"""

import faulthandler
import multiprocessing as mp
import traceback
import warnings
from collections import Counter
from dataclasses import dataclass
from importlib import import_module
from pathlib import Path

OUTCOMES = ("clean_error", "warning", "unaffected", "silent_wrong", "unclear", "crash", "hang")


@dataclass
class Result:
    kind: str  # 'returned', 'raised', 'crash' or 'hang'
    value: object = None  # the summary of what was returned
    error: str = ""  # type and message of what was raised
    project_error: bool = False  # raised by the project's code as a ValueError or OSError
    warned: tuple[str, ...] = ()

    def outcome(self, path, expected) -> str:
        """This result's class for a call on `path` whose undamaged input returns `expected`."""
        name = Path(path).name
        if self.kind in ("crash", "hang"):
            return self.kind
        if self.kind == "raised":
            return "clean_error" if self.project_error and name in self.error else "unclear"
        if any(name in w for w in self.warned):
            return "warning"
        return "unaffected" if _equal(self.value, expected) else "silent_wrong"


def _equal(a, b) -> bool:
    try:
        import numpy as np
        return bool(np.array_equal(np.asarray(a, dtype=object), np.asarray(b, dtype=object)))
    except (ValueError, TypeError):
        return a == b


def _call(target: str, args: tuple, kwargs: dict) -> Result:
    """Run `module:function` (its result through `module:summary` when the module has one for it)."""
    module_name, func_name = target.split(":")
    func = getattr(import_module(module_name), func_name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            value = func(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - the point is to classify whatever a reader raises
            origin = traceback.extract_tb(exc.__traceback__)[-1].filename
            ours = "pingpong" in Path(origin).parts or "pingpong" in type(exc).__module__
            return Result("raised", error=f"{type(exc).__name__}: {exc}"[:2000],
                          project_error=isinstance(exc, ValueError | OSError) and ours)
    return Result("returned", value=value, warned=tuple(str(w.message)[:2000] for w in caught))


def _serve(conn) -> None:
    faulthandler.disable()  # pytest's, inherited by the fork: a crash is an outcome here, not a trace
    while True:
        request = conn.recv()
        if request is None:
            return
        conn.send(_call(*request))


class IsolatedReader:
    """Calls functions in a forked child; a crash or a hang costs that child, not the test run."""

    def __init__(self, timeout_s: float = 10.0):
        self.timeout_s = timeout_s
        self._child = None

    def _start(self) -> None:
        parent, child = mp.get_context("fork").Pipe()
        self._child = mp.get_context("fork").Process(target=_serve, args=(child,), daemon=True)
        self._child.start()
        self._conn = parent

    def _stop(self) -> None:
        if self._child is not None:
            self._child.kill()
            self._child.join()
            self._child = None

    def call(self, target: str, *args, **kwargs) -> Result:
        """`target` ('module:function') called with args; its value must be picklable (summarise first)."""
        if self._child is None or not self._child.is_alive():
            self._start()
        self._conn.send((target, args, kwargs))
        if not self._conn.poll(self.timeout_s):
            self._stop()
            return Result("hang")
        try:
            return self._conn.recv()
        except (EOFError, ConnectionResetError):
            self._stop()
            return Result("crash")

    def close(self) -> None:
        if self._child is not None and self._child.is_alive():
            self._conn.send(None)
            self._child.join(5)
        self._stop()


def tally(outcomes: list[str]) -> dict[str, int]:
    """Counts by outcome, every outcome present (0 where none), and the number of examples."""
    counts = Counter(outcomes)
    return {"examples": len(outcomes), **{k: counts.get(k, 0) for k in OUTCOMES}}


TABLE: dict[str, dict[str, int]] = {}  # reader -> counts, for the fuzz table (tests/conftest.py writes it)


def record(reader: str, outcomes: list[str]) -> dict[str, int]:
    """A reader's counts, kept for the fuzz table; returned for the test's assertions."""
    TABLE[reader] = tally(outcomes)
    return TABLE[reader]


def table_markdown() -> str:
    header = "| reader | " + " | ".join(["examples", *OUTCOMES]) + " |"
    rows = [f"| {reader} | " + " | ".join(str(v) for v in counts.values()) + " |"
            for reader, counts in sorted(TABLE.items())]
    return "\n".join([header, "|---" * (len(OUTCOMES) + 2) + "|", *rows]) + "\n"


def damaged(data: bytes, rng, kinds=("truncate", "flip", "insert", "delete", "empty")) -> tuple[str, bytes]:
    """One damaged copy of `data` of a kind drawn from `kinds`: a truncation, a flipped bit, inserted or
    deleted bytes, or an empty file; returns (kind, bytes)."""
    kind = kinds[int(rng.integers(len(kinds)))]
    if kind == "empty" or not data:
        return "empty", b""
    at = int(rng.integers(len(data)))
    if kind == "truncate":
        return kind, data[:at]
    if kind == "flip":
        return kind, data[:at] + bytes([data[at] ^ (1 << int(rng.integers(8)))]) + data[at + 1:]
    if kind == "insert":
        noise = rng.integers(0, 256, int(rng.integers(1, 16)), dtype="uint8")
        return kind, data[:at] + bytes(noise) + data[at:]
    return kind, data[:at] + data[at + int(rng.integers(1, 16)):]
