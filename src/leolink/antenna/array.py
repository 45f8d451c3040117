"""Half-wavelength uniform planar arrays and the partially connected hybrid array (Sec. 2.1).

Directions and beams are direction cosines ``(u_x, u_y)`` in the satellite body frame
(``x`` along-track, ``y`` cross-track). The steering vector of a half-wavelength UPA is

    [a(u)]_n = exp(-i pi (n_x u_x + n_y u_y)),

(the paper's ``exp(-i 2 pi / lambda <k_n, v>)`` with ``k_n = (lambda / 2) (n_x, n_y, 0)``).
Gains are normalized: ``|a^H f|^2 / ||f||^2``, so the peak equals the number of elements
that the beam drives (``12 x 24 = 288``, 24.59 dB, for the paper's subarray).

A DFT beam ``f = a(b)`` is separable, so its gain in direction ``u`` is a product of two
Dirichlet kernels, ``ula_gain(u_x - b_x, n_x) * ula_gain(u_y - b_y, n_y)``;
:func:`explicit_gain` is the brute-force reference that the tests compare against.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
"""

from dataclasses import dataclass

import numpy as np

import leolink.compiled
from leolink.arrays import nonzero_2d
from leolink.errors import ConfigError, require_at_least

# |sin(pi du / 2)| below which the Dirichlet kernel is replaced by its limit n: the
# relative error of the limit is (n^2 - 1) x^2 / 3 < 1e-13 for n <= 1e3 at x = 1e-8.
_SIN_TINY = 1e-8
# |sin| below which the fast (angle-addition) kernel is recomputed directly: the
# angle-addition formula loses ~1e-15 / |sin| relative accuracy by cancellation (the
# numerator's argument n x is up to ~10 rad), so 5e-6 keeps the kernel within 4e-10 of
# the exact value while the slow path runs for ~1 direction in 10^4.
_SIN_RECOMPUTE = 5e-6
# Directions per chunk in beam_gain_lin (temporaries stay in cache).
_CHUNK = 1024


@leolink.compiled.jitable
def ula_gain(du, n):
    """Normalized gain of an n-element half-wavelength ULA steered off by ``du``.

    ``|sum_{k=0}^{n-1} exp(i pi k du)|^2 / n = sin^2(n pi du / 2) / (n sin^2(pi du / 2))``
    (Dirichlet kernel). ``du`` is first reduced modulo 2 (the kernel has period 2 in
    ``du``, grating lobes at ``du = +-2``), so ``sin`` never loses precision next to a
    grating lobe; where ``|sin(pi du / 2)|`` is tiny the limit ``n`` is used (no 0/0).

    Parameters
    ----------
    du : array_like
        Direction-cosine offset from the beam, ``u - u_beam`` [-], any real value.
    n : int or array_like of int
        Number of elements, broadcastable with ``du``.

    Returns
    -------
    ndarray, broadcast shape of the inputs
        Linear gain in ``[0, n]``; ``n`` at ``du = 0`` and at the grating lobes ``du = +-2``.
    """
    # Arithmetic and ufuncs only: numpy arrays and the compiled loops' scalars alike.
    du = np.float64(du)  # float64 whatever the input (float32, ints, a list)
    x = 0.5 * np.pi * (du - 2.0 * np.rint(0.5 * du))  # in [-pi/2, pi/2]; exact (Sterbenz)
    s = np.sin(x)
    small = np.abs(s) < _SIN_TINY  # the limit n there: s + small = 1 + s, no 0 / 0
    g = np.sin(n * x) ** 2 / (n * (s + small) ** 2)
    return np.minimum(g + small * (n - g), n)  # (rounding may overshoot n by an ulp)


def upa_gain(dux, duy, nx, ny):
    """Normalized gain of an ``nx x ny`` half-wavelength UPA, ``ula(dux, nx) ula(duy, ny)``.

    Parameters
    ----------
    dux, duy : array_like
        Direction-cosine offsets from the beam along x and y [-], broadcastable.
    nx, ny : int
        Elements along x and y.

    Returns
    -------
    ndarray, broadcast shape
        Linear gain in ``[0, nx ny]``.
    """
    return ula_gain(dux, nx) * ula_gain(duy, ny)


def steering_vector(u_xy, nx, ny):
    """Explicit UPA steering vector ``[a(u)]_n = exp(-i pi (n_x u_x + n_y u_y))`` (Sec. 2.2).

    Parameters
    ----------
    u_xy : array_like, shape (..., 2)
        Direction cosines ``(u_x, u_y)`` in the array (body) frame [-].
    nx, ny : int
        Elements along x and y.

    Returns
    -------
    ndarray of complex, shape (..., nx * ny)
        Element ``n = i_x * ny + i_y`` (x-major order, as :meth:`HybridArray.rf_index`).
    """
    u_xy = np.asarray(u_xy, dtype=float)
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    phase = ix.ravel() * u_xy[..., 0:1] + iy.ravel() * u_xy[..., 1:2]
    return np.exp(-1j * np.pi * phase)


def explicit_gain(u_xy, weights, nx, ny):
    """Reference gain ``|a(u)^H f|^2 / ||f||^2`` by the explicit steering-vector product.

    Parameters
    ----------
    u_xy : array_like, shape (..., 2)
        Directions [-].
    weights : array_like of complex, shape (nx * ny, n_beam)
        Beamforming vectors ``f`` as columns (e.g. ``F_RF``), element order as
        :func:`steering_vector`.
    nx, ny : int
        Elements along x and y of the whole array.

    Returns
    -------
    ndarray, shape (..., n_beam)
        Linear gain.
    """
    f = np.asarray(weights, dtype=complex)
    a = steering_vector(u_xy, nx, ny)
    return np.abs(a.conj() @ f) ** 2 / np.sum(np.abs(f) ** 2, axis=0)


@leolink.compiled.jitable
def dirichlet_trig(u, n):
    """``(sin x, cos x, sin n x, cos n x)`` of ``x = pi u / 2``: all that
    :func:`subtracted_gain` needs of a direction ``u`` (an array: four arrays of its shape;
    a compiled loop's scalar: four scalars). Given to :func:`dirichlet_kernels` again, it
    spares the sines of directions met before (e.g. the ROI samples of a codebook search).
    """
    x = (0.5 * np.pi) * np.float64(u)
    xn = x * n
    return np.sin(x), np.cos(x), np.sin(xn), np.cos(xn)


@leolink.compiled.jitable
def subtracted_gain(trig, coef, n):
    """:func:`ula_gain` ``(u - b, n)`` by angle subtraction: ``sin(n (x - b))^2 / (n
    sin(x - b)^2)`` with ``sin(x - b) = cos b sin x - sin b cos x`` (and the same of
    ``n x``, ``n b``), from ``trig = dirichlet_trig(u, n)`` and ``coef =
    (cos b, -sin b, cos n b, -sin n b)`` (:func:`dirichlet_coefficients`): four sines per
    direction whatever the number of beams.

    Returns ``(g, near)``: ``near`` where ``|sin(x - b)| < 5e-6``, where the subtraction
    cancels (~1e-16 / |sin| relative) and the caller takes :func:`ula_gain` instead; ``g``
    is finite there (no 0 / 0). Arrays broadcast (``coef[i]`` (k, 1) against ``trig[i]``
    (m,) gives (k, m)); scalars in the compiled loops.
    """
    den = coef[0] * trig[0] + coef[1] * trig[1]
    num = coef[2] * trig[2] + coef[3] * trig[3]
    near = np.abs(den) < _SIN_RECOMPUTE
    g = num / (den + near)
    return np.minimum(g * g * (1.0 / n), n), near  # rounding may overshoot n by ~1 ulp


def dirichlet_kernels(u, beam_u, n, trig=None):
    """Dirichlet kernels of ``u (m,)`` against each ``beam_u (k,)`` -> (k, m).

    :func:`subtracted_gain` of every (beam, direction), the four sines of each direction
    once (:func:`dirichlet_trig`, or ``trig`` if given: those of ``u`` and ``n``); where
    it cancels (at a beam peak or a grating lobe) :func:`ula_gain` of those few entries.
    Where the compiled loops run (:mod:`leolink.compiled`) a 1-D ``u`` takes
    :func:`_dirichlet_rows`, the same functions per entry without the (k, m) temporaries;
    the two agree to ~1e-13 of the peak (``tests/test_array_kernels.py``).
    """
    u = np.asarray(u, dtype=float)
    beam_u = np.asarray(beam_u, dtype=float)
    k = beam_u.size
    coef = dirichlet_coefficients(beam_u, n)
    if u.ndim == 1 and k and leolink.compiled.use(u.size):
        g = np.empty((k, u.size))
        _dirichlet_rows(u, (beam_u, coef, float(n)), g, 0, u.size)  # (one thread: no pool)
        return g
    trig = dirichlet_trig(u, n) if trig is None else trig
    with np.errstate(divide="ignore", invalid="ignore"):  # the near entries are redone below
        g, near = subtracted_gain(trig, coef[:, :, None], n)
    if near.any():
        kk, mm = nonzero_2d(near)
        g[kk, mm] = ula_gain(u[mm] - beam_u[kk], n)
    return g


@leolink.compiled.jitable
def kernels_of_direction(u, beams, out, p):
    """``out[:, p]``: the kernels of the direction ``u`` (a scalar) against the beams
    ``(beam_u (k,), coef (4, k), n)`` as :func:`dirichlet_kernels` computes them (the
    compiled loops' per-direction step)."""
    beam_u, coef, n = beams
    trig = dirichlet_trig(u, n)
    for j in range(beam_u.size):
        g, near = subtracted_gain(trig, coef[:, j], n)
        out[j, p] = ula_gain(u - beam_u[j], n) if near else g


@leolink.compiled.jit
def _dirichlet_rows(u, beams, out, lo, hi):
    """:func:`kernels_of_direction` of each direction ``lo .. hi - 1``, into ``out``."""
    for p in range(lo, hi):
        kernels_of_direction(u[p], beams, out, p)


def dirichlet_coefficients(beam_u, n):
    """The angle-subtraction coefficients of :func:`subtracted_gain`, shape (4, k):
    ``(cos b, -sin b, cos n b, -sin n b)`` of ``b = pi beam_u / 2``."""
    b = (0.5 * np.pi) * np.asarray(beam_u, dtype=float)
    return np.stack([np.cos(b), -np.sin(b), np.cos(n * b), -np.sin(n * b)])


def beam_gain_lin(u_xy, beam_u_xy, n_sub_x, n_sub_y):
    """Closed-form gains of DFT beams of an ``n_sub_x x n_sub_y`` subarray (Eqs. (14), (15)).

    The beams lie on a lattice, so the x-kernels are evaluated once per distinct beam
    ``u_x`` and the y-kernels once per distinct beam ``u_y``, then multiplied (a 5 x 3
    grid costs 8 kernels, not 15 x 2).

    Parameters
    ----------
    u_xy : array_like, shape (..., 2)
        Directions ``(u_x, u_y)`` in the body frame [-].
    beam_u_xy : array_like, shape (n_beam, 2)
        Beam boresights [-].
    n_sub_x, n_sub_y : int
        Elements of the subarray that drives each beam.

    Returns
    -------
    ndarray, shape (..., n_beam)
        Linear gain ``|a^H f|^2 / ||f||^2``, peak ``n_sub_x n_sub_y``.
    """
    u_xy = np.asarray(u_xy, dtype=float)
    beam_u_xy = np.asarray(beam_u_xy, dtype=float).reshape(-1, 2)
    bx, inv_x = np.unique(beam_u_xy[:, 0], return_inverse=True)
    by, inv_y = np.unique(beam_u_xy[:, 1], return_inverse=True)
    flat = u_xy.reshape(-1, 2)
    out = np.empty((flat.shape[0], beam_u_xy.shape[0]))
    # Cache-sized chunks: whole-array temporaries are memory bound and 2-3x slower.
    for start in range(0, flat.shape[0], _CHUNK):
        part = flat[start : start + _CHUNK].T
        kx = dirichlet_kernels(part[0], bx, n_sub_x)
        ky = dirichlet_kernels(part[1], by, n_sub_y)
        out[start : start + _CHUNK] = (kx[inv_x.ravel()] * ky[inv_y.ravel()]).T
    return out.reshape(u_xy.shape[:-1] + (beam_u_xy.shape[0],))


@dataclass(frozen=True)
class HybridArray:
    """Partially connected hybrid UPA: ``n_rf_x x n_rf_y`` subarrays, one RF chain each (Sec. 2.1).

    Attributes
    ----------
    n_x, n_y : int
        Elements of the whole array along x (along-track) and y.
    n_rf_x, n_rf_y : int
        RF chains (subarrays) along x and y; must divide ``n_x`` and ``n_y``.
    """

    n_x: int
    n_y: int
    n_rf_x: int
    n_rf_y: int

    def __post_init__(self):
        for name in ("n_x", "n_y", "n_rf_x", "n_rf_y"):
            require_at_least(f"antenna.{name}", getattr(self, name), 1, "a positive count")
        for n, n_rf, axis in ((self.n_x, self.n_rf_x, "x"), (self.n_y, self.n_rf_y, "y")):
            if n % n_rf:
                raise ConfigError(
                    f"antenna.n_rf_{axis} = {n_rf!r} does not divide antenna.n_{axis} = {n!r}; "
                    f"the subarrays must tile the array (use a divisor of {n})"
                )

    @property
    def n_sub_x(self):
        """Subarray elements along x, ``N_x^sub = N_x^sat / N_x^RF``."""
        return self.n_x // self.n_rf_x

    @property
    def n_sub_y(self):
        """Subarray elements along y, ``N_y^sub = N_y^sat / N_y^RF``."""
        return self.n_y // self.n_rf_y

    @property
    def n_rf(self):
        """Number of RF chains (= subarrays = simultaneous beams)."""
        return self.n_rf_x * self.n_rf_y

    def rf_index(self):
        """The paper's index function ``I_RF(n)``: RF chain of each element (0-based).

        Returns
        -------
        ndarray of int, shape (n_x * n_y,)
            Element ``n = i_x * n_y + i_y`` -> chain
            ``m = (i_x // n_sub_x) * n_rf_y + i_y // n_sub_y``.
        """
        ix, iy = np.meshgrid(np.arange(self.n_x), np.arange(self.n_y), indexing="ij")
        return ((ix // self.n_sub_x) * self.n_rf_y + iy // self.n_sub_y).ravel()

    def precoder(self, beam_u_xy):
        """Block-sparse analog precoder ``F_RF`` (Sec. 2.1 and 3.2), explicit reference.

        Column ``m`` holds DFT beam ``m`` on the elements of subarray ``m`` and zeros elsewhere:
        ``[F_RF]_{n, m} = exp(-i pi (n_x b_{m,x} + n_y b_{m,y}))`` if ``I_RF(n) = m``.

        Parameters
        ----------
        beam_u_xy : array_like, shape (n_rf, 2)
            Beam ``m`` boresight, driven by RF chain ``m`` [-].

        Returns
        -------
        ndarray of complex, shape (n_x * n_y, n_rf)
        """
        beam_u_xy = np.asarray(beam_u_xy, dtype=float).reshape(-1, 2)
        if beam_u_xy.shape[0] != self.n_rf:
            raise ConfigError(
                f"precoder got {beam_u_xy.shape[0]} beams; the array has n_rf = {self.n_rf} "
                "RF chains (one beam per chain)"
            )
        full = steering_vector(beam_u_xy, self.n_x, self.n_y).T  # (n_el, n_rf)
        mask = self.rf_index()[:, None] == np.arange(self.n_rf)[None, :]
        return np.where(mask, full, 0.0)
