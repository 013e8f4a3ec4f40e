"""The problems of a results table imported from Siconos' and FCLIB's files, described as
Acary, Bremond and Huber describe their benchmark's problems (qpbench.problem.description):
contacts, degrees of freedom, contact density, rank deficiency and cond of W, mu.

The rows of a table name each problem's file (``problem_file``, as ``qpbench run`` was given
it); the description is computed from that file, so it needs the problem folder the run
read. A problem whose file is gone, unreadable, or holds other numbers than those run (its
``problem_hash`` differs) is listed with its contacts from the rows and ``-`` for the rest.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import pandas as pd

from qpbench.bench.formatting import number
from qpbench.bench.runner import fingerprint
from qpbench.errors import QpbenchError
from qpbench.problem import fclib, files
from qpbench.problem.description import DENSE_LIMIT, describe
from qpbench.problem.siconos_import import FAMILY as SICONOS

IMPORTED_FAMILIES = (SICONOS, fclib.FAMILY)
# the columns of the table, in order, as its header names them
COLUMNS = ("problem", "source", "format", "contacts", "dofs", "density", "rank deficiency",
           "cond(W)", "mu")
TITLE = "Imported problems (Siconos, FCLIB)"
INTRO = ("The problems imported from Siconos' and FCLIB's files, described as Acary, Bremond "
         "and Huber describe theirs: contacts n; degrees of freedom (dofs; - for a reduced "
         "problem, W alone); contact density d n / dofs (d = 2 with friction, 1 without; "
         "above 1, W is singular); the rank deficiency size(W) - rank(W) and cond(W) = "
         "lambda_max / lambda_min (inf when W is singular), both from a dense eigenvalue "
         f"computation, so only up to {DENSE_LIMIT:,} unknowns (- beyond); mu, the friction "
         "coefficients (0: an LCP, imported as a frictionless impact problem). W is the "
         "Delassus matrix H^T M^-1 H of a global problem, the given W of a reduced one, M "
         "of an LCP.")


def _mu(low: float, high: float) -> str:
    return number(high) if low == high else f"{number(low)} .. {number(high)}"


@functools.lru_cache(maxsize=256)
def _described(path: str, digest: str | None) -> tuple[dict[str, Any], str] | None:
    """(description, file format) of the problem of ``path`` when it can be read and (where
    the rows state one) its fingerprint is ``digest``; None otherwise. Cached: the Markdown
    report and index.html describe the same problems."""
    if not Path(path).is_file():
        return None
    try:
        problem = files.load(path)
    except (QpbenchError, OSError, ValueError, KeyError):
        return None
    if digest is not None and fingerprint(problem) != digest:
        return None
    description = describe(problem)
    return description, str(problem.metadata.get("format", description["kind"]))


def describe_imported(frame: pd.DataFrame) -> pd.DataFrame:
    """One row of display strings per imported problem of ``frame`` (family ``siconos`` or
    ``fclib``), sorted by family, then contacts, then name.

    Parameters
    ----------
    frame : pd.DataFrame
        Results rows with ``problem``, ``family`` and ``problem_file``; ``problem_hash``,
        ``source`` and ``contacts`` are used where present.

    Returns
    -------
    pd.DataFrame
        The columns of ``COLUMNS``, every cell a string; no rows when ``frame`` has no
        imported problem.
    """
    needed = {"problem", "family", "problem_file"}
    if frame.empty or not needed <= set(frame.columns):
        return pd.DataFrame(columns=list(COLUMNS))
    imported = frame[frame["family"].astype(str).isin(IMPORTED_FAMILIES)]
    entries = []
    for name, rows in imported.groupby("problem", sort=False):
        first = rows.iloc[0]
        digest = first["problem_hash"] if "problem_hash" in rows else None
        described = _described(str(first["problem_file"]),
                               digest if isinstance(digest, str) else None)
        source = first["source"] if "source" in rows else None
        contacts = first["contacts"] if "contacts" in rows else None
        row = {"problem": str(name),
               "source": Path(source).name if isinstance(source, str) and source else "-",
               "format": "-",
               "contacts": "-" if contacts is None or pd.isna(contacts) else str(int(contacts)),
               "dofs": "-", "density": "-", "rank deficiency": "-", "cond(W)": "-", "mu": "-"}
        size = -1
        if described is not None:
            description, file_format = described
            size = int(description["contacts"])
            row.update({
                "format": file_format,
                "contacts": str(size),
                "dofs": number(description["dofs"]),
                "density": number(description["density"]),
                "rank deficiency": number(description["rank_deficiency"]),
                "cond(W)": number(description["cond"]),
                "mu": _mu(description["mu_min"], description["mu_max"]),
            })
        entries.append((str(first["family"]), size, str(name), row))
    entries.sort(key=lambda entry: entry[:3])
    return pd.DataFrame([row for *_, row in entries], columns=list(COLUMNS))


def unread(table: pd.DataFrame) -> int:
    """Count the problems a :func:`describe_imported` table could not describe.

    Parameters
    ----------
    table : pd.DataFrame
        A table of :func:`describe_imported`.

    Returns
    -------
    int
        Its rows without a description: the file gone, unreadable, or holding other numbers
        than those run (``format`` is ``-``).
    """
    return int((table["format"] == "-").sum()) if not table.empty else 0


def note(table: pd.DataFrame) -> str:
    """The sentence under a :func:`describe_imported` table about the problems it could not
    describe.

    Parameters
    ----------
    table : pd.DataFrame
        A table of :func:`describe_imported`.

    Returns
    -------
    str
        How many of its problems are not described and why, as a paragraph of its own (a
        blank line before it); empty when it describes all.
    """
    missing = unread(table)
    if not missing:
        return ""
    return (f"\n{missing} of {len(table)} problems not described: their file (`problem_file` of "
            "the rows) is gone, unreadable or holds other numbers than those run.\n")
