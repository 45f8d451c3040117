"""``summary.json``: run statistics streamed in bounded memory, per UT and overall."""
