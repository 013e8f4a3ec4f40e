"""The ``qpbench`` command: one module per subcommand in this package.

Each module has ``add_parser(subparsers)`` which registers its arguments and
sets ``handler`` to a function ``(args) -> exit code``. Errors in the input
reach the user as one line on stderr and a non-zero exit, never a traceback
(set QPBENCH_DEBUG=1 to see one). So does an output path that cannot be written: one
that is a device, a FIFO, a socket or a symbolic link (unless QPBENCH_FOLLOW_SYMLINKS is
set) is refused before the command starts, and a read-only or full disk is one line,
``qpbench COMMAND: PATH: cannot write: REASON``, and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from qpbench import SINGLE_THREAD_ENV, __version__
from qpbench.atomic import WRITE_ERRNOS, checked_target, os_error_reason
from qpbench.errors import QpbenchError, one_line
from qpbench.interrupts import EXIT_INTERRUPTED

# Solvers are timed single-threaded (fair, and stable on shared cores) unless the user says
# otherwise; this must happen before numpy loads its BLAS.
for _variable, _value in SINGLE_THREAD_ENV.items():
    os.environ.setdefault(_variable, _value)

# every subcommand's module, with the one line ``qpbench --help`` lists for it: the listing is
# drawn from this table alone, so that it imports no subcommand (and no solver backend)
COMMANDS = {
    "solvers": "list solvers, formulations and availability",
    "import_dump": "import SCISim LCP dumps as problems",
    "import_siconos": "import Siconos' fc2d, gfc2d and LCP text files as problems",
    "import_fclib": "import FCLIB HDF5 files (2D, local or global) as problems",
    "generate": "write seeded problems of a hard-case family",
    "build_set": "write the problems of a set file (families, dumps, captured scenes)",
    "solve": "solve one problem file and judge the answer",
    "simulate": "simulate a SCISim 2D scene",
    "run": "solve problems x solvers x accuracy levels into one Parquet table",
    "report": "write REPORT.md, plots and index.html from a results file",
    "export": "write problems for other QP benchmarks (qpbenchmark Parquet, .mat)",
    "render": "simulate a scene and draw it (png or gif)",
    "scaling": "cost per ball per step of the simulator",
    "speed": "pi-robust against one sparse factorization on box packings",
    "sequence": "replay captured scenes, each solver warm from its own answers",
    "breakdown": "where pi-robust's time goes",
    "head_to_head": "pi-robust against the fastest external pairs, per set, cold",
    "fuzz": "run mutated scenes and problem files through qpbench, judge the errors",
    "sim_precision": "what each level of inner accuracy costs in whole simulations",
}

EXIT_INPUT_ERROR = 2
EXIT_INTERNAL_ERROR = 3
# the argument names (dest) under which the commands take the paths they write: ``-o`` and
# ``simulate --capture``
OUTPUT_ARGUMENTS = ("output", "capture")


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors (a missing argument, a value of the wrong type, an
    unknown option or command) are one line on stderr like every other input error, pointing
    to ``-h`` for the usage instead of printing it. Its subcommands' parsers are of this class
    too (argparse makes them of their parent's class)."""

    def error(self, message: str) -> NoReturn:
        """Exit with one line on stderr naming the fault and pointing to ``-h``.

        argparse calls this for a missing argument, a value of the wrong type, an unknown option or
        command; the usage is not printed.

        Parameters
        ----------
        message : str
            argparse's description of the fault.

        Returns
        -------
        NoReturn
            Never returns: exits with status 2 (EXIT_INPUT_ERROR).
        """
        self.exit(EXIT_INPUT_ERROR, f"{self.prog}: {message} (usage: {self.prog} -h)\n")


def _module_name(command: str) -> str:
    return command.replace("-", "_")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """Build the ``qpbench`` argument parser.

    With ``only``, that subcommand's module is imported and registers its arguments (the solver
    backends, pandas and matplotlib load only for the commands that use them); without, every
    subcommand is listed by its line in COMMANDS and none is imported, so that ``qpbench --help``
    and a mistyped command answer at once.

    Parameters
    ----------
    only : str or None, optional
        The module name (a key of COMMANDS, ``_`` not ``-``) of the one subcommand to register
        in full; None (default) lists every subcommand by name and help line only.

    Returns
    -------
    argparse.ArgumentParser
        A OneLineParser whose subcommands are required.
    """
    parser = OneLineParser(
        prog="qpbench",
        description="Formulations and solvers for the impulses of simultaneous 2D ball impacts.",
    )
    parser.add_argument("--version", action="version", version=f"qpbench {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    if only is None:
        for name, summary in COMMANDS.items():
            subparsers.add_parser(name.replace("_", "-"), help=summary)
        return parser
    importlib.import_module(f"qpbench.cli.{only}").add_parser(subparsers)
    return parser


def _chosen_command(argv: Sequence[str]) -> str | None:
    """The subcommand's module name when argv names a known one first, else None."""
    for argument in argv:
        if argument.startswith("-"):
            return None
        return _module_name(argument) if _module_name(argument) in COMMANDS else None
    return None


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before the command does any work, a path to write that cannot be a file or folder.

    OutputError when a path the command is to write (OUTPUT_ARGUMENTS) is a device, a FIFO, a
    socket, or a symbolic link to anything but a folder that is not followed: never a file or a
    folder to write. Whether the command needs a file or a folder there is the command's own
    check.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed arguments; those named in OUTPUT_ARGUMENTS that hold a path are checked.

    Raises
    ------
    OutputError
        When one of those paths is not a regular file or folder to write
        (:func:`qpbench.atomic.checked_target`).
    """
    for name in OUTPUT_ARGUMENTS:
        value = getattr(args, name, None)
        if isinstance(value, str | os.PathLike):
            checked_target(value, accept_folder=True)


def os_error_line(error: OSError) -> str | None:
    """Describe an OSError that names its file, or that only a write gives, in one line.

    A read-only or full disk gives ``PATH: cannot write: REASON``; other errors that name a
    file, such as a permission refused, give ``PATH: REASON``.

    Parameters
    ----------
    error : OSError
        The error a command raised.

    Returns
    -------
    str or None
        The line, without the ``qpbench COMMAND:`` prefix; None for any other OSError, which
        is an internal fault.
    """
    filename = error.filename
    where = f"{os.fsdecode(filename)}: " if isinstance(filename, str | bytes | os.PathLike) else ""
    if not where and error.errno not in WRITE_ERRNOS:
        return None
    what = "cannot write: " if error.errno in WRITE_ERRNOS else ""
    return f"{where}{what}{os_error_reason(error)}"


def interrupted_by(error: BaseException) -> bool:
    """Whether ``error`` was raised while a KeyboardInterrupt was being handled.

    Such an error is a library's clean-up that fails once Ctrl-C cut its work short: then the
    interrupt is what happened. The chain of ``__context__`` is followed, each exception once.

    Parameters
    ----------
    error : BaseException
        The error a command raised.

    Returns
    -------
    bool
        True when a KeyboardInterrupt is in the chain of contexts of ``error``.
    """
    seen: set[int] = set()
    cause: BaseException | None = error
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__context__
    return False


def _internal_error(command: str, error: Exception) -> int:
    """An internal fault: one line and exit 3, unless QPBENCH_DEBUG asks for the traceback;
    an error raised while handling Ctrl-C is the interrupt (exit 130)."""
    if interrupted_by(error):
        print(f"qpbench {command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    if os.environ.get("QPBENCH_DEBUG"):
        raise error
    print(f"qpbench {command}: internal error: {type(error).__name__}: "
          f"{one_line(str(error))} (set QPBENCH_DEBUG=1 for a traceback)", file=sys.stderr)
    return EXIT_INTERNAL_ERROR


def main(argv: Sequence[str] | None = None) -> int:
    """Run one ``qpbench`` command and return its exit status.

    The subcommand named first in ``argv`` is imported alone (:func:`build_parser`), the paths
    it writes are checked (:func:`check_outputs`) and its handler run. Faults become one line on
    stderr: a QpbenchError or an OSError naming its file exits 2, Ctrl-C 130, a closed stdout
    pipe 141, any other exception 3 (or its traceback when QPBENCH_DEBUG is set).

    Parameters
    ----------
    argv : Sequence of str or None, optional
        The arguments after ``qpbench``; None (default) reads ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status: the handler's (0 when it returns None), or that of the fault above.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(only=_chosen_command(argv))
    args = parser.parse_args(argv)
    try:
        check_outputs(args)
        return int(args.handler(args) or 0)
    except QpbenchError as error:
        print(f"qpbench {args.command}: {one_line(str(error))}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    except BrokenPipeError:  # the reader went away (``| head``): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except KeyboardInterrupt:
        print(f"qpbench {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as error:  # a file the command could not read or write
        line = os_error_line(error)
        if line is None:
            return _internal_error(args.command, error)
        print(f"qpbench {args.command}: {one_line(line)}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    except Exception as error:  # an internal fault: still one line unless debugging
        return _internal_error(args.command, error)


if __name__ == "__main__":
    sys.exit(main())
