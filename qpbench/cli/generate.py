"""``qpbench generate FAMILY [--size N] [--seed S] [--count K] -o DIR``: hard-case families,
frictionless (qpbench.problem.generate) or frictional (qpbench.problem.friction_generate).

Problems are made, given their reference and written one at a time, so memory holds one
problem whatever ``--count``; a size whose balls alone need more than ``--memory-limit`` or
the machine allows is refused in one line before anything is allocated (exit 2), and Ctrl-C
ends the command within about a second (exit 130) leaving no partial file."""

from __future__ import annotations

import argparse
import sys

from qpbench.bench.settings import check_at_least
from qpbench.cli.guards import add_memory_option, guarded
from qpbench.errors import QpbenchError
from qpbench.problem import files, friction_reference
from qpbench.problem.friction_generate import FRICTION_FAMILIES
from qpbench.problem.friction_generate import generate as generate_frictional
from qpbench.problem.generate import FAMILIES, check_family_size, family_entry, generate
from qpbench.problem.reference import attach_reference
from qpbench.scenes.builders import box_scene, write_scene

ALL_FAMILIES = (*FAMILIES, *FRICTION_FAMILIES)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench generate`` and its options (family, size, seeds, coefficients, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "generate", help="write seeded problems of a hard-case family",
        description=f"families: {', '.join(FAMILIES)}; frictional: "
                    f"{', '.join(FRICTION_FAMILIES)}",
    )
    parser.add_argument("family", help="one of: " + ", ".join(ALL_FAMILIES))
    parser.add_argument("--size", type=int, default=None, help="balls (grid: per side)")
    parser.add_argument("--seed", type=int, default=0, help="first seed (0)")
    parser.add_argument("--count", type=int, default=1, help="problems, seeds seed..seed+count-1")
    parser.add_argument("--restitution", type=float, default=None,
                        help="coefficient c (the family's own: 1 without friction)")
    parser.add_argument("--mu", type=float, default=None,
                        help="frictional families: one friction coefficient for every contact")
    parser.add_argument("--no-reference", action="store_true",
                        help="skip the reference solution (v_error will be empty)")
    parser.add_argument("--scene", action="store_true",
                        help="box only: write a scene file (balls in a box with walls) to "
                             "simulate, instead of problems")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    add_memory_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Check the seeds and write the family's problems (or box scenes) under the guards.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status: 0.

    Raises
    ------
    QpbenchError
        When ``--count`` is below 1, ``--seed`` below 0, or an option does not fit the family.
    """
    check_at_least(args.count, 1, "--count")
    check_at_least(args.seed, 0, "--seed")
    with guarded(args, "generate", f"generating '{args.family}' problems", [args.output]):
        return write_family(args)


def seeds(args: argparse.Namespace) -> range:
    """The seeds of the problems asked: ``--seed`` .. ``--seed + --count - 1``.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``seed`` and ``count``.

    Returns
    -------
    range
        The seeds, one per problem.
    """
    return range(args.seed, args.seed + args.count)


def write_family(args: argparse.Namespace) -> int:
    """Write the problems (or box scenes) asked, each written before the next is made.

    Frictionless problems get their reference unless ``--no-reference`` (a reference whose
    solvers disagree is said on stderr); each path written is printed.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status: 0.

    Raises
    ------
    QpbenchError
        When ``--mu`` is given for a frictionless family, or ``--scene`` for another family than
        ``box``.
    """
    if args.scene:
        return write_box_scenes(args)
    if args.family in FRICTION_FAMILIES:
        return run_frictional(args)
    if args.mu is not None:
        raise QpbenchError(f"--mu is for the frictional families, not '{args.family}'")
    for seed in seeds(args):  # generate(seed=s + i, count=1) is generate(seed=s, count=n)[i]
        [problem] = generate(args.family, size=args.size, seed=seed, count=1,
                             restitution=args.restitution)
        if not args.no_reference:
            attach_reference(problem)
            if not problem.reference.verified:
                print(f"qpbench generate: {problem.name}: references disagree "
                      f"({problem.reference.agreement:.1e}); v_error will not be computed",
                      file=sys.stderr)
        path = files.save(problem, f"{args.output}/{problem.name}")
        print(path)
    return 0


def run_frictional(args: argparse.Namespace) -> int:
    """Write a frictional family's problems with their references (friction_reference).

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`; ``family`` is one of FRICTION_FAMILIES.

    Returns
    -------
    int
        The exit status: 0.

    Raises
    ------
    QpbenchError
        When the size does not suit the family.
    """
    _, size = family_entry(FRICTION_FAMILIES, args.family, args.size, "frictional family")
    check_family_size(args.family, size)
    for seed in seeds(args):
        [problem] = generate_frictional(args.family, size=size, seed=seed, count=1,
                                        restitution=args.restitution, mu=args.mu)
        if not args.no_reference:
            friction_reference.attach_reference(problem)
            note = friction_reference.describe(problem.reference)
            if note:
                print(f"qpbench generate: {problem.name}: {note}", file=sys.stderr)
        print(files.save(problem, f"{args.output}/{problem.name}"))
    return 0


def write_box_scenes(args: argparse.Namespace) -> int:
    """Write ``--scene`` box scenes of ``--size`` balls (seeds seed..seed+count-1) as scene XML.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`; ``size`` None means 1000 balls, ``restitution``
        None means 1.

    Returns
    -------
    int
        The exit status: 0.

    Raises
    ------
    QpbenchError
        When the family is not ``box`` or the size is below 1 or too large.
    """
    if args.family != "box":
        raise QpbenchError(f"--scene is for the box family only, not '{args.family}'")
    size = 1000 if args.size is None else args.size
    check_at_least(size, 1, "--size")
    check_family_size(args.family, size)
    for seed in seeds(args):
        scene = box_scene(size, seed=seed, restitution=1.0 if args.restitution is None
                          else args.restitution)
        print(write_scene(scene, f"{args.output}/box-{size}-s{seed}.xml"))
    return 0
