"""The progress bar of ``leolink run``: epochs, elapsed and remaining time on stderr.

It throttles itself so that logs stay short:

- nothing before the run has taken ``SHOW_AFTER_S``, nor when it is then predicted to end
  within ``MIN_REMAINING_S`` (a 0.5 s run draws nothing);
- on a terminal, one bar redrawn in place at most once per ``MIN_INTERVAL_S``, and once at
  the end;
- elsewhere (a log file, a pipe, CI), one plain line at each quarter of the run: at most
  ``len(LOG_FRACTIONS)`` lines.
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

__all__ = ["LOG_FRACTIONS", "MIN_INTERVAL_S", "Progress", "progress_bar"]

SHOW_AFTER_S = 1.0
MIN_REMAINING_S = 1.0
MIN_INTERVAL_S = 1.0
LOG_FRACTIONS = (0.25, 0.5, 0.75, 1.0)
BAR_CHARS = 24


def _clock_text(seconds):
    seconds = int(round(seconds))
    return f"{seconds // 60:02d}:{seconds % 60:02d}"


class Progress:
    """``progress(done_epochs, n_epochs)`` callback writing to ``stream``.

    Parameters
    ----------
    desc : str
        Shown first on every line.
    stream : text file, default ``sys.stderr``
        A terminal (``isatty()``) gets a bar redrawn in place, anything else plain lines.
    clock : callable
        Seconds, monotonic (tests pass a fake one).
    """

    def __init__(self, desc, stream=None, clock=time.perf_counter):
        self.desc, self.stream, self.clock = desc, stream or sys.stderr, clock
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(isatty and isatty())
        self.t0, self.shown, self.last_draw, self.next_log = clock(), False, None, 0
        self.redraws, self.state, self.drawn = 0, (0, 0), None

    def _line(self, done, total, elapsed):
        rate = done / elapsed if elapsed > 0 else 0.0
        left = (total - done) / rate if rate > 0 else 0.0
        pct = 100.0 * done / total if total else 100.0
        return (
            f"{self.desc}: {pct:3.0f}% {done}/{total} epochs "
            f"[{_clock_text(elapsed)}<{_clock_text(left)}, {rate:,.0f} epochs/s]"
        )

    def __call__(self, done, total):
        self.state = (done, total)
        now = self.clock()
        elapsed = now - self.t0
        if not self.shown:
            remaining = elapsed / max(done, 1) * (total - done)
            if elapsed < SHOW_AFTER_S or remaining < MIN_REMAINING_S:
                return
            self.shown = True
        if self.tty:
            if self.last_draw is None or now - self.last_draw >= MIN_INTERVAL_S or done == total:
                self._draw(done, total, elapsed, now)
            return
        crossed = False
        while self.next_log < len(LOG_FRACTIONS) and done >= LOG_FRACTIONS[self.next_log] * total:
            self.next_log, crossed = self.next_log + 1, True
        if crossed:  # one line however many quarters this call crossed
            self._write(self._line(done, total, elapsed) + "\n")

    def _draw(self, done, total, elapsed, now):
        filled = int(BAR_CHARS * done / total) if total else BAR_CHARS
        bar = "#" * filled + "-" * (BAR_CHARS - filled)
        line = self._line(done, total, elapsed).replace(": ", f": |{bar}| ", 1)
        self._write("\r" + line)
        self.last_draw, self.drawn = now, (done, total)

    def _write(self, text):
        self.redraws += 1
        self.stream.write(text)
        self.stream.flush()

    def close(self):
        """Draw the final state (if a bar was shown) and end its line."""
        if self.tty and self.shown:
            if self.drawn != self.state:
                now = self.clock()
                self._draw(*self.state, now - self.t0, now)
            self.stream.write("\n")
            self.stream.flush()


@contextmanager
def progress_bar(desc, enabled=True, stream=None, clock=time.perf_counter):
    """Yield a ``progress(done_epochs, n_epochs)`` callback (:class:`Progress`), or None."""
    if not enabled:
        yield None
        return
    progress = Progress(desc, stream, clock)
    try:
        yield progress
    finally:
        progress.close()
