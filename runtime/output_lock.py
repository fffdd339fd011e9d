"""One batch at a time per results file: ``OUT.lock`` held with a POSIX record lock.

The lock is the kernel's (``fcntl.lockf``), so it is released when its holder exits, normally or
not (a kill, a crash, a lost machine on NFS once the server notices); the file only tells a
refused run who holds it. A lock file left behind by a dead holder is therefore no lock at all:
the next run takes it over.
"""

from __future__ import annotations

import fcntl
import os
import socket
from contextlib import contextmanager
from pathlib import Path


class OutputLocked(RuntimeError):
    """Another process is writing the same results file."""


def lock_path(out: Path) -> Path:
    return out.with_name(out.name + ".lock")


@contextmanager
def output_lock(out: Path):
    """Hold ``OUT.lock`` while the body runs; OutputLocked names the holder if another process
    holds it. The file is removed on a normal exit and left (unlocked, harmless) after a crash."""
    path = lock_path(out)
    handle = _locked(path, out)
    try:
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()} on {socket.gethostname()}\n")
        handle.flush()
        yield
    finally:
        path.unlink(missing_ok=True)  # before the release: no one locks a file about to vanish
        handle.close()


def _locked(path: Path, out: Path):
    """The lock file, opened and locked. A file its holder removed between our open and our lock
    is not the lock any more (a newer run may have made another): open again."""
    while True:
        handle = open(path, "a+")  # never truncates: the holder's record stays readable
        try:
            fcntl.lockf(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            handle.close()
            raise OutputLocked(
                f"{out} is being written by {holder} (lock {path}); wait for that batch to end "
                "or write to another --out"
            ) from None
        try:
            if os.stat(path).st_ino == os.fstat(handle.fileno()).st_ino:
                return handle
        except FileNotFoundError:
            pass
        handle.close()
