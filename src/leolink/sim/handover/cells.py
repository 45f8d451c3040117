"""What a cell is: one beam, or one satellite (``[cells] per``).

A 3GPP cell may be one beam or several SSB beams. leolink's candidates are beams
(``cell = sat * n_beam + beam``); ``[cells] per`` says which of their changes is an L3
handover (RRC reconfiguration with sync, TS 38.331 5.3.5.5):

- ``"beam"`` (default, leolink's behaviour before): every beam is a cell; a beam change
  inside the serving satellite is a ``beam_handover``;
- ``"satellite"``: each satellite is one cell whose beams are its SSB beams. A beam change
  inside the serving satellite is beam management (L1/L2, TS 38.300 9.2.4), a
  ``beam_switch`` event with its own interruption ``beam_switch_s``, not a handover: no
  handover procedure, no T310 reset, not in the handover counts. The trigger policies
  compare satellites (their ``level = "satellite"``), and the MRO classes compare
  satellites.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CELLS_PER", "beam_switches"]

CELLS_PER = ("beam", "satellite")


def beam_switches(t_s, res, beam_switch_s):
    """Turn the ``beam_handover`` events of ``res`` (a StepResult at ``t_s``) into
    ``beam_switch`` events, each interrupting its UT for ``beam_switch_s`` [s] (``res``'s
    events, state and service codes are replaced)."""
    from leolink.sim.handover.controller import service_codes

    kind = np.asarray(res.events["kind"])
    switch = kind == "beam_handover"
    if not switch.any():
        return
    res.events = {**res.events, "kind": np.where(switch, "beam_switch", kind).astype(kind.dtype)}
    st = res.state
    st.interrupted_until_s = st.interrupted_until_s.copy()
    st.interrupted_until_s[np.asarray(res.events["ut_id"])[switch]] = t_s + beam_switch_s
    res.service = service_codes(t_s, st)
