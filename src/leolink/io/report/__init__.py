"""``report.html``: the streamed statistics, figures, maps, the animation and the page."""
