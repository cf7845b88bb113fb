"""Checks the readers share where a parsing library fails without naming the file, or lets through what
the pipeline cannot hold. Each takes the reader's own error type, so a refusal is that reader's error
naming the file and the record."""

import os
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

INT64_MIN, INT64_MAX = int(np.iinfo(np.int64).min), int(np.iinfo(np.int64).max)
# what an int64 of ns holds: numpy raises an OverflowError naming nothing beyond it, or wraps round silently
INT64_NS = f"int64 ns ({INT64_MIN} to {INT64_MAX}, 292 years either side of 1970)"


def parse_text(path: str | os.PathLike, parse: Callable[[str], object], error: type[Exception], what: str,
               expected: str = ""):
    """parse(the file's UTF-8 text) (json.loads, tomllib.loads), its failures as `error` naming the file:
    malformed text, bytes that are not UTF-8, and a document nested deeper than the parser recurses (a
    RecursionError, where json and tomllib give up)."""
    try:
        return parse(Path(path).read_text(encoding="utf-8"))
    except (ValueError, RecursionError) as err:  # JSONDecodeError, TOMLDecodeError, UnicodeDecodeError
        reason = ("nested deeper than the parser recurses" if isinstance(err, RecursionError)
                  else f"{type(err).__name__}: {err}")
        raise error(f"{path}: not {what} ({reason}){'; expected ' + expected if expected else ''}") from None


def check_int64(value: int | float, error: type[Exception], where: str, expected: str = INT64_NS):
    """value, or `error` naming where it was read (where + the value) when it does not fit int64."""
    if not INT64_MIN <= value <= INT64_MAX:  # exact for floats too (inf and NaN fail)
        raise error(f"{where} {value} does not fit int64; expected {expected}")
    return value


def check_unique(names: Iterable[str], places: Iterable[str], error: type[Exception], where: str,
                 things: str) -> None:
    """`error` naming where, the first name given twice and both its places (sections, IDs, channels)."""
    seen: dict[str, str] = {}
    for name, place in zip(names, places, strict=True):
        if name in seen:
            raise error(f"{where}: two {things} named {name!r} ({seen[name]} and {place}); expected each "
                        "name once")
        seen[name] = place
