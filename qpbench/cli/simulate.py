"""``qpbench simulate SCENE [--end-time T] [--steps N] [--solver NAME] [--capture DIR] [--json]``.

``--json`` reports the final state: ``x_final``, ``v_final`` and, for rigid bodies,
``theta_final`` and ``omega_final``. Without ``<end_time>`` in the scene and without
``--end-time``, the run stops after ``DEFAULT_STEPS`` steps and says so. Exit 0 when the
run ends; 1 when an inner solve failed (the JSON says which), 2 on bad input or when the run
needs more memory than ``--memory-limit`` or the machine allows (one line, before the
allocation where the size is known: bodies, candidate pairs, the contacts' Q), 130 on Ctrl-C.
``--progress`` shows the steps on stderr.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from qpbench.bench.settings import check_accuracy, check_at_least
from qpbench.cli.guards import add_memory_option, add_progress_option, guarded, progress_wanted
from qpbench.cli.output import plain, print_json
from qpbench.cli.progress import Progress
from qpbench.errors import InputError
from qpbench.inner_solvers import choose_by_name
from qpbench.memory import out_of_memory
from qpbench.scenes import load_scene
from qpbench.simulation.stepper import DEFAULT_ACCURACY, SimulationResult, Simulator

DEFAULT_STEPS = 1000


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench simulate`` and its options (scene, span, solver, accuracy, capture, JSON).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "simulate", epilog="Every JSON field, its unit and when it is null: docs/json-output.md")
    parser.add_argument("scene", help="a <ball2d_scene> or <rigidbody2d_scene> file")
    parser.add_argument("--end-time", type=float, default=None,
                        help="simulated seconds (default: the scene's <end_time>)")
    parser.add_argument("--steps", type=int, default=None, help="at most this many steps")
    parser.add_argument("--solver", default=None,
                        help="inner solver NAME[/FORMULATION] (default: the scene's, mapped)")
    parser.add_argument("--accuracy", type=float, default=None,
                        help=f"residual asked of every inner solve (default {DEFAULT_ACCURACY:g};"
                             " a friction solver's own tol when tighter)")
    parser.add_argument("--capture", default=None, metavar="DIR",
                        help="write every impact problem to DIR/<scene>_step<k>.npz")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_memory_option(parser)
    add_progress_option(parser)
    parser.set_defaults(handler=run)


def check_span(args: argparse.Namespace) -> None:
    """Check that ``--steps`` and ``--end-time``, where given, are at least 0.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options holding ``steps`` and ``end_time`` (None: not given).

    Raises
    ------
    QpbenchError
        When either is negative.
    """
    if args.steps is not None:
        check_at_least(args.steps, 0, "--steps")
    if args.end_time is not None:
        check_at_least(args.end_time, 0, "--end-time")


def check_memory_failure(result: SimulationResult) -> None:
    """Raise a run that an inner solve's lack of memory stopped as an out-of-memory error.

    OutOfMemory (one line, exit 2) when the run stopped because an inner solve ran out of
    memory, rather than reporting it as a failed solve.

    Parameters
    ----------
    result : SimulationResult
        The result of the run.

    Raises
    ------
    OutOfMemory
        A QpbenchError naming the step, the solver and the contacts.
    """
    failure = result.failure
    if failure is not None and "MemoryError" in str(failure.get("solver_status", "")):
        raise out_of_memory(f"simulating {result.scene}",
                            f"the inner solve of step {failure['step']} by "
                            f"{failure.get('solver')}, {failure.get('contacts', '?')} contacts")


def run(args: argparse.Namespace) -> int:
    """Check the span and the accuracy, then simulate the scene under the guards.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status of :func:`simulate`: 0, or 1 when an inner solve failed.

    Raises
    ------
    QpbenchError
        When ``--steps``, ``--end-time`` or ``--accuracy`` is out of range.
    """
    check_span(args)
    if args.accuracy is not None:
        check_accuracy(args.accuracy)
    outputs = [] if args.capture is None else [args.capture]
    with guarded(args, "simulate", f"simulating {args.scene}", outputs):
        return simulate(args)


def simulate(args: argparse.Namespace) -> int:
    """Simulate the scene and print the summary, as text or one JSON object.

    Without an end time in the scene or the options, :data:`DEFAULT_STEPS` steps are simulated
    and a note says so; the scene's warnings and the run's notes go to stderr, and with
    ``--capture`` every impact problem is written to that folder.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status: 0 when the run ends, 1 when an inner solve failed.

    Raises
    ------
    QpbenchError
        When the scene does not read, ``--capture`` is a file, or the run runs out of memory.
    """
    scene = load_scene(args.scene)
    for warning in scene.warnings:
        print(f"qpbench simulate: warning: {warning}", file=sys.stderr)
    if args.capture is not None and Path(args.capture).exists() and not Path(args.capture).is_dir():
        raise InputError(args.capture, "--capture needs a folder, this is a file")
    steps = args.steps
    if scene.end_time is None and args.end_time is None and steps is None:
        steps = DEFAULT_STEPS
        print(f"qpbench simulate: note: {scene.path} has no <end_time>; simulating "
              f"{DEFAULT_STEPS} steps (use --end-time or --steps)", file=sys.stderr)
    simulator = Simulator(scene, choose_by_name(args.solver), accuracy=args.accuracy,
                          capture=args.capture)
    for note in simulator.notes:
        print(f"qpbench simulate: note: {note}", file=sys.stderr)
    noted = len(simulator.notes)
    with Progress("simulate", progress_wanted(args),
                  simulator.step_count(args.end_time, steps), "steps") as progress:
        result = simulator.run(end_time=args.end_time, max_steps=steps,
                               on_step=lambda event: progress.advance())
        progress.summary = (f"{result.steps} steps, {result.impacts} impacts, "
                            f"{result.captured} captured")
    check_memory_failure(result)
    for note in result.notes[noted:]:  # what the run itself found (e.g. coincident centres)
        print(f"qpbench simulate: note: {note}", file=sys.stderr)
    summary = result.as_dict()
    if args.json:
        print_json(summary)
    else:
        for key, value in summary.items():
            if key not in ("x_final", "v_final", "theta_final", "omega_final"):
                print(f"{key:>18}: {plain(value, seconds=key.endswith('_s'))}")
    if result.failure is not None:
        print(f"qpbench simulate: inner solve failed at step {result.failure['step']}: "
              f"{result.failure['reason']} ({result.failure['solver']})", file=sys.stderr)
        return 1
    return 0
