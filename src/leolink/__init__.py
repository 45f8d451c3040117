"""leolink: LEO satellite downlinks with massive hybrid phased arrays and beam handover.

The physics follows J. Palacios et al., "A hybrid beamforming design for massive
MIMO LEO satellite communications"; see ``docs/errata.md`` for where leolink departs
from the paper and why.
"""

from leolink.errors import ConfigError, LeolinkError

__version__ = "0.1.0"

__all__ = ["ConfigError", "LeolinkError", "__version__", "run"]


def run(config, out_dir=None, progress=None, overwrite=False):
    """Run a simulation; see :func:`leolink.app.run.run`."""
    from leolink.app.run import run as _run

    return _run(config, out_dir=out_dir, progress=progress, overwrite=overwrite)
