"""DVB-S2/S2X MODCOD table and adaptive coding and modulation (ACM) selection.

The table (``leolink/data/dvbs2x_modcods.csv``) holds, per MODCOD, the spectral efficiency
``eta`` [bit/symbol] (net of the BBHEADER and PLHEADER overhead, normal frames, no pilots)
and the ideal Es/N0 [dB] at the quasi-error-free point on the AWGN channel, from ETSI
EN 302 307-1 Table 13 (DVB-S2) and EN 302 307-2 Table 20a (DVB-S2X).

ACM picks, per link, the MODCOD of highest spectral efficiency whose threshold plus an
implementation margin does not exceed the link's Es/N0:

    best = argmax { eta_i : esn0_ideal_i + margin <= Es/N0 }.

**Equality counts as allowed**: a link exactly at ``threshold + margin`` gets that MODCOD
(the table's Es/N0 is the point where the QEF target is met). Among MODCODs of equal
efficiency the one with the lower threshold is returned (16APSK 3/5-L before 16APSK 3/5).
The throughput of MODCOD ``i`` at symbol rate ``R_s`` is ``eta_i R_s`` [bit/s].

The table is read once (``importlib.resources``, cached); selection is vectorized
(``numpy.searchsorted`` on the thresholds of the efficiency frontier).

References
----------
.. [1] ETSI EN 302 307-1 V1.4.1, "DVB-S2", Table 13 (Es/N0 at QEF), Table 5a (BCH, clause
   5.3.1) and clause 5.5.2 (90-symbol PL header), from which the efficiencies follow.
.. [2] ETSI EN 302 307-2 V1.1.1, "DVB-S2 Extensions (DVB-S2X)", Table 20a.
"""

import csv
import functools
import importlib.resources
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ModcodTable",
    "modcod_names",
    "modcod_spectral_efficiency",
    "modcod_table",
    "modcod_throughput_bps",
    "select_modcod",
]

_TABLE_FILE = "dvbs2x_modcods.csv"
#: Name returned for index -1 (no MODCOD closes the link).
NO_MODCOD = ""


@dataclass(frozen=True, eq=False)
class ModcodTable:
    """The MODCOD table as arrays, rows in file order (index = row).

    Attributes
    ----------
    names : tuple of str, length n_modcod
        Canonical MODCOD names (``"QPSK 1/4"``, ``"16APSK 3/5-L"``).
    spectral_efficiency_bit_sym : ndarray, shape (n_modcod,)
        Net spectral efficiency [bit/symbol].
    esn0_ideal_db : ndarray, shape (n_modcod,)
        Ideal Es/N0 at the QEF point, AWGN [dB].
    sources : tuple of str
        Standard and table of each row.
    """

    names: tuple
    spectral_efficiency_bit_sym: np.ndarray
    esn0_ideal_db: np.ndarray
    sources: tuple

    @functools.cached_property
    def _frontier(self):
        """Thresholds sorted ascending and, at each, the row of best efficiency so far."""
        # Stable: rows identical in (threshold, eta) keep the file order. Within equal
        # thresholds the running argmax below finds the best eta whatever their order.
        order = np.argsort(self.esn0_ideal_db, kind="stable")
        eta = self.spectral_efficiency_bit_sym[order]
        # Running argmax; strict '>' keeps the first (lowest-threshold) of equal etas.
        best_before = np.concatenate(([-np.inf], np.maximum.accumulate(eta)[:-1]))
        is_new_best = eta > best_before
        best_pos = np.maximum.accumulate(np.where(is_new_best, np.arange(len(eta)), 0))
        return self.esn0_ideal_db[order], order[best_pos]

    def index_of(self, name):
        """Row of the MODCOD called ``name`` (``ValueError`` if absent)."""
        return self.names.index(name)


@functools.cache
def modcod_table():
    """Load the packaged DVB-S2/S2X table once (cached).

    Returns
    -------
    ModcodTable
        Rows in file order.
    """
    text = importlib.resources.files("leolink").joinpath("data", _TABLE_FILE).read_text("utf-8")
    lines = [line for line in text.splitlines() if line and not line.startswith("#")]
    rows = list(csv.DictReader(lines))[1:]  # rows[0] is the units row
    column = lambda key: np.array([float(r[key]) for r in rows])  # noqa: E731
    return ModcodTable(
        names=tuple(r["name"] for r in rows),
        spectral_efficiency_bit_sym=column("spectral_efficiency_bit_sym"),
        esn0_ideal_db=column("esn0_ideal_db"),
        sources=tuple(r["source"] for r in rows),
    )


def select_modcod(esn0_db, margin_db=0.0, table=None):
    """Best MODCOD that the Es/N0 allows (ACM), vectorized.

    Row ``i`` is allowed when ``esn0_ideal_db[i] + margin_db <= esn0_db`` (equality
    allowed); of the allowed rows the one of highest spectral efficiency is returned, the
    lower threshold breaking ties.

    Parameters
    ----------
    esn0_db : array_like, any shape
        Link Es/N0 [dB]; NaN (no link) gives -1.
    margin_db : float
        Implementation margin added to every threshold [dB], ``>= 0`` in practice (modem
        losses, phase noise, a safety margin).
    table : ModcodTable, optional
        Default: :func:`modcod_table`.

    Returns
    -------
    ndarray of int, shape of ``esn0_db``
        Row index into the table, -1 where no MODCOD closes the link.
    """
    table = modcod_table() if table is None else table
    thresholds_db, best_row = table._frontier
    x = np.asarray(esn0_db, dtype=float)
    # side="right": a link exactly at threshold + margin counts as allowed.
    pos = np.searchsorted(thresholds_db + margin_db, x, side="right") - 1
    ok = (pos >= 0) & ~np.isnan(x)
    return np.where(ok, best_row[np.clip(pos, 0, None)], -1)


def modcod_spectral_efficiency(index, table=None):
    """Spectral efficiency [bit/symbol] of rows ``index``; 0 where ``index == -1``."""
    table = modcod_table() if table is None else table
    index = np.asarray(index)
    eta = table.spectral_efficiency_bit_sym[np.clip(index, 0, None)]
    return np.where(index >= 0, eta, 0.0)


def modcod_throughput_bps(index, symbol_rate_baud, table=None):
    """Information throughput ``eta_i R_s`` [bit/s] of MODCOD rows ``index``.

    Parameters
    ----------
    index : array_like of int
        Rows from :func:`select_modcod` (-1: outage, throughput 0).
    symbol_rate_baud : array_like
        Symbol rate [baud], broadcastable with ``index``.
    table : ModcodTable, optional
        Default: :func:`modcod_table`.

    Returns
    -------
    ndarray, broadcast shape
        Throughput [bit/s].
    """
    return modcod_spectral_efficiency(index, table) * np.asarray(symbol_rate_baud, dtype=float)


def modcod_names(index, table=None):
    """Names of MODCOD rows ``index`` (``""`` where ``index == -1``), for the trace column."""
    table = modcod_table() if table is None else table
    names = np.array((*table.names, NO_MODCOD), dtype=object)
    index = np.asarray(index)
    return names[np.where(index >= 0, index, len(table.names))]
