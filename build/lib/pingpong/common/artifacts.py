"""The one way artifacts are written and read (docs/architecture.md, "Artifacts").

Parquet tables carry, in the file's key-value metadata under the key `pingpong`, a JSON record:
schema name and version, stage, params hash, stage code hash, content hashes of the inputs and
the package version. Models are safetensors weights with a JSON sidecar holding the
hyperparameters and the same record. Every write is atomic.
"""

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from pingpong import __version__
from pingpong.common.atomic import atomic_path, write_text_atomic
from pingpong.common.hashing import params_sha256, path_sha256

META_KEY = b"pingpong"


class ArtifactError(RuntimeError):
    """An artifact is missing its provenance, has the wrong schema or a version we cannot read."""


@dataclass(frozen=True)
class Schema:
    """A named, versioned table layout: the columns every file of this schema must hold."""

    name: str
    version: int
    columns: tuple[str, ...] = ()


@dataclass(frozen=True)
class Provenance:
    stage: str
    params_hash: str = ""
    code_hash: str = ""
    inputs: dict[str, str] = field(default_factory=dict)  # path -> sha256
    package_version: str = __version__

    @classmethod
    def of(cls, stage: str, params=None, code_hash: str = "", inputs=()) -> "Provenance":
        """Provenance of a stage run with these params (JSON-able) on these input files/folders."""
        return cls(
            stage=stage,
            params_hash=params_sha256(params if params is not None else {}),
            code_hash=code_hash,
            inputs={str(p): path_sha256(p) for p in inputs},
        )


def _record(schema: Schema, prov: Provenance) -> dict:
    return {"schema": schema.name, "schema_version": schema.version, **asdict(prov)}


def _check_record(record: dict | None, schema: Schema, path) -> dict:
    if record is None:
        raise ArtifactError(f"{path}: no pingpong provenance metadata; expected schema "
                            f"'{schema.name}' v{schema.version}. Was it written by this pipeline?")
    if record.get("schema") != schema.name:
        raise ArtifactError(f"{path}: holds schema '{record.get('schema')}', expected '{schema.name}'")
    version = record.get("schema_version")
    if version != schema.version:
        hint = ("rebuild it with this version of the pipeline" if version < schema.version
                else "it was written by a newer pipeline; upgrade the pingpong package")
        raise ArtifactError(f"{path}: schema '{schema.name}' version {version}, this code reads "
                            f"version {schema.version}: {hint}")
    return record


def _check_columns(columns, schema: Schema, path) -> None:
    missing = [c for c in schema.columns if c not in columns]
    if missing:
        raise ArtifactError(f"{path}: schema '{schema.name}' v{schema.version} needs columns {missing}")


def write_table(df: pd.DataFrame, path, schema: Schema, prov: Provenance) -> None:
    """Write `df` as Parquet with provenance metadata, atomically."""
    _check_columns(df.columns, schema, path)
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[META_KEY] = json.dumps(_record(schema, prov), sort_keys=True).encode()
    table = table.replace_schema_metadata(meta)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def read_metadata(path) -> dict | None:
    """The provenance record of a Parquet artifact (None if it has none)."""
    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(META_KEY)
    return json.loads(raw) if raw else None


def read_table(path, schema: Schema, columns=None) -> pd.DataFrame:
    """Read a Parquet artifact, failing clearly when its schema name or version is not `schema`'s."""
    if not Path(path).is_file():
        raise ArtifactError(f"{path}: missing; expected a '{schema.name}' table")
    _check_record(read_metadata(path), schema, path)
    df = pq.read_table(path, columns=columns).to_pandas()
    _check_columns(df.columns, Schema(schema.name, schema.version, tuple(columns or schema.columns)), path)
    return df


def write_json(obj, path, schema: Schema, prov: Provenance) -> None:
    """Write a JSON artifact with its provenance under the key `_provenance`, atomically."""
    payload = {**obj, "_provenance": _record(schema, prov)}
    write_text_atomic(path, json.dumps(payload, indent=2, sort_keys=True))


def read_json(path, schema: Schema) -> dict:
    try:
        payload = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise ArtifactError(f"{path}: cannot read a '{schema.name}' JSON artifact: {err}") from err
    _check_record(payload.pop("_provenance", None), schema, path)
    return payload


def save_model(tensors: dict, hparams: dict, stem, schema: Schema, prov: Provenance) -> None:
    """Weights to `{stem}.safetensors` (no pickle), hyperparameters + provenance to `{stem}.json`."""
    from safetensors.torch import save_file

    stem = Path(stem)
    with atomic_path(stem.with_suffix(".safetensors")) as tmp:
        save_file({k: v.detach().cpu().contiguous() for k, v in tensors.items()}, str(tmp))
    write_json({"hparams": hparams}, stem.with_suffix(".json"), schema, prov)


def load_model(stem, schema: Schema) -> tuple[dict, dict]:
    """(tensors, hyperparameters) of a saved model; checks the schema version first."""
    from safetensors.torch import load_file

    stem = Path(stem)
    meta = read_json(stem.with_suffix(".json"), schema)
    return load_file(str(stem.with_suffix(".safetensors"))), meta["hparams"]
