"""Runs a command and records its wall time, CPU time (user + system, of it and its children) and peak
memory as one JSON line of a file, so that a run made in parts (a resumed Snakemake run, or a rerun of what
a later commit changed) sums its parts; each part names the commit it ran (None outside a git checkout):

    .venv/bin/python analysis/timed_run.py TIMES.jsonl -- COMMAND [ARGS...]

The line is rewritten every CHECKPOINT_S while the command runs ("complete": false), so a part killed with
its session (SIGKILL, which nothing can catch) keeps its time up to the last checkpoint; SIGINT and SIGTERM
are passed to the command, which ends as it would alone, and the part is then recorded in full. Portable
where GNU time (`/usr/bin/time -v`) is not installed (mid-run CPU is read from Linux's /proc; elsewhere the
checkpoints carry wall time only); the exit status is the command's, as a shell gives it."""

import json
import os
import resource
import signal
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

CHECKPOINT_S = 30.0


def cpu_so_far(pid: int) -> tuple[float | None, float | None]:
    """User and system seconds of a running process and of the children it has reaped (Snakemake reaps
    its jobs), from /proc/PID/stat: fields utime, stime, cutime, cstime (proc(5)); None where unreadable."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None, None
    tick = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[13])) / tick, (int(fields[12]) + int(fields[14])) / tick


def head_commit() -> str | None:
    """The working directory's checked-out commit, or None."""
    try:
        done = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    except OSError:  # no git
        return None
    return done.stdout.strip() or None if done.returncode == 0 else None


def _key(part: dict) -> tuple:
    return part.get("started"), part.get("pid")


def write_part(times: Path, part: dict) -> None:
    """Replaces this part's line (same start and pid) or appends it; atomic, so a kill mid-write loses
    nothing already recorded."""
    lines = times.read_text().splitlines() if times.is_file() else []
    kept = [line for line in lines if line.strip() and _key(json.loads(line)) != _key(part)]
    tmp = times.with_name(times.name + ".tmp")
    tmp.write_text("\n".join([*kept, json.dumps(part)]) + "\n", encoding="utf-8")
    os.replace(tmp, times)


def main(argv: list[str]) -> int:
    if len(argv) < 3 or argv[1] != "--":
        sys.exit(__doc__)
    times, started, t0 = Path(argv[0]), datetime.now(UTC).isoformat(timespec="seconds"), time.monotonic()
    child = subprocess.Popen(argv[2:])
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _frame: child.send_signal(signum))
    part = {"started": started, "pid": child.pid, "commit": head_commit(), "command": argv[2:]}
    while True:
        try:
            code = child.wait(timeout=CHECKPOINT_S)
            break
        except subprocess.TimeoutExpired:
            user, system = cpu_so_far(child.pid)
            write_part(times, part | {"wall_s": round(time.monotonic() - t0, 1), "user_s": user,
                                      "system_s": system, "max_rss_mb": None, "complete": False})
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    write_part(times, part | {"wall_s": round(time.monotonic() - t0, 1), "user_s": round(usage.ru_utime, 1),
                              "system_s": round(usage.ru_stime, 1), "returncode": code, "complete": True,
                              "max_rss_mb": round(usage.ru_maxrss / 1024, 1)})
    return code if code >= 0 else 128 - code  # killed by signal N: the shell's status 128 + N


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
