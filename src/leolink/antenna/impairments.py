"""Terminal impairments: pointing misalignment, phase-shifter quantization (Sec. 5, Fig. 6 [1]).

Both are Monte Carlo estimates, vectorized over trials, with a caller's ``rng``.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] Reference "Palacios2016" of [1] (hybrid beamforming with few-bit phase
   shifters). leolink implements a simplified two-RF-chain version, not that
   paper's algorithm (see :func:`hybrid_weights`).
"""

from dataclasses import dataclass

import numpy as np

from leolink.antenna.array import steering_vector
from leolink.errors import ConfigError

_DISTRIBUTIONS = ("fixed", "uniform", "gaussian")
_MIN_ELEVATION_RAD = np.radians(20.0)  # default lowest elevation of the quantization study


@dataclass(frozen=True)
class MisalignmentStats:
    """Gain statistics under pointing error, one entry per error value.

    Attributes
    ----------
    error_deg : ndarray, shape (n_err,)
        Error parameter (see :func:`misalignment_gain_db`) [deg].
    mean_db : ndarray, shape (n_err,)
        ``10 log10(E[G])``, average power gain [dB].
    min_db : ndarray, shape (n_err,)
        Smallest gain over the trials [dB].
    percentiles : tuple of float
        Percentile levels [%].
    percentile_db : ndarray, shape (n_err, n_pct)
        Gain percentiles [dB].
    """

    error_deg: np.ndarray
    mean_db: np.ndarray
    min_db: np.ndarray
    percentiles: tuple
    percentile_db: np.ndarray


def _sample_error_rad(error_deg, n_trials, rng, distribution):
    """Pointing-error magnitudes (n_err, n_trials) [rad]."""
    e = np.radians(np.asarray(error_deg, dtype=float))[:, None]
    if distribution == "fixed":
        return np.broadcast_to(e, (e.shape[0], n_trials))
    if distribution == "uniform":
        return e * rng.uniform(0.0, 1.0, (e.shape[0], n_trials))
    # "gaussian": per-axis std e, so the magnitude is Rayleigh(e)
    return e * np.hypot(*rng.standard_normal((2, e.shape[0], n_trials)))


def misalignment_gain_db(
    terminal,
    error_deg,
    n_trials,
    rng,
    elevation_rad=np.pi / 2,
    distribution="fixed",
    percentiles=(1.0, 5.0, 50.0),
):
    """Monte Carlo gain of a terminal whose beam misses the satellite (Fig. 6b).

    The error direction around the satellite direction is uniform in ``[0, 2 pi)``.

    Parameters
    ----------
    terminal : object with ``gain_db(elevation_rad, off_boresight_rad, error_azimuth_rad)``
        E.g. :class:`~leolink.antenna.terminal.UPATerminal` or ``LeakyWave``.
    error_deg : array_like, shape (n_err,)
        Error size [deg]: the exact angle (``"fixed"``), the maximum of a uniform angle
        (``"uniform"``), or the per-axis standard deviation (``"gaussian"``, Rayleigh angle).
    n_trials : int
        Trials per error value.
    rng : numpy.random.Generator
        Random source.
    elevation_rad : float or array_like broadcastable to (n_err, n_trials)
        Satellite elevation [rad].
    distribution : {"fixed", "uniform", "gaussian"}
    percentiles : tuple of float
        Percentile levels to report [%].

    Returns
    -------
    MisalignmentStats
    """
    if distribution not in _DISTRIBUTIONS:
        raise ConfigError(
            f"distribution = {distribution!r} is not allowed; "
            f"use one of {', '.join(_DISTRIBUTIONS)}"
        )
    error_deg = np.atleast_1d(np.asarray(error_deg, dtype=float))
    delta = _sample_error_rad(error_deg, n_trials, rng, distribution)
    psi = rng.uniform(0.0, 2.0 * np.pi, delta.shape)
    g_db = terminal.gain_db(elevation_rad, delta, psi)
    return MisalignmentStats(
        error_deg=error_deg,
        mean_db=10.0 * np.log10(np.mean(10.0 ** (g_db / 10.0), axis=-1)),
        min_db=np.min(g_db, axis=-1),
        percentiles=tuple(percentiles),
        percentile_db=np.percentile(g_db, percentiles, axis=-1).T,
    )


def _quantize(phase_rad, bits):
    """Nearest of the 2^bits phases 2 pi k / 2^bits."""
    step = 2.0 * np.pi / 2**bits
    return step * np.round(phase_rad / step)


def analog_weights(ideal, bits):
    """Fully analog: each element's phase quantized to ``bits`` bits, unit modulus.

    Parameters
    ----------
    ideal : array_like of complex, shape (..., n_el)
        Ideal unit-modulus weights.
    bits : int
        Phase-shifter resolution.

    Returns
    -------
    ndarray of complex, shape (..., n_el)
    """
    return np.exp(1j * _quantize(np.angle(ideal), bits))


def hybrid_weights(ideal, bits, amplitude=None):
    """Two RF chains with ``bits``-bit phase shifters, combined digitally (after [2]).

    The effective weight is ``q1 + c q2``: ``q1, q2`` unit modulus with quantized phases and
    ``c = exp(i pi / 2^bits)`` a digital (baseband) coefficient of chain 2 that offsets its
    phase grid by half a step. Each target ``A e^{i phi}`` is decomposed as
    ``e^{i(phi + t)} + c e^{i(phi - t - pi/2^b)}``, ``t = acos(A / 2)``; each phase is
    rounded down and up and the closest of the 4 sums to the target is kept.

    Parameters
    ----------
    ideal : array_like of complex, shape (..., n_el)
        Ideal unit-modulus weights.
    bits : int
        Phase-shifter resolution.
    amplitude : float, optional
        Target modulus ``A`` in ``(0, 2]`` (the common scale is irrelevant to the gain).
        Default ``|1 + c| = 2 cos(pi / 2^(b+1))``, the modulus of two aligned terms: it
        measured best (24 x 24, b = 2: 0.23 dB loss, vs 0.91 dB with A = 1).

    Returns
    -------
    ndarray of complex, shape (..., n_el)
        Effective per-element weights (modulus in ``[0, 2]``).
    """
    step = 2.0 * np.pi / 2**bits
    c = np.exp(0.5j * step)
    amplitude = abs(1.0 + c) if amplitude is None else amplitude
    phi = np.angle(ideal)[..., None]
    t = np.arccos(0.5 * amplitude)
    a1, a2 = phi + t, phi - t - 0.5 * step
    lo1, lo2 = step * np.floor(a1 / step), step * np.floor(a2 / step)
    cand_1 = np.concatenate([lo1, lo1, lo1 + step, lo1 + step], axis=-1)
    cand_2 = np.concatenate([lo2, lo2 + step, lo2, lo2 + step], axis=-1)
    cand = np.exp(1j * cand_1) + c * np.exp(1j * cand_2)  # (..., n_el, 4)
    best = np.argmin(np.abs(cand - amplitude * np.exp(1j * phi)), axis=-1)
    return np.take_along_axis(cand, best[..., None], axis=-1)[..., 0]


def quantization_loss_db(n_x, n_y, bits, n_trials, rng, min_elevation_rad=_MIN_ELEVATION_RAD):
    """Mean gain loss of the UT UPA under b-bit phase shifters, analog vs hybrid (Fig. 6c).

    Directions are random (azimuth uniform, elevation uniform above ``min_elevation_rad``);
    the ideal beam is the steering vector, gain ``|a^H w|^2 / ||w||^2``, loss
    ``10 log10(N / E[gain])``.

    Parameters
    ----------
    n_x, n_y : int
        UPA size.
    bits : array_like of int, shape (n_bits,)
        Phase-shifter resolutions, e.g. 1..8.
    n_trials : int
        Random directions.
    rng : numpy.random.Generator
        Random source.

    Returns
    -------
    analog_db, hybrid_db : ndarray, shape (n_bits,)
        Mean loss [dB], >= 0.
    """
    el = rng.uniform(min_elevation_rad, np.pi / 2, n_trials)
    az = rng.uniform(0.0, 2.0 * np.pi, n_trials)
    u = np.cos(el)[:, None] * np.stack([np.cos(az), np.sin(az)], axis=-1)
    a = steering_vector(u, n_x, n_y)  # (n_trials, N); ideal weight w = a
    n_el = n_x * n_y

    def loss_db(w):
        gain = np.abs(np.sum(a.conj() * w, axis=-1)) ** 2 / np.sum(np.abs(w) ** 2, axis=-1)
        return 10.0 * np.log10(n_el / np.mean(gain))

    bits = np.atleast_1d(bits)
    analog = np.array([loss_db(analog_weights(a, b)) for b in bits])
    hybrid = np.array([loss_db(hybrid_weights(a, b)) for b in bits])
    return analog, hybrid
