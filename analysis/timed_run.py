"""Runs a command and appends its wall time, CPU time (user + system, of it and its children) and peak
memory as one JSON line to a file, so that a run made in parts (a resumed Snakemake run) sums its parts:

    .venv/bin/python analysis/timed_run.py TIMES.jsonl -- COMMAND [ARGS...]

Portable where GNU time (`/usr/bin/time -v`) is not installed; the exit status is the command's."""

import json
import resource
import subprocess
import sys
import time
from datetime import UTC, datetime


def main(argv: list[str]) -> int:
    if len(argv) < 3 or argv[1] != "--":
        sys.exit(__doc__)
    started, t0 = datetime.now(UTC).isoformat(timespec="seconds"), time.monotonic()
    code = subprocess.call(argv[2:])
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    part = {"started": started, "wall_s": round(time.monotonic() - t0, 1), "user_s": round(usage.ru_utime, 1),
            "system_s": round(usage.ru_stime, 1), "max_rss_mb": round(usage.ru_maxrss / 1024, 1),
            "returncode": code, "command": argv[2:]}
    with open(argv[0], "a", encoding="utf-8") as out:
        out.write(json.dumps(part) + "\n")
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
