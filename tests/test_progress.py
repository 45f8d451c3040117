"""The progress bar throttles itself: nothing for short runs, at most one redraw a second on
a terminal, at most four lines elsewhere (a log, a pipe, CI)."""

import io
import subprocess
import sys

from leolink.app.progress import LOG_FRACTIONS, MIN_INTERVAL_S, progress_bar
from report_helpers import PAPER, REPO


class _Stream(io.StringIO):
    def __init__(self, tty):
        super().__init__()
        self.tty, self.writes = tty, 0

    def isatty(self):
        return self.tty

    def write(self, text):
        self.writes += 1
        return super().write(text)


def _drive(duration_s, tty, n_epochs=120, calls=200):
    """Feed ``calls`` progress updates spread over ``duration_s`` of a fake clock."""
    now = [0.0]
    stream = _Stream(tty)
    with progress_bar("leolink run", stream=stream, clock=lambda: now[0]) as progress:
        for i in range(1, calls + 1):
            now[0] = duration_s * i / calls
            progress(round(n_epochs * i / calls), n_epochs)
    return stream


def test_a_half_second_run_draws_nothing():
    # The old bar redrew 122 times for a 0.5 s run.
    for tty in (True, False):
        assert _drive(0.5, tty).getvalue() == ""


def test_a_run_predicted_to_end_soon_draws_nothing():
    assert _drive(1.8, True).getvalue() == ""  # at 1 s only 0.8 s remain


def test_terminal_bar_redraws_at_most_once_a_second():
    out = _drive(30.0, True)
    text = out.getvalue()
    redraws = text.count("\r")
    assert 25 <= redraws <= 30.0 / MIN_INTERVAL_S + 2
    assert text.endswith("\n") and "100% 120/120 epochs" in text.rsplit("\r", 1)[1]


def test_non_terminal_gets_at_most_a_line_per_quarter():
    lines = _drive(30.0, False).getvalue().splitlines()
    assert len(lines) == len(LOG_FRACTIONS) == 4
    assert [ln.split(":")[1].split("%")[0].strip() for ln in lines] == ["25", "50", "75", "100"]
    assert "\r" not in "".join(lines)


def test_leolink_run_into_a_pipe_prints_few_progress_lines(tmp_path):
    # A real run with stderr a pipe (not a terminal): at most 4 lines, whatever its speed.
    done = subprocess.run(
        [sys.executable, "-m", "leolink.cli", "run", PAPER, "--out", tmp_path,
         "--set", "output.report.enabled=false", "--set", "output.plots.enabled=false"],
        capture_output=True, text=True, cwd=REPO, check=True,
    )  # fmt: skip
    # Only the progress lines count: the run's notes (codebook, ROI frame) follow them, and
    # whether progress shows at all depends on the machine's load (SHOW_AFTER_S).
    progress = [ln for ln in done.stderr.splitlines() if ln.startswith("leolink run:")]
    assert "\r" not in done.stderr and len(progress) <= len(LOG_FRACTIONS)
    assert all(ln.startswith(("leolink run:", "note: ")) for ln in done.stderr.splitlines())
    assert done.stdout.startswith(f"wrote {tmp_path}: 7 UTs, 120 epochs")
