"""Progress of long computations: standard ``logging``, and the terminal on request.

Every stage of a study is logged to the ``"pysindy_mme"`` logger at INFO
level (finer steps at DEBUG), so an application configures it like any
other library's logging; nothing is printed by default. ``verbose=True``
(or ``--verbose`` on the command line) also writes each stage to standard
error with the elapsed time, and, on an interactive terminal, keeps one
status line updated with the finer steps.
"""

from __future__ import annotations

import logging
import sys
import time

__all__ = ["Progress", "logger"]

logger = logging.getLogger("pysindy_mme")


class Progress:
    """Stage messages for one long computation.

    Parameters
    ----------
    verbose : bool
        Also write to ``stream`` (default: standard error).
    """

    def __init__(self, verbose: bool = False, stream=None):
        self.verbose = bool(verbose)
        self.stream = sys.stderr if stream is None else stream
        self.start = time.perf_counter()
        self._status = False
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def _elapsed(self) -> str:
        return f"[{time.perf_counter() - self.start:7.1f} s]"

    def stage(self, message: str) -> None:
        """A new stage: logged at INFO, printed when verbose."""
        logger.info(message)
        if self.verbose:
            self._clear()
            print(f"{self._elapsed()} {message}", file=self.stream, flush=True)

    def step(self, message: str) -> None:
        """A finer step: logged at DEBUG; a status line on a terminal."""
        logger.debug(message)
        if self.verbose and self._tty:
            line = f"{self._elapsed()}   {message}"[:100]
            print("\r" + line.ljust(100), end="", file=self.stream, flush=True)
            self._status = True
        elif self.verbose:
            print(f"{self._elapsed()}   {message}", file=self.stream, flush=True)

    def _clear(self):
        if self._status:
            print("\r" + " " * 100 + "\r", end="", file=self.stream, flush=True)
            self._status = False

    def done(self, message: str = "done") -> None:
        self.stage(message)
