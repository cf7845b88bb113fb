"""An artifact's content without its provenance, to compare two runs made by different code.

Two clean runs of one commit give the same bytes (tests/test_reproducible.py). A change that only moves
code changes every code hash, and with it each artifact's provenance record and the input hashes in the
records downstream; what must not change is the content: a Parquet table's schema and data, a JSON
artifact less `_provenance`, an MCAP file's schemas, channels, messages and metadata less the `pingpong`
record. Every other file is compared byte for byte.

    python -m pingpong.common.content RUN_A RUN_B   # lists the artifacts whose content differs
"""

import hashlib
import io
import json
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
from mcap.reader import make_reader

from pingpong.common.artifacts import META_KEY

DATA_FOLDERS = ("raw", "interim", "processed", "reports")


def _parquet_content(path: Path) -> bytes:
    table = pq.read_table(path)
    metadata = {k: v for k, v in (table.schema.metadata or {}).items() if k != META_KEY}
    sink = io.BytesIO()
    with pa.ipc.new_stream(sink, table.schema.with_metadata(metadata)) as writer:
        writer.write_table(table)
    return sink.getvalue()


def _json_content(path: Path) -> bytes:
    payload = json.loads(path.read_text())
    if isinstance(payload, dict):
        payload.pop("_provenance", None)
    return json.dumps(payload, sort_keys=True).encode()


def _mcap_content(path: Path) -> bytes:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            for part in (schema.name if schema else "", channel.topic, str(message.log_time)):
                h.update(part.encode())
            h.update(message.data)
        for record in reader.iter_metadata():
            if record.name != META_KEY.decode():
                h.update(json.dumps([record.name, record.metadata], sort_keys=True).encode())
    return h.digest()


READERS = {".parquet": _parquet_content, ".json": _json_content, ".mcap": _mcap_content}


def content_sha256(path) -> str:
    """SHA-256 of an artifact's content less its provenance (module doc)."""
    path = Path(path)
    reader = READERS.get(path.suffix)
    return hashlib.sha256(reader(path) if reader else path.read_bytes()).hexdigest()


def run_contents(root) -> dict[str, str]:
    """content_sha256 of every artifact under a run's data folders, by path relative to the run's root."""
    root = Path(root)
    return {str(p.relative_to(root)): content_sha256(p)
            for folder in DATA_FOLDERS for p in sorted((root / folder).rglob("*"))
            if p.is_file() and p.name != ".gitkeep"}


def compare_runs(a, b) -> dict[str, list[str]]:
    """Artifacts only in a, only in b, and in both with different content."""
    ca, cb = run_contents(a), run_contents(b)
    return {"only_in_a": sorted(set(ca) - set(cb)), "only_in_b": sorted(set(cb) - set(ca)),
            "differ": sorted(p for p in ca.keys() & cb.keys() if ca[p] != cb[p])}


if __name__ == "__main__":
    result = compare_runs(*sys.argv[1:3])
    n = len(run_contents(sys.argv[1]))
    for kind, paths in result.items():
        print(f"{kind}: {len(paths)}", *paths[:50], sep="\n  ")
    print(f"{n} artifacts compared")
    sys.exit(1 if any(result.values()) else 0)
