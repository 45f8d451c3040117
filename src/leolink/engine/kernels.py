"""The compiled kernels of the engine (``leolink._kernels``, C; imported by
:mod:`leolink.engine.jit` only, when the extension is built).

Each kernel is the fused loop of a numpy function of the engine and repeats its floating
point operations one for one, in the same order (``src/leolink/_kernels.c``), so that a
pair gets the same bits from either: a sum of three products is ``(p0 + p2) + p1`` (what
``numpy.einsum`` does over a length-3 axis), the Dirichlet angle subtraction
``fma(c1, t1, c0 t0)`` (what the BLAS product of ``dirichlet_kernels`` does for up to 16
beams an axis; with more, OpenBLAS rounds the last ``m mod 4`` pairs without the fused
multiply-add: ~1e-13 relative apart, ``leolink.antenna.array.dirichlet_kernels``), the
transcendental functions are the C library's (as numpy's float64 loops on x86-64 without
AVX-512; with AVX-512 numpy takes ``arcsin``, ``arctan2``, ``log10``, ``log1p``, ``exp``
and ``power`` from Intel's SVML, a few ulp away, so that the two paths then differ in the
last bits). ``tests/test_jit.py`` checks the equality bit for bit where numpy's loops are
the C library's, to a few ulp elsewhere (``tests/platform_math.py``).

Every kernel fills the rows ``lo .. hi - 1`` of its outputs without the GIL
(:func:`leolink.compiled.run_rows` splits a large call over threads):

- ``links_kernel``: the geometry and beam kernels of ``LinkEngine.evaluate_pairs``, per pair;
- ``snr_kernel``: ``Links.snr_db_bm``, ``(10 log10 k_x + 10 log10 k_y) + 10 log10 p``;
- ``best_beam_kernel``: ``numpy.argmax`` of ``Links.snr_db_bm`` over the beams and that
  beam's dB value, without the (n_beam, m) matrix. Every beam's linear SNR ``(k_x k_y) p``
  is computed and the largest kept, with the second largest. Where the second is below
  ``1 - 1e-9`` times the largest (every pair but near ties), the largest is the dB argmax
  as well: exactly, its SNR is then above the others by 4.3e-9 dB at least (the products
  err by a few 1e-16, relative), and the dB values as computed err by < 1e-10 dB (C library
  ``log10`` <= 2 ulp, terms below 1e4 dB: ~1e-11 dB), so only its dB value is computed.
  That holds where every product near the largest is a normal number (a path in [1e-150,
  1e150], the largest in [1e-100, 1e100]); elsewhere, near ties and NaN kernels, every
  beam's dB value is computed and ``numpy.argmax``'s rule applied (the first NaN, else
  the first maximum); a pair not visible (NaN path) gets beam 0 and NaN;
- ``serve_kernel``: ``LinkEngine.serve_pairs`` for a full beam lattice with one colour,
  per row, ``out`` (16, n) in the order of ``SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS``;
- ``screen_ragged``: ``screening.screen``'s codes, bounds and sin(elevation), per UT row,
  each UT with its group's satellites (:func:`screening.screen_ragged`; ``screen``: one
  group of every satellite).
  It rounds differently from the numpy code: both bounds are rigorous, and it decides which
  pairs are evaluated, never a value that reaches an output.
"""

from __future__ import annotations

from leolink import _kernels
from leolink.antenna.array import _SIN_RECOMPUTE, _SIN_TINY

__all__ = ["best_beam_kernel", "links_kernel", "screen_ragged", "serve_kernel", "snr_kernel"]

snr_kernel = _kernels.snr_kernel
best_beam_kernel = _kernels.best_beam_kernel
serve_kernel = _kernels.serve_kernel
screen_ragged = _kernels.screen_ragged


def links_kernel(ut_pos, ut_up, sphere, r_ut, sat_pos, ax_x, ax_y, ut, sat, min_el, bx, cx, nx,
                 by, cy, ny, rel, rho2, rho, elevation, visible, kx, ky, lo, hi):  # fmt: skip
    """The geometry and beam kernels of ``LinkEngine.evaluate_pairs``, of the pairs
    ``lo .. hi - 1`` (``dirichlet_kernels`` with ``leolink.antenna.array``'s thresholds)."""
    _kernels.links_kernel(ut_pos, ut_up, sphere, r_ut, sat_pos, ax_x, ax_y, ut, sat, min_el,
                          bx, cx, nx, by, cy, ny, rel, rho2, rho, elevation, visible, kx, ky,
                          lo, hi, _SIN_RECOMPUTE, _SIN_TINY)  # fmt: skip
