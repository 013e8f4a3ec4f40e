"""``qpbench --help`` lists every subcommand from the command table without importing any of
them, and each listed subcommand builds its own parser under the listed name."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

import pytest

from qpbench.cli import COMMANDS, build_parser, interrupted_by, main

LISTING = """
import contextlib, io, json, sys
from qpbench.cli import main
out = io.StringIO()
with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
    main(["--help"])
loaded = sorted(name for name in sys.modules
                if name.startswith(("qpbench.cli.", "qpbench.solvers", "numpy", "pandas")))
print(json.dumps({"help": out.getvalue(), "loaded": loaded}))
"""


def test_help_lists_every_command_and_imports_none_of_them() -> None:
    result = subprocess.run([sys.executable, "-c", LISTING], capture_output=True, text=True,
                            check=True)
    listing = json.loads(result.stdout)
    for name, summary in COMMANDS.items():
        assert name.replace("_", "-") in listing["help"]
        assert summary.split()[0] in listing["help"]
    assert listing["loaded"] == []


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_each_listed_command_builds_its_own_parser(name: str) -> None:
    command = name.replace("_", "-")
    parser = build_parser(only=name)
    subcommands = next(action for action in parser._actions
                       if isinstance(action, argparse._SubParsersAction))
    assert list(subcommands.choices) == [command]
    assert callable(subcommands.choices[command].get_default("handler"))


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_each_commands_help_renders(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    """argparse formats every help string with %: a stray % would break ``COMMAND --help``."""
    with pytest.raises(SystemExit) as ended:
        main([name.replace("_", "-"), "--help"])
    assert ended.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: qpbench {name.replace('_', '-')}")


def test_an_error_raised_while_handling_ctrl_c_is_the_interrupt() -> None:
    """A library's clean-up that fails once Ctrl-C cut its work short (zipfile closing with a
    member half written, say) raises inside the KeyboardInterrupt's handling: exit 130."""
    def interrupted_clean_up() -> None:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise ValueError("can't close the archive while a member is open") from None

    with pytest.raises(ValueError) as raised:
        interrupted_clean_up()
    assert interrupted_by(raised.value)
    assert not interrupted_by(ValueError("a fault of its own"))
