"""The table of known solver defects (``defects.toml`` beside this module).

A row names a solver/formulation pair, a package and a version range, the problems it hits
and what goes wrong. :func:`known_defect` tells whether a row applies to a solve here: the
installed version is in the range and the problem is of the kind named. Tests read it to
expect a described failure; the report prints the table.
"""

from __future__ import annotations

import subprocess
import tomllib
from dataclasses import dataclass
from functools import cache
from importlib import metadata
from pathlib import Path

from packaging.specifiers import SpecifierSet

from qpbench.errors import InputError

TABLE = Path(__file__).with_name("defects.toml")
PROBLEM_KINDS = ("any", "singular")
EFFECTS = ("wrong-claim", "fails", "inaccurate")
FIELDS = ("solver", "formulation", "package", "versions", "problems", "effect", "what")


# a package named ``debian:NAME`` is Debian's package NAME (a solver that runs in the system
# interpreter, such as python3-siconos, has no Python metadata that the venv can see)
DEBIAN = "debian:"


@cache
def debian_version(package: str) -> str | None:
    """The installed version of Debian package ``package`` as dpkg records it.

    Parameters
    ----------
    package : str
        The Debian package's name (``python3-siconos``).

    Returns
    -------
    str or None
        Its version (``4.4.0+dfsg-2``), or None when it is not installed or there is no
        dpkg.
    """
    try:
        query = subprocess.run(["dpkg-query", "-W", "-f=${Status}|${Version}", package],
                               capture_output=True, text=True, check=False, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    status, _, version = query.stdout.partition("|")
    return version.strip() or None if status.endswith(" installed") else None


@dataclass(frozen=True)
class Defect:
    solver: str
    formulation: str
    package: str
    versions: str
    problems: str
    effect: str
    what: str

    def installed_version(self) -> str | None:
        """The version of ``package`` installed here.

        A Python distribution's, or for ``debian:NAME`` that Debian package's (dpkg's
        record).

        Returns
        -------
        str or None
            The version, None when the package is missing.
        """
        if self.package.startswith(DEBIAN):
            return debian_version(self.package.removeprefix(DEBIAN))
        try:
            return metadata.version(self.package)
        except metadata.PackageNotFoundError:
            return None

    def applies_here(self) -> bool:
        """The installed version of ``package`` is within ``versions``.

        Returns
        -------
        bool
            False also when the package is not installed; pre-releases count as in range.
        """
        version = self.installed_version()
        return version is not None and SpecifierSet(self.versions).contains(
            version, prereleases=True)

    def hits(self, solver: str, formulation: str, rank_deficiency: int) -> bool:
        """Whether this row describes a solve of ``solver/formulation`` here.

        The row's pair must match (its formulation ``*`` matches any), its problem kind
        must fit the rank deficiency, and its package be installed here in its range.

        Parameters
        ----------
        solver : str
            The solver's name.
        formulation : str
            The formulation it posed.
        rank_deficiency : int
            The problem's rank deficiency of Q (``singular`` rows need it above 0).

        Returns
        -------
        bool
            True when the row applies.
        """
        pair = self.solver == solver and self.formulation in ("*", formulation)
        kind = self.problems == "any" or (self.problems == "singular" and rank_deficiency > 0)
        return pair and kind and self.applies_here()


@cache
def defects(path: Path = TABLE) -> tuple[Defect, ...]:
    """Every row of the table, read once per path.

    Parameters
    ----------
    path : Path, optional
        The TOML table; ``defects.toml`` beside this module by default.

    Returns
    -------
    tuple[Defect, ...]
        The rows in the file's order.

    Raises
    ------
    InputError
        Naming the file, row and field on an unreadable table or a malformed row.
    packaging.specifiers.InvalidSpecifier
        On a malformed ``versions`` range.
    """
    try:
        rows = tomllib.loads(path.read_text(encoding="utf-8")).get("defect", [])
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise InputError(str(path), f"cannot read the defects table: {error}") from error
    table = []
    for number, row in enumerate(rows, start=1):
        where = f"defect {number}"
        for name in FIELDS:
            if not isinstance(row.get(name), str):
                raise InputError(str(path), "missing or not a string", element=where,
                                 attribute=name)
        if row["problems"] not in PROBLEM_KINDS:
            raise InputError(str(path), f"must be one of {PROBLEM_KINDS}", element=where,
                             attribute="problems")
        if row["effect"] not in EFFECTS:
            raise InputError(str(path), f"must be one of {EFFECTS}", element=where,
                             attribute="effect")
        SpecifierSet(row["versions"])  # raises InvalidSpecifier on a malformed range
        table.append(Defect(**{name: row[name] for name in FIELDS}))
    return tuple(table)


def known_defect(solver: str, formulation: str, rank_deficiency: int) -> Defect | None:
    """The first row that describes this solve here, or None.

    Parameters
    ----------
    solver : str
        The solver's name.
    formulation : str
        The formulation it posed.
    rank_deficiency : int
        The problem's rank deficiency of Q.

    Returns
    -------
    Defect or None
        The first row of :func:`defects` that :meth:`Defect.hits` this solve, None when none
        does.
    """
    return next((defect for defect in defects()
                 if defect.hits(solver, formulation, rank_deficiency)), None)
