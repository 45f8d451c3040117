"""A stand-in for the engine's :class:`~leolink.engine.links.Links` in the look-ahead tests."""

import numpy as np


class TableLinks:
    """Links whose every beam's SNR [dB] is given, ``values (m, n_beam)``, every pair
    visible: ``snr_db_bm`` is the table (beam-major), ``best_beam`` its first largest
    entry per pair and that entry (the engine's rule: ``numpy.argmax`` over the beams)."""

    def __init__(self, values):
        self.values = np.asarray(values, float)
        self.visible = np.ones(self.values.shape[0], bool)

    def snr_db_bm(self, beam_ix, beam_iy):
        return self.values.T

    def best_beam(self, beam_ix, beam_iy, with_snr_db=False):
        beam = np.argmax(self.values, axis=1)
        snr = self.values[np.arange(beam.size), beam]
        return beam, (snr if with_snr_db else None)
