"""The ``qpbench`` command: one module per subcommand in this package.

Each module has ``add_parser(subparsers)`` which registers its arguments and
sets ``handler`` to a function ``(args) -> exit code``. Errors in the input
reach the user as one line on stderr and a non-zero exit, never a traceback
(set QPBENCH_DEBUG=1 to see one).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from qpbench import __version__
from qpbench.errors import QpbenchError

COMMANDS = (
    "solvers",
    "import_dump",
    "generate",
    "build_set",
    "solve",
    "simulate",
    "run",
    "report",
    "export",
    "render",
    "scaling",
)

EXIT_INPUT_ERROR = 2
EXIT_INTERNAL_ERROR = 3


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="qpbench",
        description="Formulations and solvers for the impulses of simultaneous 2D ball impacts.",
    )
    parser.add_argument("--version", action="version", version=f"qpbench {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"qpbench.cli.{name}")
        except ModuleNotFoundError as error:
            if error.name != f"qpbench.cli.{name}":
                raise
            continue
        module.add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except QpbenchError as error:
        print(f"qpbench {args.command}: {error}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    except KeyboardInterrupt:
        print(f"qpbench {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as error:  # an internal fault: still one line unless debugging
        if os.environ.get("QPBENCH_DEBUG"):
            raise
        print(f"qpbench {args.command}: internal error: {type(error).__name__}: {error} "
              "(set QPBENCH_DEBUG=1 for a traceback)", file=sys.stderr)
        return EXIT_INTERNAL_ERROR


if __name__ == "__main__":
    sys.exit(main())
