"""Progress of a long command on stderr: a tqdm bar that appears once the work has taken
:data:`BAR_DELAY_S`, and a closing summary line when it took more than :data:`SUMMARY_AFTER_S`
(stdout is left to the command's own output)."""

from __future__ import annotations

import sys
import time

from tqdm import tqdm

BAR_DELAY_S = 1.0
SUMMARY_AFTER_S = 3.0
# no monitor thread: the bars run under a memory cap, where a new thread's stack may not fit
tqdm.monitor_interval = 0


class Progress:
    """A bar counting ``unit`` up to ``total`` (None: unknown) for ``command``, shown only
    when ``enabled``."""

    def __init__(self, command: str, enabled: bool, total: int | None, unit: str) -> None:
        self.command = command
        self.enabled = enabled
        self.started = time.perf_counter()
        self.summary: str | None = None  # the closing line, set by the work when it ends
        self.bar = tqdm(total=total, unit=f" {unit}", desc=f"qpbench {command}",
                        file=sys.stderr, delay=BAR_DELAY_S, leave=False, disable=not enabled,
                        dynamic_ncols=True)

    def advance(self, count: int = 1, note: str | None = None) -> None:
        """Count ``count`` more units, with ``note`` (e.g. the item just done) beside the bar.

        Parameters
        ----------
        count : int, optional
            The units done; 1 by default.
        note : str or None, optional
            The text shown beside the bar; None (default) leaves it as it is.
        """
        self.bar.update(count)
        if note is not None:
            self.bar.set_postfix_str(note, refresh=False)

    def close(self, summary: str | None) -> None:
        """Remove the bar and print the closing summary when it is due.

        Prints ``qpbench COMMAND: SUMMARY in T s`` on stderr when enabled, a summary is given and
        the work took more than :data:`SUMMARY_AFTER_S`.

        Parameters
        ----------
        summary : str or None
            The closing line's text; None prints nothing.
        """
        self.bar.close()
        elapsed = time.perf_counter() - self.started
        if self.enabled and summary is not None and elapsed > SUMMARY_AFTER_S:
            print(f"qpbench {self.command}: {summary} in {elapsed:.1f} s", file=sys.stderr)

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        """Closes the bar, with :attr:`summary` only when the block ended normally."""
        self.close(self.summary if kind is None else None)
