"""Run the paper's scenario from Python and look at UT 0's pass.

python examples/quickstart.py
"""

from pathlib import Path

import leolink
from leolink.config import load_config

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "paper.toml"

cfg = load_config(CONFIG, ["output.plots.enabled=false"])
result = leolink.run(cfg)  # everything in memory: no out_dir

ut0 = result.trace[result.trace.ut_id == 0]
print(f"UT 0: {len(ut0)} epochs, SNR {ut0.snr_db.min():.2f} .. {ut0.snr_db.max():.2f} dB")
print("beams:", " -> ".join(str(b) for b in ut0.beam_id.drop_duplicates()))
dwell = result.summary["per_ut"][0]["dwell"]
print("complete dwells [s]:", ", ".join(f"{d:.0f}" for d in dwell["complete_s"]))
print("events:", result.events.kind.value_counts().to_dict())
