"""The link budget of the paper's scenario at a few elevations, term by term.

python examples/budget.py
"""

from pathlib import Path

from leolink.app.reports import link_budget_at_elevation
from leolink.config import load_config

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "paper.toml"

cfg = load_config(CONFIG)
print(f"{'el [deg]':>8} {'range [km]':>10} {'FSPL [dB]':>9} {'G_tx [dB]':>9} {'SNR [dB]':>8}")
for el in (90.0, 75.0, 65.0):
    b = link_budget_at_elevation(cfg, el)
    print(
        f"{el:8.1f} {b['slant_range_m'] / 1e3:10.1f} {b['fspl_db']:9.2f} "
        f"{b['gain_tx_db']:9.2f} {b['snr_db']:8.2f}"
    )
