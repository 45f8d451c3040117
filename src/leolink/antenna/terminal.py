"""User-terminal antennas (Sec. 2.1 and 4.1 of [1]): one interface, five models.

Every model has ``gain_db(elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0)``
(broadcasting). ``off_boresight_rad`` is the pointing error of the terminal beam
(angle between the beam and the true satellite direction) and ``error_azimuth_rad`` the
direction of that error around the satellite direction (0: towards higher elevation,
pi/2: sideways); only the array models (UPA, leaky wave) use them.

Array terminals lie flat in the UT panel frame of :mod:`leolink.antenna.panel` (the one
frame of the engine and of pointing errors); a pointing error moves the beam off the
satellite direction by the offsets of :func:`~leolink.antenna.panel.pointing_offsets`
(the satellite taken due east of the panel, so panel x points towards it).

Every model is registered in :data:`TERMINALS` (config ``terminal.kind``) with its
parameter model; the engine relies only on the :class:`TerminalAntenna` protocol.

Below the horizon (``elevation_rad < 0``) the models return the formula value (finite for
the arrays, NaN for the metasurface); callers (the engine) mask those links.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
"""

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.antenna.array import ula_gain, upa_gain
from leolink.antenna.element import DEFAULT_SCAN_EXPONENT, element_factor_lin
from leolink.antenna.panel import pointing_offsets
from leolink.errors import ConfigError
from leolink.registry import Params, Registry

__all__ = [
    "TERMINALS",
    "FixedGain",
    "Isotropic",
    "LeakyWave",
    "Metasurface",
    "TerminalAntenna",
    "TerminalGroups",
    "UPATerminal",
    "leaky_wave_gain_lin",
    "leaky_wave_peak_gain_lin",
    "pruning_terminal",
]


@runtime_checkable
class TerminalAntenna(Protocol):  # pragma: no mutate block (mutants would add protocol members)
    """What the engine needs of a UT antenna steered at its serving satellite.

    ``gain_db(elevation_rad, off_boresight_rad, error_azimuth_rad)`` [dB] broadcasts;
    ``elevation_independent`` says whether it depends on the elevation at all (then the
    engine evaluates it once); ``pattern_lin(du_x, du_y)`` is the linear gain towards a
    direction offset by panel direction cosines from the beam, or None for a model
    without a pattern (it cannot weigh other satellites' beams).

    The whole contract, including what the rest of leolink assumes of the gain:

    - **Smoothness (candidate pruning).** :func:`leolink.engine.screening.screen` bounds
      every pair's SNR with the gain at the screening elevation, which differs from the
      engine's by rounding (~1e-15 rad); its slack covers a gain that changes by less than
      1e-6 dB per 1e-12 rad. A model whose gain jumps (a stepped or tabulated pattern)
      sets ``smooth_gain = False`` and gives ``max_gain_db``: the pruning then bounds its
      gain by that maximum (exact, less tight). ``smooth_gain`` is optional (default
      True); a model with ``smooth_gain = False`` and no ``max_gain_db`` is refused when
      the scenario is built (:func:`pruning_terminal`).
    - **Maximum gain.** ``max_gain_db`` (optional, [dB]): no ``gain_db`` exceeds it, at
      any elevation, pointing error or UT.
    - **Fading reference gain.** With ``link.fading = "rician"`` the linear
      ``10^(gain_db / 10)`` of the serving link is taken as the LoS combining gain ``N``
      of Eq. (17) (:mod:`leolink.link.fading`), and the draws are normalized by the mean
      ``N + 1/K``: the fading has mean 1 whatever the model, and the gain stays the
      terminal's mean gain.
    """

    @property
    def elevation_independent(self) -> bool: ...  # an attribute, or a property

    @property
    def pattern_lin(self) -> Callable[..., np.ndarray] | None: ...  # a method, or None

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0): ...


def pruning_terminal(terminal, where=None):
    """The terminal whose gain the candidate pruning takes as a bound of ``terminal``'s.

    ``terminal`` itself where its gain is smooth (``smooth_gain``, default True); a
    :class:`FixedGain` at its ``max_gain_db`` where it is not; per member of a
    :class:`TerminalGroups`.

    Raises
    ------
    ConfigError
        A terminal with ``smooth_gain = False`` and no ``max_gain_db`` (``where`` names
        it in the message, e.g. ``"terminal.kind = 'stepped'"``).
    """
    if isinstance(terminal, TerminalGroups):
        members = [pruning_terminal(t, where) for t in terminal.terminals]
        if all(m is t for m, t in zip(members, terminal.terminals, strict=True)):
            return terminal
        return TerminalGroups(members, terminal.group)
    if getattr(terminal, "smooth_gain", True):
        return terminal
    peak_db = getattr(terminal, "max_gain_db", None)
    if peak_db is None:
        raise ConfigError(
            f"{where or type(terminal).__name__} is not allowed: its gain is not smooth "
            "(smooth_gain = False) and it gives no max_gain_db, which the candidate pruning "
            "needs to bound it (the TerminalAntenna protocol)"
        )
    return FixedGain(float(peak_db))


#: Terminal antennas by config name (``terminal.kind``).
TERMINALS: Registry[TerminalAntenna] = Registry("terminal.kind", protocol=TerminalAntenna)


def _panel_field(doc):
    return Field(24, ge=1, le=4096, description=doc)


def _scan_fields():
    return {
        "scan_loss": Field(
            False,
            description="weigh the panel's gain by the element factor cos(theta)^q of the angle "
            "off the panel normal (flat-panel scan loss); false: the paper's constant gain",
        ),
        "element_exponent": Field(
            DEFAULT_SCAN_EXPONENT,
            ge=0.0,
            le=20.0,
            description="q of the element factor cos^q (1.2: the Kymeta roll-off the paper "
            "quotes, Sec. 2.1; 1: the projected aperture)",
        ),
    }


class UpaConfig(Params):
    n_x: int = _panel_field("elements along x")
    n_y: int = _panel_field("elements along y")
    scan_loss: bool = _scan_fields()["scan_loss"]
    element_exponent: float = _scan_fields()["element_exponent"]


class LeakyWaveConfig(Params):
    n_x: int = _panel_field("elements along x")
    n_y: int = _panel_field("elements along y")
    leakage: float = Field(0.05, gt=0.0, le=10.0, description="amplitude decay per element [Np]")
    scan_loss: bool = _scan_fields()["scan_loss"]
    element_exponent: float = _scan_fields()["element_exponent"]


def _element_lin(panel, elevation_rad):
    """Element factor of a flat panel towards a satellite at ``elevation_rad`` (1 without
    scan loss): ``cos(90 deg - el)^q`` = ``sin(el)^q``, 0 below the panel plane."""
    if not panel.scan_loss:
        return 1.0
    return element_factor_lin(
        0.5 * np.pi - np.asarray(elevation_rad, float), panel.element_exponent
    )


class MetasurfaceConfig(Params):
    peak_gain_db: float = Field(33.0, ge=-20.0, le=80.0, description="gain at broadside [dB]")
    rolloff: float = Field(1.2, ge=0.0, le=20.0, description="cos-power scan roll-off")


def leaky_wave_gain_lin(du, n, leakage):
    """Gain of an n-element line with weights ``exp(-leakage k)``, steered off by ``du``.

    ``|sum_k e^{-a k} e^{i pi k du}|^2 / sum_k e^{-2 a k} = |1 - z^n|^2 / |1 - z|^2 / S``,
    ``z = e^{-a + i pi du}``, ``S = (1 - e^{-2 a n}) / (1 - e^{-2 a})``. At ``du = 0`` this is
    the paper's closed form ``(1 - e^{-a n})(1 + e^{-a}) / ((1 + e^{-a n})(1 - e^{-a}))``
    (Sec. 2.1); ``a -> 0`` gives the Dirichlet kernel (limit used for ``a < 1e-12``).

    Parameters
    ----------
    du : array_like
        Direction-cosine offset from the beam [-].
    n : int
        Elements along the axis.
    leakage : float
        Amplitude decay per element ``a`` [Np/element], ``>= 0``.

    Returns
    -------
    ndarray
        Linear gain, ``<= coth(a / 2)`` and ``<= n``.
    """
    a = float(leakage)
    if a < 1e-12:
        return ula_gain(du, n)
    z = np.exp(-a + 1j * np.pi * np.asarray(du, dtype=float))
    s = -np.expm1(-2 * a * n) / -np.expm1(-2 * a)
    return np.abs(1.0 - z**n) ** 2 / np.abs(1.0 - z) ** 2 / s


def leaky_wave_peak_gain_lin(n, leakage):
    """The paper's closed form per dimension, ``(1-e^{-an})(1+e^{-a}) / ((1+e^{-an})(1-e^{-a}))``.

    Equals ``tanh(a n / 2) coth(a / 2)``; the limit ``a -> 0`` is ``n``.
    """
    a = np.asarray(leakage, dtype=float)
    safe = np.where(a > 0, a, 1.0)
    return np.where(a > 0, np.tanh(safe * n / 2) / np.tanh(safe / 2), n)


@TERMINALS.register("isotropic")
@dataclass(frozen=True)
class Isotropic:
    """0 dBi in every direction."""

    #: The gain towards the satellite does not depend on its elevation.
    elevation_independent = True

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Gain [dB] = 0, broadcast shape of the inputs."""
        shape = np.broadcast_shapes(*(np.shape(a) for a in (elevation_rad, off_boresight_rad)))
        return np.zeros(shape)

    def pattern_lin(self, du_x, du_y):
        """Gain towards a direction offset by ``(du_x, du_y)`` from the beam: 1."""
        return np.ones(np.broadcast_shapes(np.shape(du_x), np.shape(du_y)))


class FixedGainConfig(Params):
    gain_dbi: float = Field(
        0.0,
        ge=-20.0,
        le=80.0,
        description="gain towards the serving satellite at every elevation [dBi] (TR 38.821 "
        "Table 6.1.1.1-3: 39.7 dBi VSAT in Ka band, 0 dBi handheld in S band)",
    )


@TERMINALS.register("fixed", config=FixedGainConfig)
@dataclass(frozen=True)
class FixedGain:
    """A terminal specified by its gain only (with ``[link]`` antenna temperature and noise
    figure: by its G/T, as TR 38.821 Table 6.1.1.1-3 specifies UEs): ``gain_dbi`` towards
    the serving satellite, whatever the elevation; no pattern (pointing errors ignored, it
    cannot weigh other satellites' beams)."""

    gain_dbi: float = 0.0
    elevation_independent = True
    pattern_lin = None

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Gain [dB] = ``gain_dbi``, broadcast shape of the inputs."""
        shape = np.broadcast_shapes(*(np.shape(a) for a in (elevation_rad, off_boresight_rad)))
        return np.full(shape, float(self.gain_dbi))


@TERMINALS.register(
    "upa",
    config=UpaConfig,
    build=lambda p, ctx: UPATerminal(
        p.n_x, p.n_y, getattr(ctx, "rician_k", np.inf), p.scan_loss, p.element_exponent
    ),
)
@dataclass(frozen=True)
class UPATerminal:
    """Half-wavelength ``n_x x n_y`` UPA, unit-modulus weights (Sec. 2.1, 4.1).

    Average gain with Rician factor K (Sec. 4.1): ``E[max_w |<a_u(v), w>|^2/||w||^2] + 1/K
    = N + 1/K`` (24 x 24, K = 10: 27.60 dB). With a pointing error the LoS term becomes
    the UPA Dirichlet gain off the beam; the diffuse term ``1/K`` (Sigma = I) stays.

    ``scan_loss``: the LoS term is weighed by the element factor ``cos(theta)^q`` of the
    satellite's angle off the panel normal (:mod:`leolink.antenna.element`; a panel lying
    flat: ``theta = 90 deg - el``), so ``N sin(el)^q + 1/K`` on the beam. The diffuse term
    arrives from all directions and keeps ``1/K``. ``pattern_lin`` stays the array factor
    relative to the beam (other satellites' beams are weighed without the element factor,
    see docs/errata.md).
    """

    n_x: int
    n_y: int
    rician_k: float = np.inf
    scan_loss: bool = False
    element_exponent: float = DEFAULT_SCAN_EXPONENT

    @property
    def elevation_independent(self):
        """Steered at the satellite: without scan loss (the paper) and without a pointing
        error the gain does not depend on the elevation."""
        return not self.scan_loss

    def gain_lin(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Linear average gain ``G_LoS(du) g_e(theta) + 1/K`` (Eq. (17) of the paper)."""
        du = pointing_offsets(elevation_rad, off_boresight_rad, error_azimuth_rad)
        los = upa_gain(du[0], du[1], self.n_x, self.n_y) * _element_lin(self, elevation_rad)
        return los + 1.0 / self.rician_k

    def pattern_lin(self, du_x, du_y):
        """Linear gain towards a direction ``(du_x, du_y)`` off the beam, in the panel's
        direction cosines: ``G_LoS(du) + 1/K`` (the diffuse part does not depend on it)."""
        return upa_gain(du_x, du_y, self.n_x, self.n_y) + 1.0 / self.rician_k

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Average receive gain [dB], broadcast shape of the inputs."""
        return 10.0 * np.log10(self.gain_lin(elevation_rad, off_boresight_rad, error_azimuth_rad))


@TERMINALS.register("leaky_wave", config=LeakyWaveConfig)
@dataclass(frozen=True)
class LeakyWave:
    """CRLH leaky-wave flat panel, weights decaying as ``e^{-leakage n}`` per dimension (Sec. 2.1).

    ``leakage`` is the amplitude decay per element (leolink's convention; the paper's weight
    formula would give ``leakage / 2`` per half-wavelength element, see docs/errata.md).
    The gain never exceeds the threshold ``coth(leakage / 2)^2`` however large the panel.
    ``rician_k`` adds the diffuse term ``1/K`` as for the UPA (default: none);
    ``scan_loss`` the element factor ``cos(theta)^q`` as for the UPA.
    """

    n_x: int
    n_y: int
    leakage: float
    rician_k: float = np.inf
    scan_loss: bool = False
    element_exponent: float = DEFAULT_SCAN_EXPONENT

    @property
    def elevation_independent(self):
        """Steered at the satellite, as the UPA: constant gain without scan loss."""
        return not self.scan_loss

    def gain_lin(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Linear gain, product of the two tapered line kernels (times the element
        factor with scan loss) plus ``1/K``."""
        du = pointing_offsets(elevation_rad, off_boresight_rad, error_azimuth_rad)
        los = self._array_lin(*du) * _element_lin(self, elevation_rad)
        return los + 1.0 / self.rician_k

    def _array_lin(self, du_x, du_y):
        gx = leaky_wave_gain_lin(du_x, self.n_x, self.leakage)
        return gx * leaky_wave_gain_lin(du_y, self.n_y, self.leakage)

    def pattern_lin(self, du_x, du_y):
        """Linear gain towards a direction ``(du_x, du_y)`` off the beam (panel frame)."""
        return self._array_lin(du_x, du_y) + 1.0 / self.rician_k

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Gain [dB], broadcast shape of the inputs."""
        return 10.0 * np.log10(self.gain_lin(elevation_rad, off_boresight_rad, error_azimuth_rad))


@TERMINALS.register("metasurface", config=MetasurfaceConfig)
@dataclass(frozen=True)
class Metasurface:
    """Kymeta-like metasurface: ``peak_gain_db + rolloff 10 log10(sin el)`` (cos^r scan roll-off).

    The scan angle from the panel normal is ``90 deg - el``, so ``cos(scan)^r = sin(el)^r``
    and the gain **falls** at low elevation. The paper prints ``33 - 1.2 * 10 log10(sin el)``
    (Sec. 2.1), which rises at low elevation; leolink corrects the sign (docs/errata.md).
    No array factor is known, so pointing errors are ignored. ``el <= 0`` gives -inf/NaN.
    """

    peak_gain_db: float = 33.0
    rolloff: float = 1.2
    elevation_independent = False
    pattern_lin = None  # no array factor: it cannot weigh other satellites' beams

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Gain [dB], broadcast shape of ``elevation_rad`` and ``off_boresight_rad``."""
        el = np.asarray(elevation_rad, dtype=float) + 0.0 * np.asarray(off_boresight_rad)
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.peak_gain_db + self.rolloff * 10.0 * np.log10(np.sin(el))


class TerminalGroups:
    """Different UT antennas for different UTs (one per population), behind one interface.

    The engine calls ``gain_db(elevation_rad)`` and ``pattern_lin(du_x, du_y)`` with the UT
    axis first, ``(n_ut, ...)``; each group's antenna answers for its UTs. Not
    ``elevation_independent`` (the gains differ per UT, so the engine cannot take one
    constant); an elevation-independent member is evaluated once for all its UTs.

    Parameters
    ----------
    terminals : sequence of TerminalAntenna
        The distinct antennas.
    group : array_like of int, shape (n_ut,)
        Index into ``terminals`` of each UT's antenna.
    """

    elevation_independent = False

    def __init__(self, terminals, group):
        self.terminals = tuple(terminals)
        self.group = np.asarray(group, np.int64)
        self._rows = [np.flatnonzero(self.group == g) for g in range(len(self.terminals))]
        if any(r.size == 0 for r in self._rows) or self.group.min(initial=0) < 0:
            raise ValueError("TerminalGroups: every terminal needs UTs, every UT a terminal")
        if all(t.pattern_lin is not None for t in self.terminals):
            self.pattern_lin = self._pattern_lin
        else:
            self.pattern_lin = None

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        """Receive gain [dB], shape of ``elevation_rad`` (n_ut, ...): each UT's antenna."""
        el = np.asarray(elevation_rad, float)
        out = np.empty(el.shape)
        for term, rows in zip(self.terminals, self._rows, strict=True):
            if term.elevation_independent:
                out[rows] = float(term.gain_db(np.pi / 2))
            else:
                out[rows] = term.gain_db(el[rows], off_boresight_rad, error_azimuth_rad)
        return out

    def _pattern_lin(self, du_x, du_y):
        """Linear gain towards offsets ``(du_x, du_y)`` (n_ut, ...) of each UT's antenna."""
        du_x, du_y = np.broadcast_arrays(np.asarray(du_x, float), np.asarray(du_y, float))
        out = np.empty(du_x.shape)
        for term, rows in zip(self.terminals, self._rows, strict=True):
            out[rows] = term.pattern_lin(du_x[rows], du_y[rows])
        return out

    def __repr__(self):
        return f"TerminalGroups({list(self.terminals)!r}, n_ut={self.group.size})"
