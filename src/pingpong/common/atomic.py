"""Atomic file writes: write under a temporary name in the same folder, then rename.

A killed run therefore never leaves a half-written file under the final name, and a file
already there stays intact until the new one is complete. What a killed write leaves is a
temporary file of the pattern `.{name}.XXXXXXXX.tmp` beside its target (a folder for
`atomic_dir`): `sweep_temporaries` removes those of a job's outputs when the job starts again.
Artifacts get the modes of an ordinary write under the process's umask (mkstemp's and mkdtemp's
are 0600 and 0700 whatever the umask).
"""

import contextlib
import logging
import os
import re
import shutil
import tempfile
from pathlib import Path

log = logging.getLogger(__name__)

_PREFIX, _SUFFIX = ".", ".tmp"
# Called as hook(temporary, final) just before a write is renamed into place: a job that writes raw/
# records each file's hash there first (pingpong.common.raw_ownership.recording), so that whatever a
# killed job left is still known as its own.
BEFORE_RENAME: list = []
# mkstemp's and mkdtemp's random part: 8 characters of tempfile's alphabet (lower-case letters, digits, _)
_RANDOM = re.compile(r"[a-z0-9_]{8}")


def _umask() -> int:
    """The process's umask (read by setting it and setting it back: os has no getter before 3.13)."""
    mask = os.umask(0o077)
    os.umask(mask)
    return mask


def _temporary_name(final: Path) -> str:
    return f"{_PREFIX}{final.name}."


def is_temporary_of(candidate: Path, final: Path) -> bool:
    """Whether `candidate` is a temporary file or folder that an atomic write of `final` makes."""
    name, head = candidate.name, _temporary_name(final)
    if candidate.parent != final.parent or not (name.startswith(head) and name.endswith(_SUFFIX)):
        return False
    return bool(_RANDOM.fullmatch(name[len(head):-len(_SUFFIX)]))


def sweep_temporaries(path: str | os.PathLike) -> list[Path]:
    """Remove what killed atomic writes of `path` left beside it (only names of the atomic writes'
    pattern for this very `path`, nothing else); returns what was removed."""
    final = Path(path)
    if not final.parent.is_dir():
        return []
    removed = []
    for candidate in sorted(final.parent.iterdir()):  # not glob: an output's name may hold [ or *
        if not is_temporary_of(candidate, final):
            continue
        if candidate.is_dir() and not candidate.is_symlink():
            shutil.rmtree(candidate, ignore_errors=True)
        else:
            with contextlib.suppress(FileNotFoundError):
                candidate.unlink()
        log.info("removed %s, left by a killed write of %s", candidate, final)
        removed.append(candidate)
    return removed


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside `path`; rename it onto `path` only if the block succeeds."""
    final = Path(path)
    final.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=_temporary_name(final), suffix=_SUFFIX, dir=final.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # the block may have replaced the file: chmod after it
        for hook in BEFORE_RENAME:
            hook(Path(tmp), final)
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    write_bytes_atomic(path, text.encode())


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike):
    """Yield a temporary folder beside `path`; it replaces `path` only if the block succeeds."""
    final = Path(path)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=_temporary_name(final), suffix=_SUFFIX, dir=final.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        for hook in BEFORE_RENAME:
            hook(tmp, final)
        if final.exists():
            shutil.rmtree(final)
        os.replace(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
