"""numba kernels of the engine (imported by :mod:`leolink.engine.jit` only, numba required).

Each kernel is the fused loop of a numpy function of the engine and repeats its floating
point operations one for one, in the same order, so that a pair gets the same bits from
either: a sum of three products is ``(p0 + p2) + p1`` (what ``numpy.einsum`` does over a
length-3 axis), the Dirichlet angle subtraction ``fma(c1, t1, c0 t0)`` (what the BLAS
product of ``dirichlet_kernels`` does), the transcendental functions are the C library's
(as numpy's float64 loops on x86-64 without AVX-512; with AVX-512 numpy takes ``arcsin``,
``arctan2``, ``log10``, ``log1p``, ``exp`` and ``power`` from Intel's SVML, a few ulp
away, so that the two paths then differ in the last bits). ``tests/test_jit.py`` checks
the equality bit for bit where numpy's loops are the C library's, to a few ulp elsewhere
(``tests/platform_math.py``).
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from leolink.antenna.array import _SIN_RECOMPUTE, _SIN_TINY

_HALF_PI = 0.5 * np.pi
_CHUNK = 2048  # pairs per parallel task where a kernel needs scratch arrays
_SCREEN_HALF_PI = 1.5707963267948966


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (the hardware FMA, as BLAS uses it)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@numba.njit(cache=True, inline="always")
def _dot3(a0, a1, a2, b0, b1, b2):
    """``numpy.einsum('k,k->', a, b)`` over three values: ``(a0 b0 + a2 b2) + a1 b1``."""
    return (a0 * b0 + a2 * b2) + a1 * b1


@numba.njit(cache=True, inline="always")
def _ula_gain(du, n):
    """``leolink.antenna.array.ula_gain`` of one offset (numpy's operations, in order)."""
    du_red = du - 2.0 * np.rint(0.5 * du)
    x = _HALF_PI * du_red
    s = np.sin(x)
    if abs(s) < _SIN_TINY:
        return float(n)
    sn = np.sin(n * x)
    g = (sn * sn) / (n * (s * s))
    if g < 0.0:  # np.clip, which keeps NaN
        return 0.0
    return float(n) if g > n else g


@numba.njit(cache=True, inline="always")
def _kernels(u, beam_u, coef, n, out, p):
    """``dirichlet_kernels`` of direction ``u`` into ``out[:, p]`` (coef: (2k, 4), the
    angle-subtraction coefficients of ``dirichlet_kernels``)."""
    x = _HALF_PI * u
    s, c = np.sin(x), np.cos(x)
    xn = x * n
    sn, cn = np.sin(xn), np.cos(xn)
    k = beam_u.shape[0]
    inv_n = 1.0 / n
    for j in range(k):
        den = _fma(coef[j, 1], c, coef[j, 0] * s)
        if abs(den) < _SIN_RECOMPUTE:
            out[j, p] = _ula_gain(u - beam_u[j], n)
            continue
        g = _fma(coef[k + j, 3], cn, coef[k + j, 2] * sn) / den
        g = (g * g) * inv_n
        out[j, p] = float(n) if g > n else g  # np.minimum, which keeps NaN


@numba.njit(cache=True, nogil=True)
def links_kernel(ut_pos, ut_up, sphere, r_ut, sat_pos, ax_x, ax_y, ut, sat, min_el, bx, cx, nx,
                 by, cy, ny, rel, rho2, rho, elevation, visible, kx, ky, lo, hi):  # fmt: skip
    """The geometry and beam kernels of ``LinkEngine.evaluate_pairs``, per pair (the
    pairs ``lo .. hi - 1``: a thread's share)."""
    for p in range(lo, hi):
        i, j = ut[p], sat[p]
        r0 = ut_pos[i, 0] - sat_pos[j, 0]
        r1 = ut_pos[i, 1] - sat_pos[j, 1]
        r2 = ut_pos[i, 2] - sat_pos[j, 2]
        rel[p, 0], rel[p, 1], rel[p, 2] = r0, r1, r2
        d2 = _dot3(r0, r1, r2, r0, r1, r2)
        d = np.sqrt(d2)
        rho2[p], rho[p] = d2, d
        if sphere:
            s_el = -_dot3(r0, r1, r2, ut_pos[i, 0], ut_pos[i, 1], ut_pos[i, 2]) / (d * r_ut[i])
        else:
            s_el = -_dot3(r0, r1, r2, ut_up[i, 0], ut_up[i, 1], ut_up[i, 2]) / d
        if s_el < -1.0:  # np.clip, which keeps NaN
            s_el = -1.0
        elif s_el > 1.0:
            s_el = 1.0
        el = np.arcsin(s_el)
        elevation[p], visible[p] = el, el >= min_el
        inv = 1.0 / d
        ux = _dot3(r0, r1, r2, ax_x[j, 0], ax_x[j, 1], ax_x[j, 2]) * inv
        uy = _dot3(r0, r1, r2, ax_y[j, 0], ax_y[j, 1], ax_y[j, 2]) * inv
        _kernels(ux, bx, cx, nx, kx, p)
        _kernels(uy, by, cy, ny, ky, p)


@numba.njit(cache=True, nogil=True)
def snr_kernel(kx, ky, path_snr, ix, iy, out, lo, hi):
    """``Links.snr_db_bm``: ``(10 log10 k_x + 10 log10 k_y) + 10 log10 p``, (n_beam, m),
    of the pairs ``lo .. hi - 1``."""
    for c in range((hi - lo + _CHUNK - 1) // _CHUNK):  # chunks: scratch per thread
        _snr_chunk(kx, ky, path_snr, ix, iy, out, lo + c * _CHUNK, min(hi, lo + (c + 1) * _CHUNK))


@numba.njit(cache=True, inline="always")
def _snr_chunk(kx, ky, path_snr, ix, iy, out, lo, hi):
    """:func:`snr_kernel` of the pairs ``lo .. hi - 1``."""
    lx = np.empty(kx.shape[0])
    ly = np.empty(ky.shape[0])
    for p in range(lo, hi):
        for a in range(kx.shape[0]):
            lx[a] = 10.0 * np.log10(kx[a, p])
        for a in range(ky.shape[0]):
            ly[a] = 10.0 * np.log10(ky[a, p])
        pdb = 10.0 * np.log10(path_snr[p])
        for b in range(ix.shape[0]):
            out[b, p] = (lx[ix[b]] + ly[iy[b]]) + pdb


#: :func:`best_beam_kernel`'s margin: a beam whose linear SNR is below ``1 - _TIE_MARGIN``
#: times the largest is below it in dB too. Exactly, its SNR is then below by 4.3e-9 dB at
#: least (the products err by a few 1e-16, relative); the dB values as computed err by
#: < 1e-10 dB (C library ``log10`` <= 2 ulp, terms below 1e4 dB: ~1e-11 dB).
_TIE_MARGIN = 1e-9
#: Ranges of the path and of the largest linear SNR where that argument holds: every
#: product near the largest is a normal number, the subnormal ones are far below it.
_PATH_MIN, _PATH_MAX, _SNR_MIN, _SNR_MAX = 1e-150, 1e150, 1e-100, 1e100


@numba.njit(cache=True, nogil=True)
def best_beam_kernel(kx, ky, path_snr, ix, iy, with_db, best, best_db, lo, hi):
    """``numpy.argmax(Links.snr_db_bm(ix, iy), axis=0)`` and that beam's dB value, of the
    pairs ``lo .. hi - 1``, without the (n_beam, m) matrix.

    Every beam's linear SNR ``(k_x k_y) p`` is computed and the largest kept, with the
    second largest. Where the second is below ``1 - _TIE_MARGIN`` times the largest
    (every pair but near ties), the largest is the dB argmax as well: only its dB value
    is computed, ``(10 log10 k_x + 10 log10 k_y) + 10 log10 p`` as in :func:`snr_kernel`.
    Elsewhere (near ties, NaN kernels, values outside ``_PATH_*``, ``_SNR_*``) every beam's
    dB value is computed and ``numpy.argmax``'s rule applied (the first NaN, else the first
    maximum); a pair not visible (NaN path: every beam NaN) gets beam 0 and NaN.
    ``with_db`` False: the quick pairs' ``best_db`` is left unwritten (not asked for).
    """
    for p in range(lo, hi):
        path = path_snr[p]
        if path != path:
            best[p], best_db[p] = 0, np.nan
            continue
        s_max, s_2nd, i, nan = -1.0, -1.0, 0, False
        for b in range(ix.shape[0]):  # written for selects, not branches
            s = (kx[ix[b], p] * ky[iy[b], p]) * path
            nan |= s != s
            up = s > s_max
            s_2nd = max(s_2nd, s_max if up else s)
            i = b if up else i
            s_max = s if up else s_max
        clear = s_2nd < s_max * (1.0 - _TIE_MARGIN) and not nan
        if clear and _PATH_MIN <= path <= _PATH_MAX and _SNR_MIN <= s_max <= _SNR_MAX:
            best[p] = i
            if with_db:
                best_db[p] = (
                    10.0 * np.log10(kx[ix[i], p]) + 10.0 * np.log10(ky[iy[i], p])
                ) + 10.0 * np.log10(path)
        else:
            _best_of_all(kx, ky, path, ix, iy, best, best_db, p)


@numba.njit(cache=True, inline="always")
def _best_of_all(kx, ky, path, ix, iy, best, best_db, p):
    """``numpy.argmax`` of every beam's dB value (the first NaN, else the first maximum)
    into ``best[p]``, and that value into ``best_db[p]``."""
    pdb = 10.0 * np.log10(path)
    i, d_best = 0, 0.0
    for b in range(ix.shape[0]):
        d = (10.0 * np.log10(kx[ix[b], p]) + 10.0 * np.log10(ky[iy[b], p])) + pdb
        if d != d:
            i, d_best = b, d
            break
        if b == 0 or d > d_best:
            i, d_best = b, d
    best[p], best_db[p] = i, d_best


_DEG = 180.0 / np.pi  # numpy.degrees multiplies by this constant
_C4PI = 4.0 * np.pi


@numba.njit(cache=True, inline="always")
def _mod360(x):
    """``numpy.mod(x, 360.0)`` (fmod, then the divisor's sign)."""
    m = np.fmod(x, 360.0)
    if m != 0.0:
        if m < 0.0:
            m += 360.0
    else:
        m = 0.0
    return m


@numba.njit(cache=True, nogil=True)
def serve_kernel(kx, ky, path_snr, rel, slant, elevation, pair, beam, served, ix, iy, fading,
                 i_other, ut_vel, ut_acc, sat_vel, sat_acc, ut_pos, enu, has_enu, k_dop, freq,
                 bw, rx, atm, out, lo, hi):  # fmt: skip
    """``LinkEngine.serve_pairs`` for a full beam lattice with one colour, per row (the
    rows ``lo .. hi - 1``).

    ``out`` (16, n): the columns in the order of ``SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS``;
    ``fading``, ``i_other``, ``rx``, ``atm`` (n,): per row (1, 0 and the constants where
    the engine has scalars).
    """
    c = 299_792_458.0
    ln2 = np.log(2.0)
    for r in range(lo, hi):
        p, b = pair[r], beam[r]
        nan = 1.0 if served[r] else np.nan
        sx, sy = kx[0, p], ky[0, p]
        for a in range(1, kx.shape[0]):
            sx += kx[a, p]
        for a in range(1, ky.shape[0]):
            sy += ky[a, p]
        g_sig = kx[ix[b], p] * ky[iy[b], p]
        g_int = sx * sy - g_sig
        path = path_snr[p] * fading[r]
        snr = g_sig * path
        sinr = snr / ((g_int * path + i_other[r]) + 1.0)
        se = np.log1p(sinr) / ln2
        l0, l1, l2 = -rel[p, 0], -rel[p, 1], -rel[p, 2]
        rho_k = np.sqrt(_dot3(l0, l1, l2, l0, l1, l2))
        v_sat = _dot3(sat_vel[r, 0], sat_vel[r, 1], sat_vel[r, 2], l0, l1, l2) / rho_k
        v_ut = _dot3(ut_vel[r, 0], ut_vel[r, 1], ut_vel[r, 2], l0, l1, l2) / rho_k
        v0, v1 = sat_vel[r, 0] - ut_vel[r, 0], sat_vel[r, 1] - ut_vel[r, 1]
        v2_ = sat_vel[r, 2] - ut_vel[r, 2]
        v2 = _dot3(v0, v1, v2_, v0, v1, v2_)
        a0, a1 = sat_acc[r, 0] - ut_acc[r, 0], sat_acc[r, 1] - ut_acc[r, 1]
        a2 = sat_acc[r, 2] - ut_acc[r, 2]
        rho_dot = v_sat - v_ut
        rho_ddot = ((v2 + _dot3(l0, l1, l2, a0, a1, a2)) - rho_dot * rho_dot) / rho_k
        perp = v2 - rho_dot * rho_dot
        if perp < 0.0:  # np.maximum(., 0), which keeps NaN
            perp = 0.0
        ang = np.sqrt(perp) / rho_k
        if has_enu:
            e0, e1, e2 = enu[r, 0, 0], enu[r, 0, 1], enu[r, 0, 2]
            n0, n1, n2 = enu[r, 1, 0], enu[r, 1, 1], enu[r, 1, 2]
            east = _dot3(l0, l1, l2, e0, e1, e2)
            north = _dot3(l0, l1, l2, n0, n1, n2)
        else:  # links.azimuth_deg: the sphere's east and north times h r
            x, y, z = ut_pos[r, 0], ut_pos[r, 1], ut_pos[r, 2]
            h2 = x * x + y * y
            east = np.sqrt(h2 + z * z) * (x * l1 - y * l0)
            north = h2 * l2 - z * (x * l0 + y * l1)
        rho = slant[p]
        out[0, r] = (elevation[p] * _DEG) * nan
        out[1, r] = rho * nan
        out[2, r] = (10.0 * np.log10(g_sig)) * nan
        out[3, r] = rx[r] * nan
        out[4, r] = (20.0 * np.log10(((_C4PI * rho) * freq) / c)) * nan
        out[5, r] = atm[r] * nan
        out[6, r] = (10.0 * np.log10(snr)) * nan
        out[7, r] = (10.0 * np.log10(sinr)) * nan
        out[8, r] = se * nan
        out[9, r] = se * (bw * nan)
        out[10, r] = (-k_dop * rho_dot) * nan
        out[11, r] = (-k_dop * v_sat) * nan
        out[12, r] = (k_dop * v_ut) * nan
        out[13, r] = (-k_dop * rho_ddot) * nan
        out[14, r] = (ang * _DEG) * nan
        out[15, r] = _mod360(np.arctan2(east, north) * _DEG) * nan


@numba.njit(cache=True, inline="always")
def _screen_envelope(u, beams, n):
    """``min(n, 1 / (n s^2))``, ``s`` a lower bound of ``sin(pi d / 2)`` and ``d`` the
    distance from ``u`` to the nearest beam cosine modulo 2 (``screening.envelope``)."""
    d = 2.0 - max(u - beams[0], beams[beams.shape[0] - 1] - u)
    for k in range(beams.shape[0]):
        d = min(d, abs(u - beams[k]))
    x = _SCREEN_HALF_PI * min(max(d, 0.0), 1.0)
    x2 = x * x
    s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)))
    if s <= 0.0:
        return n
    return min(n, 1.0 / (n * s * s))


@numba.njit(cache=True, nogil=True)
def screen_kernel(ut_pos, ut_up, sphere, sat_pos, ax_x, ax_y, bx, by, nx, ny, k_lin, s_min,
                  band, slack, ut_factor, code, bound, sin_out, lo, hi):  # fmt: skip
    """Fill ``code``, ``bound`` and ``sin_out`` (n_u, n_s) as ``screening.screen`` does,
    rows (UTs) ``lo .. hi - 1``.

    ``ut_factor (n_u,)``: each UT's ``G_rx / L_atm`` bound where it does not depend on the
    elevation (1 elsewhere: the caller multiplies it in afterwards). The screening rounds
    differently from the numpy one; both bounds hold (it decides what is evaluated only).
    """
    n_s = code.shape[1]
    fx, fy = float(nx), float(ny)
    s_lo, s_hi = s_min - band, s_min + band
    for i in range(lo, hi):
        px, py, pz = ut_pos[i, 0], ut_pos[i, 1], ut_pos[i, 2]
        if sphere:
            r = np.sqrt(px * px + py * py + pz * pz)
            ex, ey, ez = px / r, py / r, pz / r
        else:
            ex, ey, ez = ut_up[i, 0], ut_up[i, 1], ut_up[i, 2]
        k = k_lin * (1.0 + slack) * ut_factor[i]
        for j in range(n_s):
            dx, dy, dz = px - sat_pos[j, 0], py - sat_pos[j, 1], pz - sat_pos[j, 2]
            rho2 = dx * dx + dy * dy + dz * dz
            inv = 1.0 / np.sqrt(rho2)
            s_el = -(dx * ex + dy * ey + dz * ez) * inv
            sin_out[i, j] = s_el
            if s_el < s_lo:
                code[i, j] = 0
                bound[i, j] = -1.0
                continue
            code[i, j] = 2 if s_el >= s_hi else 1
            ux = (dx * ax_x[j, 0] + dy * ax_x[j, 1] + dz * ax_x[j, 2]) * inv
            uy = (dx * ax_y[j, 0] + dy * ax_y[j, 1] + dz * ax_y[j, 2]) * inv
            bound[i, j] = k / rho2 * _screen_envelope(ux, bx, fx) * _screen_envelope(uy, by, fy)
