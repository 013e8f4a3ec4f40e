"""``qpbench generate FAMILY [--size N] [--seed S] [--count K] -o DIR``: hard-case families,
frictionless (qpbench.problem.generate) or frictional (qpbench.problem.friction_generate)."""

from __future__ import annotations

import argparse
import sys

from qpbench.bench.settings import check_at_least
from qpbench.errors import QpbenchError
from qpbench.problem import files, friction_reference
from qpbench.problem.friction_generate import FRICTION_FAMILIES
from qpbench.problem.friction_generate import generate as generate_frictional
from qpbench.problem.generate import FAMILIES, generate
from qpbench.problem.reference import attach_reference

ALL_FAMILIES = (*FAMILIES, *FRICTION_FAMILIES)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
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
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_at_least(args.count, 1, "--count")
    check_at_least(args.seed, 0, "--seed")
    if args.scene:
        return write_box_scenes(args)
    if args.family in FRICTION_FAMILIES:
        return run_frictional(args)
    if args.mu is not None:
        raise QpbenchError(f"--mu is for the frictional families, not '{args.family}'")
    problems = generate(args.family, size=args.size, seed=args.seed, count=args.count,
                        restitution=args.restitution)
    for problem in problems:
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
    """A frictional family: its problems with their references (friction_reference)."""
    problems = generate_frictional(args.family, size=args.size, seed=args.seed,
                                   count=args.count, restitution=args.restitution, mu=args.mu)
    for problem in problems:
        if not args.no_reference:
            friction_reference.attach_reference(problem)
            note = friction_reference.describe(problem.reference)
            if note:
                print(f"qpbench generate: {problem.name}: {note}", file=sys.stderr)
        print(files.save(problem, f"{args.output}/{problem.name}"))
    return 0


def write_box_scenes(args: argparse.Namespace) -> int:
    """``--scene``: box scenes of ``--size`` balls (seeds seed..seed+count-1) as scene XML."""
    from qpbench.scenes.builders import box_scene, write_scene

    if args.family != "box":
        raise QpbenchError(f"--scene is for the box family only, not '{args.family}'")
    size = 1000 if args.size is None else args.size
    for seed in range(args.seed, args.seed + args.count):
        scene = box_scene(size, seed=seed, restitution=1.0 if args.restitution is None
                          else args.restitution)
        print(write_scene(scene, f"{args.output}/box-{size}-s{seed}.xml"))
    return 0
