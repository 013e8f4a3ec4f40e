"""Ctrl-C within a second, even while compiled code runs for long.

Python runs its SIGINT handler (which raises KeyboardInterrupt) only between bytecodes, so a
long numpy, scipy or solver call would delay an interrupt until it returns. The C-level
handler, however, writes the signal's number to the wakeup file descriptor
(``signal.set_wakeup_fd``) at once. :func:`interrupt_watchdog` points that descriptor at a
socket read by a helper thread: on SIGINT the main thread still gets its KeyboardInterrupt as
usual (the command then ends the ordinary way, exit 130, atomic writes undone); if it has not
left the watched block ``grace_s`` seconds later, the helper removes the temporary files it
knows of (every ``.tmp-*`` entry made since the block began in the folders registered with
:meth:`Watchdog.sweep`, and the paths registered with :meth:`Watchdog.remove_on_exit`),
prints ``qpbench COMMAND: interrupted`` and ends the process with ``os._exit(130)``.

The helper needs the interpreter lock to act; numpy's and scipy's long loops and the solver
libraries release it, but a compiled kernel that keeps it delays the exit until it returns.
Atomic writes (:mod:`qpbench.atomic`) rename a complete temporary file over their target, so
an exit at any moment leaves each target either as it was or whole.

Beside the watchdog: :func:`terminate_as_interrupt` takes SIGTERM as Ctrl-C within a block, and
:func:`interrupts_held` holds both off within a block that must not be cut short (a table
compacted, a library writing a file whose state an exception in mid-write would break), raising
the interrupt when the block ends.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from types import FrameType

from qpbench.atomic import TEMPORARY_PREFIX

EXIT_INTERRUPTED = 130
GRACE_S = 0.8  # the main thread's time to end by itself after SIGINT


class Watchdog:
    """What the helper thread of :func:`interrupt_watchdog` removes before it ends the
    process."""

    def __init__(self, command: str) -> None:
        self.command = command
        self.started = time.time()
        self._folders: list[Path] = []
        self._paths: list[Path] = []
        self._lock = threading.Lock()

    def sweep(self, folder: str | os.PathLike[str]) -> None:
        """Registers ``folder`` for the removal of its temporary files on a forced exit.

        Only its ``.tmp-*`` entries made since the watch began are removed.

        Parameters
        ----------
        folder : str or os.PathLike
            A folder where atomic writes put their temporary files.
        """
        with self._lock:
            self._folders.append(Path(folder))

    def remove_on_exit(self, path: str | os.PathLike[str]) -> None:
        """Registers a temporary file or folder, removed on a forced exit.

        Parameters
        ----------
        path : str or os.PathLike
            The file or folder to remove (a folder with all it holds).
        """
        with self._lock:
            self._paths.append(Path(path))

    def forget(self, path: str | os.PathLike[str]) -> None:
        """Unregisters a path of :meth:`remove_on_exit` (it is gone or kept).

        Parameters
        ----------
        path : str or os.PathLike
            The path given to :meth:`remove_on_exit`.
        """
        with self._lock:
            self._paths = [known for known in self._paths if known != Path(path)]

    def remove_temporaries(self) -> None:
        """Removes the registered paths and the recent ``.tmp-*`` entries of the registered
        folders; errors (an entry already gone) are ignored."""
        with self._lock:
            folders, paths = list(self._folders), list(self._paths)
        for folder in folders:
            try:
                entries = list(folder.glob(f"{TEMPORARY_PREFIX}*"))
            except OSError:
                continue
            for entry in entries:
                try:
                    if entry.lstat().st_mtime >= self.started - 1.0:
                        paths.append(entry)
                except OSError:
                    continue
        for path in paths:
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            else:
                with suppress(OSError):
                    path.unlink()

    def force_exit(self) -> None:
        """Removes the temporaries, says ``interrupted`` on stderr and ends the process with
        exit status 130, whatever the main thread is doing."""
        self.remove_temporaries()
        try:
            os.write(2, f"qpbench {self.command}: interrupted\n".encode())
        finally:
            os._exit(EXIT_INTERRUPTED)


def _watch(reader: socket.socket, done: threading.Event, watchdog: Watchdog,
           grace_s: float) -> None:
    """The helper thread: waits for SIGINT's byte on ``reader``; then gives the main thread
    ``grace_s`` seconds to set ``done`` before :meth:`Watchdog.force_exit`."""
    while not done.is_set():
        try:
            received = reader.recv(64)
        except OSError:
            return
        if not received:  # the writer was closed: the watch is over
            return
        if signal.SIGINT in received and not done.wait(grace_s):
            watchdog.force_exit()


@contextmanager
def interrupt_watchdog(command: str, grace_s: float = GRACE_S) -> Iterator[Watchdog]:
    """Watches the block for SIGINT (module docstring).

    Yields the :class:`Watchdog` to register temporary files with. Outside the main thread
    (where no wakeup descriptor can be set) the block runs unwatched.

    Parameters
    ----------
    command : str
        The command's name, said in ``qpbench COMMAND: interrupted``.
    grace_s : float, optional
        Seconds the main thread has after SIGINT to leave the block before the process is
        ended; :data:`GRACE_S` by default.

    Yields
    ------
    Watchdog
        The registry of temporary files to remove on a forced exit.
    """
    watchdog = Watchdog(command)
    if not _in_main_thread():
        yield watchdog
        return
    reader, writer = socket.socketpair()
    writer.setblocking(False)
    done = threading.Event()
    previous = signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)
    helper = threading.Thread(target=_watch, args=(reader, done, watchdog, grace_s),
                              name="qpbench-interrupt-watchdog", daemon=True)
    helper.start()
    try:
        yield watchdog
    finally:
        done.set()
        signal.set_wakeup_fd(previous)
        writer.close()
        helper.join(timeout=1.0)
        reader.close()


INTERRUPTS = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """SIGTERM, taken as an interrupt: the run ends as after Ctrl-C."""


def _in_main_thread() -> bool:
    """Whether this is the main thread, the only one that can take signals."""
    return threading.current_thread() is threading.main_thread()


def _raise_terminated(number: int, frame: FrameType | None) -> None:
    raise Terminated(f"signal {signal.Signals(number).name}")


@contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """Take SIGTERM as Ctrl-C within the block.

    Within the block, SIGTERM raises :class:`Terminated` (a KeyboardInterrupt) as Ctrl-C
    does, so that a run stopped by ``kill`` keeps its rows too; the previous handler is put
    back after. Only the main thread can take signals: elsewhere this does nothing.

    Yields
    ------
    None
        Control to the block.
    """
    if not _in_main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Hold off SIGINT and SIGTERM within the block.

    Within the block, SIGINT and SIGTERM are noted instead of raised; one that arrived is
    raised as KeyboardInterrupt when the block ends (so the block, writing a table or a file,
    is never cut short). Does nothing outside the main thread.

    Yields
    ------
    None
        Control to the block.
    """
    if not _in_main_thread():
        yield
        return
    arrived: list[int] = []
    previous = {number: signal.signal(number, lambda number, frame: arrived.append(number))
                for number in INTERRUPTS}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
    if arrived:
        raise (Terminated if arrived[0] == signal.SIGTERM else KeyboardInterrupt)()
