"""What under raw/ the pipeline wrote itself, by content: the only files a rule or `make clean` may replace.

A lab's recordings are irreplaceable, and a path says nothing about who wrote a file: a lab's session
folder can carry a twin's name (`s00/openpose/cam0`), and a twin run leaves no mark on a lab's files.
So every job whose outputs lie under raw/ (the twin's) records each file it writes with its SHA-256 in
`raw/twin_truth/owned/`, and before any job runs (`check`, from the Snakefile, the dry run too) every file
under raw/ must be one of those with the same content; `clean` removes only such files.

Records, one per job (named by the rule and its outputs, so parallel jobs never share a file), in
sha256sum's format (`sha256  path` lines; `sha256sum -c` reads them):
- `{rule}-{key}.pending`: a line appended and synced just before each write is renamed into place
  (`pingpong.common.atomic`'s hook), so a job killed between its renames and its end still owns them;
- `{rule}-{key}.sha256`: the same, compacted to its output files, at the job's end.
Reading 28 GB (the paper-scale raw/) at every start of Snakemake would cost minutes, so a cache
(`.snakemake/raw_stat_cache.json`: the workflow's state, not an artifact; its stats differ run to run)
keeps each file's size, mtime, ctime and inode beside the hash it was last found to have, as git's index
does: a file whose stat is unchanged is not read again (a copy, `cp -p`, `rsync -a` or any write changes
the inode, mtime or ctime, which no user tool sets back). The check fills it in, not the job, because
Snakemake touches a job's outputs after it ends.

Not counted as anyone's file: `.gitkeep` (the repository's), `.snakemake_timestamp` (Snakemake writes it
into directory outputs) and the atomic writes' temporaries (`.NAME.XXXXXXXX.tmp`, swept by the job that
left them); a lab's file of exactly such a name inside a twin output folder is the one thing the
check would not stop (no recording tool writes those names). Standard library only: `make clean` runs it
without the project's environment.
"""

import contextlib
import hashlib
import json
import os
import re
import sys
from collections.abc import Iterator
from pathlib import Path

from pingpong.common import atomic
from pingpong.common.hashing import file_sha256

RAW = "raw"
OWNED = "raw/twin_truth/owned"
STAT_CACHE = ".snakemake/raw_stat_cache.json"
NOT_RECORDINGS = {".gitkeep", ".snakemake_timestamp"}
_TEMPORARY = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")  # common.atomic's temporary names
_SHOWN = 12  # files named in an error before "and N more"


class RawOwnershipError(RuntimeError):
    """Files under raw/ that the pipeline did not write, where it would write."""


def _relative(path: str | os.PathLike, root: Path) -> str:
    return Path(os.path.relpath(os.path.abspath(path), root)).as_posix()


def under_raw(path: str | os.PathLike, root: Path = Path(".")) -> bool:
    rel = _relative(path, Path(root).resolve())
    return rel == RAW or rel.startswith(RAW + "/")


def _stat_key(st: os.stat_result) -> list[int]:
    return [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino]


def _files_in(path: str | os.PathLike, rel: str) -> Iterator[tuple[str, str, os.stat_result]]:
    """A file, or every file inside a folder (a symbolic link counts as a file and is never followed), by
    name: (path, its name under `rel`, its lstat). Strings and scandir, not pathlib: 200,000 files
    (the default run's raw/) take 1 s so, where Path objects took 11 s."""
    path = os.fspath(path)
    if not os.path.isdir(path) or os.path.islink(path):
        if os.path.lexists(path):
            yield path, rel, os.lstat(path)
        return
    stack = [(path, rel)]  # depth first, by name: a stack, not recursion (generators nest per level)
    while stack:
        folder, folder_rel = stack.pop()
        with os.scandir(folder) as entries:
            listed = sorted(entries, key=lambda e: e.name)
        subfolders = []
        for entry in listed:
            if entry.name in NOT_RECORDINGS or _TEMPORARY.fullmatch(entry.name):
                continue
            if entry.is_dir(follow_symlinks=False):
                subfolders.append((entry.path, f"{folder_rel}/{entry.name}"))
            else:
                yield entry.path, f"{folder_rel}/{entry.name}", entry.stat(follow_symlinks=False)
        stack.extend(reversed(subfolders))


def _job_stem(stage: str, outputs: list[str]) -> str:
    key = hashlib.sha256("\n".join(sorted(outputs)).encode()).hexdigest()[:16]
    return f"{stage}-{key}"


@contextlib.contextmanager
def recording(stage: str, outputs: list[str], root: Path = Path(".")) -> Iterator[None]:
    """Record what a job writes under raw/ (nothing when no output lies there): each file's hash before
    its rename (the .pending file), then every output file's hash and stat once the job succeeds."""
    root = Path(root).resolve()
    mine = sorted(_relative(p, root) for p in outputs if under_raw(p, root))
    if not mine:
        yield
        return
    stem = root / OWNED / _job_stem(stage, mine)
    stem.parent.mkdir(parents=True, exist_ok=True)

    def before_rename(tmp: Path, final: Path) -> None:
        if not under_raw(final, root):
            return
        lines = [f"{file_sha256(f)}  {rel}\n" for f, rel, _ in _files_in(tmp, _relative(final, root))]
        with open(stem.with_suffix(".pending"), "a") as out:
            out.writelines(lines)
            out.flush()
            os.fsync(out.fileno())

    atomic.BEFORE_RENAME.append(before_rename)
    try:
        yield
    finally:
        atomic.BEFORE_RENAME.remove(before_rename)
    pending = _hash_lines(stem.with_suffix(".pending"))
    files = [(f, rel) for out in mine for f, rel, _ in _files_in(root / out, out)]
    lines = [f"{pending.get(rel) or file_sha256(f)}  {rel}\n" for f, rel in files]
    atomic.write_text_atomic(stem.with_suffix(".sha256"), "".join(lines))
    stem.with_suffix(".pending").unlink(missing_ok=True)


def _hash_lines(path: Path) -> dict[str, str]:
    """The last hash a record gives each path."""
    pairs = (line.split("  ", 1) for line in path.read_text().splitlines() if "  " in line)
    return {rel: sha for sha, rel in pairs}


def owned(root: Path = Path(".")) -> dict[str, set[str]]:
    """Every path the records list, with the hashes it may have."""
    folder = Path(root) / OWNED
    hashes: dict[str, set[str]] = {}
    for path in sorted([*folder.glob("*.sha256"), *folder.glob("*.pending")]) if folder.is_dir() else []:
        for rel, sha in _hash_lines(path).items():
            hashes.setdefault(rel, set()).add(sha)
    return hashes


def _read_cache(root: Path) -> dict[str, list]:
    path = root / STAT_CACHE
    try:
        return json.loads(path.read_text()) if path.is_file() else {}
    except (OSError, ValueError):  # a damaged cache costs only its reading again
        return {}


def _classify(root: Path, cache_to: Path | None) -> tuple[list[tuple[str, str]], list[str]]:
    """The files under raw/ (the records excepted) that the records list with their present content, and
    the others; the stat cache refreshed for what it had to read (cache_to: where; None, not written)."""
    hashes, cache = owned(root), _read_cache(root)
    fresh, mine, foreign = {}, [], []
    for f, rel, st in _files_in(root / RAW, RAW):
        if rel.startswith(OWNED + "/"):
            continue
        stat = _stat_key(st)
        cached = cache.get(rel)
        sha = cached[0] if cached and cached[1:] == stat else file_sha256(f)
        if sha in hashes.get(rel, ()):
            mine.append((f, rel))
            fresh[rel] = [sha, *stat]
        else:
            foreign.append(rel)
    if cache_to is not None and fresh != cache:
        with contextlib.suppress(OSError):  # where it cannot be written, the files are only read again
            atomic.write_text_atomic(cache_to, json.dumps(fresh))
    return mine, foreign


def foreign_files(root: Path = Path(".")) -> list[str]:
    """The files under raw/ that no record lists with their present content (the records excepted)."""
    return _classify(Path(root), Path(root) / STAT_CACHE)[1]


def check(root: Path = Path(".")) -> None:
    """Stop, naming the files, when raw/ holds anything the pipeline did not write (source: twin, whose
    rules write raw/: before any job runs)."""
    foreign = foreign_files(root)
    if not foreign:
        return
    more = f"\n  ... and {len(foreign) - _SHOWN} more" if len(foreign) > _SHOWN else ""
    raise RawOwnershipError(
        f"{len(foreign)} files under raw/ were not written by the twin (or were changed since; "
        f"records in {OWNED}/), and source: twin writes raw/:\n  "
        + "\n  ".join(foreign[:_SHOWN]) + more
        + "\nNothing was run. To run on these recordings, set source: lab (the README's 'Bringing your lab's "
        "recordings'); to simulate, move them out of raw/ first.")


def clean(root: Path = Path(".")) -> tuple[list[str], list[str]]:
    """Remove the files under raw/ that the records list with their present content, then the records and
    the folders left empty; everything else stays. Returns (removed, kept)."""
    root = Path(root)
    mine, kept = _classify(root, None)
    for f, _rel in mine:
        os.unlink(f)
    for record in sorted((root / OWNED).iterdir()) if (root / OWNED).is_dir() else []:
        record.unlink()
    removed = [rel for _f, rel in mine]
    _remove_emptied_folders(root / RAW, {(root / r).parent for r in removed} | {root / OWNED})
    return removed, kept


def _remove_emptied_folders(top: Path, folders: set[Path]) -> None:
    """The folders that clean emptied, and their parents up to `top` (which stays) while they hold nothing
    but Snakemake's timestamp: a folder the lab made and left empty is the lab's."""
    for folder in sorted(folders, key=lambda p: -len(p.parts)):
        while folder != top and folder.is_dir() and not folder.is_symlink() \
                and set(os.listdir(folder)) <= {".snakemake_timestamp"}:
            (folder / ".snakemake_timestamp").unlink(missing_ok=True)
            folder.rmdir()
            folder = folder.parent


def main(argv: list[str]) -> int:
    """`python -m pingpong.common.raw_ownership clean|check [ROOT]` (make clean runs `clean`)."""
    if not argv or argv[0] not in ("clean", "check"):
        print(main.__doc__, file=sys.stderr)
        return 2
    root = Path(argv[1] if len(argv) > 1 else ".")
    if argv[0] == "check":
        foreign = foreign_files(root)
        print("\n".join(foreign) or "every file under raw/ was written by the twin")
        return 1 if foreign else 0
    removed, kept = clean(root)
    print(f"removed the twin's {len(removed)} files under raw/; kept {len(kept)} files it did not write"
          + "".join(f"\n  kept {k}" for k in kept[:_SHOWN])
          + (f"\n  ... and {len(kept) - _SHOWN} more" if len(kept) > _SHOWN else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
