"""``qpbench render SCENE -o FILE.png|FILE.gif [--end-time T] [--steps N] [--solver NAME]``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from qpbench.bench.settings import check_at_least
from qpbench.cli.guards import add_memory_option, add_progress_option, guarded, progress_wanted
from qpbench.cli.output import writable_output
from qpbench.cli.progress import Progress
from qpbench.cli.simulate import DEFAULT_STEPS, check_memory_failure, check_span
from qpbench.inner_solvers import choose_by_name
from qpbench.scenes import load_scene
from qpbench.simulation.render import render
from qpbench.simulation.stepper import SimulationResult


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench render`` and its options (scene, ``-o``, span, solver, frames, guards).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser("render")
    parser.add_argument("scene", help="a <ball2d_scene> or <rigidbody2d_scene> file")
    parser.add_argument("-o", "--output", required=True, help="FILE.png or FILE.gif")
    parser.add_argument("--end-time", type=float, default=None,
                        help="simulated seconds (default: the scene's <end_time>)")
    parser.add_argument("--steps", type=int, default=None, help="at most this many steps")
    parser.add_argument("--solver", default=None, help="inner solver (default: the scene's)")
    parser.add_argument("--frames", type=int, default=80, help="frames of a gif (80)")
    add_memory_option(parser)
    add_progress_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Check the options and the output path, then draw the scene under the guards.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status of :func:`draw`: 0, or 1 when an inner solve failed.

    Raises
    ------
    QpbenchError
        When ``--steps``, ``--end-time`` or ``--frames`` is out of range or the output path
        cannot be written.
    """
    check_span(args)
    check_at_least(args.frames, 1, "--frames")
    writable_output(args.output)
    output_folder = Path(args.output).parent
    with guarded(args, "render", f"rendering {args.scene}", [output_folder]):
        return draw(args, render)


def draw(args: argparse.Namespace, render: Callable[..., SimulationResult]) -> int:
    """Simulate the scene and draw it with ``render``; exit 1 when an inner solve failed.

    Without an end time in the scene or the options, :data:`DEFAULT_STEPS` steps are drawn and
    a note says so; the scene's warnings and the run's notes go to stderr.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.
    render : callable
        The renderer, :func:`qpbench.simulation.render.render` or a stand-in with its
        signature, returning the simulation's result.

    Returns
    -------
    int
        The exit status: 0, or 1 when an inner solve failed (drawn up to there).

    Raises
    ------
    QpbenchError
        When the scene does not read, or an inner solve ran out of memory.
    """
    scene = load_scene(args.scene)
    for warning in scene.warnings:
        print(f"qpbench render: warning: {warning}", file=sys.stderr)
    steps = args.steps
    if scene.end_time is None and args.end_time is None and steps is None:
        steps = DEFAULT_STEPS
        print(f"qpbench render: note: {scene.path} has no <end_time>; drawing {DEFAULT_STEPS} "
              "steps (use --end-time or --steps)", file=sys.stderr)
    with Progress("render", progress_wanted(args), None, "steps and frames") as progress:
        result = render(scene, args.output, args.end_time, steps, choose_by_name(args.solver),
                        args.frames, progress=progress.advance)
        progress.summary = f"{result.steps} steps drawn to {args.output}"
    check_memory_failure(result)
    for note in result.notes:
        print(f"qpbench render: note: {note}", file=sys.stderr)
    if result.failure is not None:
        print(f"qpbench render: inner solve failed at step {result.failure['step']}: "
              f"{result.failure['reason']}; drawn up to there", file=sys.stderr)
    print(f"wrote {args.output}")
    return 0 if result.failure is None else 1
