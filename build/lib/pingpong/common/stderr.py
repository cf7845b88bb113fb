"""File descriptor 2 pointed elsewhere for a block: what C libraries print (libjpeg's "Corrupt JPEG
data", FFmpeg's decoder messages) goes there, not only what Python writes to sys.stderr."""

import contextlib
import os
import sys


def _flush_python_stderr() -> None:
    """Python's pending stderr text out first, so that it lands where it was written for."""
    for stream in (sys.stderr, sys.__stderr__):
        if stream is not None:
            stream.flush()


@contextlib.contextmanager
def fd2_onto(target_fd: int):
    """Point fd 2 at target_fd for the block, restoring it after."""
    _flush_python_stderr()
    saved = os.dup(2)
    os.dup2(target_fd, 2)
    try:
        yield
    finally:
        _flush_python_stderr()
        os.dup2(saved, 2)
        os.close(saved)
