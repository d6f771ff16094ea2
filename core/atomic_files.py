"""Files written whole or not at all: a temporary file beside the output, renamed into place
when complete, so that a reader (Blender playing a cache, a farm job merging chunks) or a failed
write never sees half a file; temporary files of writers killed before they could remove them are
deleted by the next writer of the same name. Used by :mod:`core.point_cache` for caches, stamps
and merged chunks.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

try:  # POSIX: a temporary file is locked while it is written (not on Windows, which keeps it open instead)
    import fcntl
except ImportError:
    fcntl = None

#: Ends the name of the temporary file an output is written to, ``.<output name>.<random>.part``
#: beside it (:func:`write_atomically`).
PART_SUFFIX = ".part"


def open_part(path: Path) -> tuple[int, str]:
    """A new temporary file for ``path``, ``.<name>.<random>.part`` beside it, opened for writing
    and, on POSIX, locked (``flock``) for as long as this process lives: the system drops the lock
    of a process that dies, which is how :func:`_remove_abandoned_parts` tells a file a live writer
    holds from one left by a writer killed with SIGKILL."""
    while True:
        handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=PART_SUFFIX, dir=path.parent)
        if fcntl is None:
            return handle, temporary
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)  # waits for a cleaner that took it before this process
        except OSError:  # a file system without locks: written unlocked (and never taken for abandoned)
            return handle, temporary
        if os.fstat(handle).st_nlink:
            return handle, temporary
        os.close(handle)  # a cleaner took it for abandoned between its creation and the lock: another


def _remove_abandoned_parts(path: Path) -> None:
    """Delete the temporary files of ``path`` (:func:`open_part`) no live writer holds: those of a
    writer killed before it could remove its own (SIGKILL, a node lost), as large as the part it had
    written. A file another writer is writing stays (locked on POSIX; open, so not removable, on
    Windows), and so does every file on a file system without locks."""
    own = re.compile(re.escape(f".{path.name}.") + r"[^.]+" + re.escape(PART_SUFFIX))
    try:
        names = [name for name in os.listdir(path.parent) if own.fullmatch(name)]
    except OSError:
        return
    for name in names:
        part = path.parent / name
        try:
            if fcntl is None:
                os.unlink(part)
                continue
            handle = os.open(part, os.O_RDONLY)
        except OSError:  # gone meanwhile, or held open by its writer (Windows)
            continue
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            os.unlink(part)
        except OSError:  # locked: its writer is alive
            pass
        finally:
            os.close(handle)


def write_atomically(path: Path, chunks, *, exclusive: bool = False) -> None:
    """Write ``chunks`` (bytes-like) to a temporary file beside ``path`` and rename it into place,
    so that a reader (or a failed write) never sees half a file. Temporary files of ``path`` that
    writers killed before they could remove them left are deleted first.

    ``exclusive``: never replace an existing ``path``: the complete file is linked to the name,
    which raises :class:`FileExistsError` if another process took it meanwhile (checking first and
    then renaming would let two processes writing one new name keep only the later file)."""
    given = path
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        _remove_abandoned_parts(path)
        handle, temporary = open_part(path)
    except OSError as error:  # said of the user's path, not of the temporary file
        raise OSError(error.errno, error.strerror, str(given)) from None
    try:
        os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes it private; a cache is shared like any file
        publish = _link_new if exclusive else os.replace
        with os.fdopen(handle, "wb") as stream:
            for chunk in chunks:
                stream.write(chunk)
            stream.flush()
            if fcntl is not None:  # named while still locked: never taken for abandoned before
                publish(temporary, path)
        if fcntl is None:  # Windows renames closed files only
            publish(temporary, path)
    except BaseException as error:
        if os.path.lexists(temporary):
            os.unlink(temporary)
        if isinstance(error, OSError) and not isinstance(error, FileExistsError):
            raise OSError(error.errno, error.strerror, str(given)) from None
        raise


def _link_new(temporary: str, path: Path) -> None:
    """Give the complete file ``temporary`` the name ``path`` unless a file has it (then
    :class:`FileExistsError`), and remove the temporary name. A file system without hard links
    (FAT, some network shares) gets a rename after a check instead."""
    try:
        os.link(temporary, path)
    except FileExistsError:
        raise
    except OSError:
        if os.path.lexists(path):
            raise FileExistsError(f"'{path}' exists") from None
        os.replace(temporary, path)
        return
    os.unlink(temporary)


def _umask() -> int:
    """The process's file mode mask, read from ``/proc/self/status`` where the system gives it
    (Linux 4.7+). Python reads the mask only by setting it (``os.umask``), which leaves it 0 for a
    moment in which a file another thread of the process creates (Blender's, an add-on's) would be
    world-writable; that is done only where the system does not give the mask."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0)  # elsewhere (Windows, macOS) the mask is read by setting it
    os.umask(mask)
    return mask
