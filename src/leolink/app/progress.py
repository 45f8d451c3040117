"""The progress bar of ``leolink run``: simulated seconds and epochs per second on stderr."""

from __future__ import annotations

import time
from contextlib import contextmanager

__all__ = ["progress_bar"]


@contextmanager
def progress_bar(desc, enabled=True):
    """Yield a ``progress(done_epochs, n_epochs)`` callback drawing a tqdm bar (or None)."""
    if not enabled:
        yield None
        return
    from tqdm import tqdm

    fmt = "{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} epochs "
    fmt += "[{elapsed}<{remaining}{postfix}]"
    t_wall = time.perf_counter()
    bar = None

    def progress(done, total):
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, desc=desc, bar_format=fmt, mininterval=0.5)
        bar.n = done
        rate = done / max(time.perf_counter() - t_wall, 1e-9)
        bar.set_postfix_str(f"{rate:,.0f} epochs/s", refresh=False)
        bar.refresh()

    try:
        yield progress
    finally:
        if bar is not None:
            bar.close()
