"""Atomic file output: write a temporary file in the target's folder, then rename it over the
target, so that no reader and no interrupted run ever sees half a file.

Only a regular file (or nothing) is ever replaced. A target that is a folder, a device, a FIFO
or a socket is refused, and so is a symbolic link unless the environment variable
``QPBENCH_FOLLOW_SYMLINKS`` is set (to anything but ``0``): then the link's final target is
replaced (atomically, beside it) and the link is kept. Every refusal, and every failure to
write (a read-only or full disk), is an :class:`~qpbench.errors.OutputError`: one line naming
the path, with no temporary file left behind.
"""

from __future__ import annotations

import errno
import os
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from qpbench.errors import OutputError

FOLLOW_SYMLINKS_ENV = "QPBENCH_FOLLOW_SYMLINKS"
TEMPORARY_PREFIX = ".tmp-"  # a temporary file is .tmp-<16 random hex digits>-<target's name>
# errors that only a write can give: the reason alone says what went wrong
WRITE_ERRNOS = frozenset({errno.EROFS, errno.ENOSPC, errno.EDQUOT, errno.EFBIG})
_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symbolic link"))


def following_symlinks() -> bool:
    """Whether ``QPBENCH_FOLLOW_SYMLINKS`` asks to write through symbolic links.

    Returns
    -------
    bool
        True when the variable is set to anything but an empty string or ``0``.
    """
    return os.environ.get(FOLLOW_SYMLINKS_ENV, "0").strip() not in ("", "0")


def _kind(mode: int) -> str:
    """What a file of st_mode ``mode`` is, in words."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def os_error_reason(error: OSError) -> str:
    """The reason an OSError gives, on one line: its strerror, else its first line of text.

    Parameters
    ----------
    error : OSError
        The error to describe.

    Returns
    -------
    str
        The first line of its reason, or the error's class name when it has no text.
    """
    lines = (error.strerror or str(error)).strip().splitlines()
    return lines[0] if lines else type(error).__name__


def cannot_write(path: str | os.PathLike[str], error: OSError) -> OutputError:
    """The one-line error for a write to ``path`` that failed with ``error``.

    Parameters
    ----------
    path : str or os.PathLike
        The path that could not be written.
    error : OSError
        The failure; its reason (:func:`os_error_reason`) ends the message.

    Returns
    -------
    OutputError
        ``PATH: cannot write: REASON``, to be raised by the caller.
    """
    return OutputError(path, f"cannot write: {os_error_reason(error)}")


def _status(path: Path) -> os.stat_result | None:
    """lstat of ``path``; None when nothing is there; OutputError when it cannot be looked at."""
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None
    except OSError as error:
        raise cannot_write(path, error) from error


def checked_target(path: str | os.PathLike[str], accept_folder: bool = False) -> Path:
    """The file that a write to ``path`` replaces.

    That is ``path`` itself, or, when symbolic links are followed, the final target of the
    link at ``path``.

    Nothing there, or a regular file, is accepted; with ``accept_folder`` a folder, or a
    symbolic link to one, is accepted too (an output folder). Anything else is an
    :class:`OutputError` naming ``path`` and what it is: a device, a FIFO, a socket, a folder,
    or a symbolic link (unless followed).

    Parameters
    ----------
    path : str or os.PathLike
        The path a write is asked for.
    accept_folder : bool, optional
        Accept a folder (or a link to one) as well; False by default.

    Returns
    -------
    Path
        ``path``, or the resolved target of the link at ``path`` when links are followed.

    Raises
    ------
    OutputError
        When ``path`` (or its link's target) is neither nothing nor an acceptable file, or
        cannot be looked at.
    """
    path = Path(path)
    status = _status(path)
    if status is None or stat.S_ISREG(status.st_mode):
        return path
    if stat.S_ISDIR(status.st_mode) and accept_folder:
        return path
    if not stat.S_ISLNK(status.st_mode):
        raise OutputError(path, f"is {_kind(status.st_mode)}, not a file qpbench can write")
    if accept_folder and path.is_dir():
        return path
    if not following_symlinks():
        raise OutputError(path, f"is a symbolic link (to {os.readlink(path)}); qpbench does "
                          f"not replace it: remove it, or set {FOLLOW_SYMLINKS_ENV}=1 to write "
                          "to its target")
    target = Path(os.path.realpath(path))
    status = _status(target)
    if status is None or stat.S_ISREG(status.st_mode):
        return target
    if stat.S_ISLNK(status.st_mode):
        raise OutputError(path, "is a symbolic link that never reaches a file (a loop)")
    raise OutputError(path, f"is a symbolic link to {target}, which is "
                      f"{_kind(status.st_mode)}, not a file qpbench can write")


def _new_file_mode() -> int:
    """0o666 minus the process umask: the mode ``open`` would give a new file."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def sync_folder(folder: Path) -> None:
    """Makes a rename in ``folder`` durable (fsync of the directory, where supported).

    Parameters
    ----------
    folder : Path
        The directory to sync; an OSError on opening or syncing it is ignored.
    """
    try:
        descriptor = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)


def _temporary_beside(target: Path) -> Path:
    """A name for a temporary file beside ``target``: :data:`TEMPORARY_PREFIX`, 64 random
    bits in hex, then the target's name."""
    return target.with_name(f"{TEMPORARY_PREFIX}{secrets.token_hex(8)}-{target.name}")


def _made_new(path: Path) -> bool:
    """Makes ``path`` as a new empty file, readable and writable by its owner alone; False
    when a file of that name exists already (it is left as it is)."""
    try:
        descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        return False
    os.close(descriptor)
    return True


@contextmanager
def atomic_path(path: str | os.PathLike[str], durable: bool = False) -> Iterator[Path]:
    """Yields a temporary path ``.tmp-<random>-<name>`` beside the file that ``path`` names.

    The target is :func:`checked_target`: an OutputError before anything is written when that
    is not a regular file or nothing. When the block ends normally the file is given a new
    file's mode and renamed over it; on any error it is removed. An OSError while writing (a
    read-only or full disk) becomes an OutputError naming ``path``. ``durable``: the file is
    synced before the rename and the folder after it, so the new file survives a power cut,
    not only a killed process.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; missing parent folders are created.
    durable : bool, optional
        Sync the file before the rename and its folder after it; False by default.

    Yields
    ------
    Path
        The temporary file for the block to write.

    Raises
    ------
    OutputError
        When the target cannot be replaced or a write, chmod or rename fails.
    """
    target = checked_target(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise cannot_write(path, error) from error
    # named before it is made, so that Ctrl-C at any moment after it exists finds it to remove
    temporary = _temporary_beside(target)
    try:
        try:
            while not _made_new(temporary):
                temporary = _temporary_beside(target)
            yield temporary
            os.chmod(temporary, _new_file_mode())
            if durable:
                with open(temporary, "rb") as stream:
                    os.fsync(stream.fileno())
            os.replace(temporary, target)
        except OSError as error:
            raise cannot_write(path, error) from error
    except BaseException:
        with suppress(OSError):  # a read-only folder: none was made; the first error is told
            temporary.unlink(missing_ok=True)
        raise
    if durable:
        sync_folder(target.parent)
