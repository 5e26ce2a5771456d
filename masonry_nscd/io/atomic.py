"""Atomic writes: a file on disk is always either its previous complete version or the new one.

``atomic_write(path, write)`` has ``write`` fill a temporary file ``.<name>.<random>.tmp`` in the
same folder, flushes it to disk (fsync) and renames it onto ``path`` (``os.replace``, atomic on
POSIX). A failing or interrupted write leaves the previous version untouched and removes the
temporary file; only a process killed during the write (SIGKILL, power loss) can leave a stray
``.*.tmp`` file, never a truncated target. Files get the usual permissions (0666 minus the umask
read when this module is imported), not ``mkstemp``'s 0600.

``writing(path)`` turns an ``OSError`` raised inside its block into a
:class:`~masonry_nscd.errors.RunOutputError` naming the file (disk full, permissions).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

from masonry_nscd.errors import RunOutputError

PathLike = str | os.PathLike[str]

# Read once: os.umask can only be read by setting it, which is not thread-safe.
_UMASK = os.umask(0)
os.umask(_UMASK)


def fsync_file(path: PathLike) -> None:
    """Flush a closed file's contents to disk."""
    fd = os.open(path, os.O_RDWR)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_write(path: PathLike, write: Callable[[str], None]) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it onto ``path``.

    The temporary file is fsynced before ``os.replace`` so that the target is always either
    the previous complete file or the new complete one. On any exception (including
    KeyboardInterrupt) the temporary file is removed and the exception re-raised.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        os.chmod(tmp, 0o666 & ~_UMASK)
        write(tmp)
        fsync_file(tmp)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def writing(path: PathLike) -> Iterator[None]:
    """Turn an OSError raised inside the block into a RunOutputError naming ``path``."""
    try:
        yield
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise RunOutputError(f"cannot write {path}: {reason}") from exc
