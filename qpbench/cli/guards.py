"""The guards of the commands that build things (``simulate``, ``render``, ``generate``,
``build-set``) or call external solvers in their own process (``head-to-head``,
``sequence``): their ``--memory-limit`` and ``--progress`` options, and :func:`guarded`,
which applies the memory cap, turns running out of memory into one line (exit 2) and
watches for Ctrl-C (exit 130 within about a second)."""

from __future__ import annotations

import argparse
import os
import resource
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager

from qpbench.bench.settings import check_at_least
from qpbench.interrupts import Watchdog, interrupt_watchdog
from qpbench.memory import (
    DEFAULT_FRACTION,
    LIMIT_OPTION,
    apply_limit,
    default_limit_mb,
    out_of_memory_as_error,
)


def add_memory_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--memory-limit MB``: the address-space cap.

    The default is a fraction of the memory available; 0 means no cap.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser; the value is stored as ``memory_limit`` (None: the default).
    """
    parser.add_argument(
        LIMIT_OPTION, type=int, default=None, metavar="MB", dest="memory_limit",
        help=f"cap on the address space in MiB (default: {DEFAULT_FRACTION:.0%}% of the "
             "memory available at the start; 0: none); a request that needs more is "
             "refused in one line")


def memory_arguments(args: argparse.Namespace) -> list[str]:
    """``--memory-limit MB`` as given on the command line, for a child rerun; none when the
    default stands.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options holding ``memory_limit`` (see :func:`add_memory_option`).

    Returns
    -------
    list of str
        The option and its value, or an empty list.
    """
    return [] if args.memory_limit is None else [LIMIT_OPTION, str(args.memory_limit)]


def add_progress_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--progress/--no-progress``: a progress bar and a closing summary on stderr.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser; the value is stored as ``progress`` (None: when stderr is a
        terminal).
    """
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="progress and a closing summary on stderr (default: when "
                             "stderr is a terminal)")


def progress_wanted(args: argparse.Namespace) -> bool:
    """Whether to show progress: ``--progress``/``--no-progress`` when given, else a terminal.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options holding ``progress`` (see :func:`add_progress_option`).

    Returns
    -------
    bool
        The option's value when given, else whether stderr is a terminal.
    """
    if args.progress is not None:
        return bool(args.progress)
    return sys.stderr.isatty()


@contextmanager
def guarded(args: argparse.Namespace, command: str, what: str,
            outputs: Iterable[str | os.PathLike[str]] = ()) -> Iterator[Watchdog]:
    """Run the block of ``command`` under the memory cap, with Ctrl-C watched.

    The cap of ``args.memory_limit`` is restored after; a MemoryError becomes one line
    (``out of memory while WHAT``, exit 2 through :class:`~qpbench.errors.QpbenchError`) and
    SIGINT is watched (:func:`~qpbench.interrupts.interrupt_watchdog`: the ``.tmp-*`` files of
    the folders ``outputs`` are removed on a forced exit).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options holding ``memory_limit`` in MiB (None: the default fraction of the
        memory available; 0: no cap).
    command : str
        The command's name, for the interrupt line.
    what : str
        What the block does, for the out-of-memory line (``generating 'box' problems``).
    outputs : iterable of str or os.PathLike, optional
        Folders the block writes, swept of temporary files on a forced exit; none by default.

    Yields
    ------
    Watchdog
        The interrupt watchdog of the block.

    Raises
    ------
    QpbenchError
        When the memory limit is negative, or the block runs out of memory.
    """
    limit_mb = default_limit_mb() if args.memory_limit is None else args.memory_limit
    check_at_least(limit_mb, 0, LIMIT_OPTION)
    previous = resource.getrlimit(resource.RLIMIT_AS)
    # the watchdog's thread starts before the cap: a thread's stack is address space too
    with interrupt_watchdog(command) as watchdog:
        apply_limit(limit_mb)
        try:
            with out_of_memory_as_error(what):
                for folder in outputs:
                    watchdog.sweep(folder)
                yield watchdog
        finally:
            apply_limit(0)
            resource.setrlimit(resource.RLIMIT_AS, previous)

