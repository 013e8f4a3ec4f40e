"""Errors that qpbench reports to the user as one line, never as a traceback."""

from __future__ import annotations

import os

# a value quoted in a message is cut to this many characters
MAX_QUOTED = 40


def shown(text: str) -> str:
    """``text`` quoted for a one-line message.

    Its repr, cut to MAX_QUOTED characters with its length said when it is longer (a value read
    from a file may be megabytes long).

    Parameters
    ----------
    text : str
        The value to quote.

    Returns
    -------
    str
        ``repr(text)``, or the repr of its first MAX_QUOTED characters followed by
        ``... (N characters)``.
    """
    if len(text) <= MAX_QUOTED:
        return repr(text)
    return f"{text[:MAX_QUOTED]!r}... ({len(text)} characters)"


# an error's line is cut to this many characters (a damaged file's own bytes can reach it
# through a library's message)
MAX_LINE = 800


def one_line(text: str) -> str:
    """``text`` as one line of at most about MAX_LINE printable characters.

    Characters that are not printable (line breaks, other control characters) are written as
    their escapes, ``\\n`` and the like, and a longer text is cut with its length said: the
    text of an error may quote a damaged file's bytes (a member name, a library's message).

    Parameters
    ----------
    text : str
        The message.

    Returns
    -------
    str
        The message on one line.
    """
    if not text.isprintable():
        text = "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)
    if len(text) <= MAX_LINE:
        return text
    return f"{text[:MAX_LINE]}... ({len(text)} characters)"


class QpbenchError(Exception):
    """A user-facing error: bad input, unknown solver, unsupported feature.

    The message names the file, the element and the attribute at fault where
    there is one: ``scene.xml: <ball> attribute 'r': must be positive, got -1``.
    """


class InputError(QpbenchError):
    """Bad input data (file, element, attribute)."""

    def __init__(self, file: str, message: str, element: str | None = None,
                 attribute: str | None = None) -> None:
        self.file = str(file)
        self.element = element
        self.attribute = attribute
        where = self.file
        if element is not None:
            where += f": <{element}>"
        if attribute is not None:
            where += f" attribute '{attribute}'"
        super().__init__(f"{where}: {message}")


class UnsupportedError(QpbenchError):
    """Input that is well formed but asks for something qpbench does not do."""


class OutputError(QpbenchError):
    """An output path that qpbench cannot or will not write: a device, a folder or a symbolic
    link where a file goes, or a read-only or full disk. The message names the path first:
    ``results.json: cannot write: Read-only file system``."""

    def __init__(self, path: str | os.PathLike[str], message: str) -> None:
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")
