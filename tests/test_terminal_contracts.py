"""The terminal models' contracts against explicit element sums and closed forms.

Written from the survivors of a mutation run (docs/testing.md). References: explicit sums
over the panel's elements (``|sum_mn w_mn e^{i pi (m du_x + n du_y)}|^2 / sum |w_mn|^2``,
no Dirichlet kernel), the beam of a pointing error built by rotating the satellite
direction in elevation (no ``pointing_offsets``), the paper's closed form of the
leaky-wave peak gain (Sec. 2.1, exponentials, not tanh), each member of a
``TerminalGroups`` evaluated alone on its own UTs. Tolerances: float64 rounding of the
explicit sums (1e-10 relative) unless said.
"""

import warnings

import numpy as np
import pytest

from leolink.antenna.terminal import (
    FixedGain,
    Isotropic,
    LeakyWave,
    LeakyWaveConfig,
    Metasurface,
    TerminalGroups,
    UpaConfig,
    UPATerminal,
    leaky_wave_gain_lin,
    leaky_wave_peak_gain_lin,
)
from leolink.errors import LeolinkError

REL = 1e-10
K = 10.0


def _explicit(du_x, du_y, n_x, n_y, taper=0.0):
    """Explicit panel sum towards offsets (du_x, du_y) from the beam, any shape."""
    du_x, du_y = np.broadcast_arrays(np.asarray(du_x, float), np.asarray(du_y, float))
    m = np.arange(n_x)[:, None]
    k = np.arange(n_y)[None, :]
    w = np.exp(-taper * m) * np.exp(-taper * k)
    out = np.empty(du_x.shape)
    for idx in np.ndindex(du_x.shape):
        a = np.exp(1j * np.pi * (m * du_x[idx] + k * du_y[idx]))
        out[idx] = np.abs(np.sum(w * a)) ** 2 / np.sum(w**2)
    return out


def _beam_off_in_elevation(el, err):
    """Panel-cosine offsets of a beam at elevation el + err, satellite due east at el."""
    return np.cos(el + err) - np.cos(el), 0.0


def test_upa_pattern_is_the_explicit_panel_sum_plus_the_diffuse_term():
    upa = UPATerminal(6, 9, K)
    du_x = np.array([[0.0], [0.05], [0.31], [-0.7]])
    du_y = np.array([0.0, 0.12, -0.4])  # broadcast (4, 3)
    got = upa.pattern_lin(du_x, du_y)
    assert got.shape == (4, 3)
    np.testing.assert_allclose(got, _explicit(du_x, du_y, 6, 9) + 1.0 / K, rtol=REL)


def test_leaky_wave_pattern_and_gain_with_a_rician_term():
    lw = LeakyWave(7, 5, 0.08, rician_k=K)
    du_x = np.array([0.0, 0.03, 0.2, -0.55])
    du_y = np.array([0.0, -0.1, 0.25, 0.6])
    got = lw.pattern_lin(du_x, du_y)
    np.testing.assert_allclose(got, _explicit(du_x, du_y, 7, 5, 0.08) + 1.0 / K, rtol=REL)
    # On the beam: the explicit peak (the paper's closed form, checked below) plus 1/K.
    peak = _explicit(0.0, 0.0, 7, 5, 0.08)
    assert lw.gain_lin(np.radians(40.0)) == pytest.approx(peak + 1.0 / K, rel=REL)


@pytest.mark.parametrize("kind", ["upa", "leaky"])
def test_default_pointing_error_is_none_and_its_default_direction_is_up(kind):
    n, a = 8, (0.0 if kind == "upa" else 0.06)
    term = UPATerminal(n, n, K) if kind == "upa" else LeakyWave(n, n, a, rician_k=K)
    el, err = np.radians(35.0), np.radians(3.0)
    assert term.gain_lin(el) == pytest.approx(_explicit(0.0, 0.0, n, n, a)[()] + 1 / K, rel=REL)
    # An error given without its direction moves the beam up in elevation (psi = 0).
    dux, duy = _beam_off_in_elevation(el, err)
    expect = _explicit(dux, duy, n, n, a)[()] + 1.0 / K
    assert term.gain_lin(el, err) == pytest.approx(expect, rel=REL)
    assert term.gain_db(el, err) == pytest.approx(10 * np.log10(expect), abs=1e-9)
    # ... and the direction is used when given: sideways, the beam turns towards the left
    # of the satellite (north, panel y), b = cos(err) v + sin(err) y.
    side = _explicit((np.cos(err) - 1.0) * np.cos(el), np.sin(err), n, n, a)[()] + 1.0 / K
    assert term.gain_db(el, err, np.pi / 2) == pytest.approx(10 * np.log10(side), abs=1e-6)


def test_leaky_wave_gain_keeps_float64_for_float32_offsets():
    du = np.array([0.013, 0.21, 0.47, 0.88], np.float32)
    ref = _explicit(du.astype(float), 0.0, 16, 1, 0.05)
    np.testing.assert_allclose(leaky_wave_gain_lin(du, 16, 0.05), ref, rtol=REL)


def test_leaky_wave_peak_gain_is_the_papers_closed_form():
    n = 24
    a = np.array([0.0, 1e-3, 0.05, 0.2, 1.0])
    e_an, e_a = np.exp(-a[1:] * n), np.exp(-a[1:])
    paper = (1 - e_an) * (1 + e_a) / ((1 + e_an) * (1 - e_a))  # Sec. 2.1
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a = 0 is its limit n, without 0/0
        got = leaky_wave_peak_gain_lin(n, a)
    assert got[0] == n
    np.testing.assert_allclose(got[1:], paper, rtol=1e-12)
    np.testing.assert_allclose(leaky_wave_peak_gain_lin(n, a.astype(np.float32)[1:]),
                               leaky_wave_peak_gain_lin(n, a.astype(np.float32)[1:].astype(float)),
                               rtol=1e-13)  # fmt: skip
    assert leaky_wave_peak_gain_lin(n, 0) == n  # an integer leakage 0


def test_scan_loss_keeps_float64_for_float32_elevations():
    upa = UPATerminal(8, 8, K, scan_loss=True, element_exponent=1.2)
    el = np.array([0.21, 0.66, 1.1], np.float32)
    ref = 64.0 * np.sin(el.astype(float)) ** 1.2 + 1.0 / K  # on the beam: N sin(el)^q
    np.testing.assert_allclose(upa.gain_lin(el), ref, rtol=1e-12)


def test_metasurface_ignores_pointing_errors_and_is_silent_at_and_below_the_horizon():
    ms = Metasurface(33.0, 1.2)
    el = np.radians([10.0, 45.0, 90.0])
    expect = 33.0 + 12.0 * np.log10(np.sin(el))
    np.testing.assert_allclose(ms.gain_db(el, 0.1, 0.7), expect, atol=1e-12)
    assert ms.gain_db(el[:, None], np.zeros(4)).shape == (3, 4)
    el32 = el.astype(np.float32)
    np.testing.assert_allclose(ms.gain_db(el32), 33.0 + 12.0 * np.log10(np.sin(el32.astype(float))),
                               atol=1e-12)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        low = ms.gain_db(np.array([0.0, -0.1]))
    assert low[0] == -np.inf and np.isnan(low[1])


def test_isotropic_and_fixed_gain_broadcast_their_inputs():
    el, off = np.zeros((3, 1)), np.zeros(4)
    assert Isotropic().gain_db(el, off).shape == (3, 4)
    assert (Isotropic().pattern_lin(np.zeros((2, 1)), np.zeros(5)) == 1.0).all()
    assert Isotropic().pattern_lin(np.zeros((2, 1)), np.zeros(5)).shape == (2, 5)
    got = FixedGain(39.7).gain_db(el, off)
    assert got.shape == (3, 4) and (got == 39.7).all()


def _groups():
    members = (UPATerminal(4, 6, K, scan_loss=True), Isotropic(), FixedGain(12.5),
               LeakyWave(5, 5, 0.1))  # fmt: skip
    group = np.array([1, 0, 2, 0, 3, 1, 3])
    return members, group, TerminalGroups(members, group.tolist())


def test_terminal_groups_answer_with_each_uts_own_antenna():
    members, group, tg = _groups()
    el = np.radians(np.linspace(12.0, 80.0, 7 * 3)).reshape(7, 3)  # (n_ut, n_sat)
    got = tg.gain_db(el)
    err = np.radians(6.0)
    got_err = tg.gain_db(el, err)
    for u, g in enumerate(group):
        np.testing.assert_allclose(got[u], members[g].gain_db(el[u]), atol=1e-12)
        # A pointing error reaches the elevation-dependent members (an elevation-independent
        # one is evaluated once, without it).
        m = members[g]
        ref = m.gain_db(np.pi / 2) if m.elevation_independent else m.gain_db(el[u], err)
        np.testing.assert_allclose(got_err[u], np.broadcast_to(ref, 3), atol=1e-12)
    assert (got_err[1] < got[1] - 0.01).all()  # the scanned UPA loses by the error
    # ... in the direction given (sideways here).
    side = tg.gain_db(el, err, np.pi / 2)
    np.testing.assert_allclose(side[1], members[0].gain_db(el[1], err, np.pi / 2), atol=1e-12)
    assert np.abs(side[1] - got_err[1]).max() > 1e-3
    # The scanned UPA depends on the elevation; the others do not.
    assert np.ptp(got[1]) > 1.0 and np.ptp(got[0]) == 0.0
    members = (members[0], members[1], members[3])  # each with a pattern
    group = np.minimum(group, 2)
    tg = TerminalGroups(members, group)
    du_x = np.linspace(-0.3, 0.3, 7 * 2).reshape(7, 2)
    du_y = np.full((7, 1), 0.05)
    pat = tg.pattern_lin(du_x, du_y)
    assert pat.shape == (7, 2)
    for u, g in enumerate(group):
        np.testing.assert_allclose(pat[u], members[g].pattern_lin(du_x[u], du_y[u]), rtol=1e-12)


def test_terminal_groups_without_a_pattern_and_bad_groups():
    _, _, tg = _groups()  # FixedGain has no pattern: the groups have none
    assert tg.pattern_lin is None
    both = TerminalGroups((UPATerminal(4, 4, K), Isotropic()), [1, 0])
    assert both.pattern_lin is not None
    assert "n_ut=2" in repr(both)
    for group in ([0, 0, 0], [0, -1, 1], [1, 1]):
        with pytest.raises(
            ValueError, match="^TerminalGroups: every terminal needs UTs, every UT a terminal$"
        ):
            TerminalGroups((Isotropic(), FixedGain(3.0)), group)


def test_panel_config_defaults_and_bounds():
    # docs/config.md: n_x, n_y in [1, 4096], default 24; q in [0, 20], default 1.2.
    cfg = UpaConfig()
    assert (cfg.n_x, cfg.n_y, cfg.scan_loss, cfg.element_exponent) == (24, 24, False, 1.2)
    assert LeakyWaveConfig().element_exponent == 1.2 and LeakyWaveConfig().n_y == 24
    for ok in ({"n_x": 1}, {"n_y": 4096}, {"element_exponent": 0.0}, {"element_exponent": 20.0}):
        UpaConfig(**ok)
    for bad in ({"n_x": 0}, {"n_y": 4097}, {"element_exponent": -1e-9},
                {"element_exponent": 20.000001}):  # fmt: skip
        with pytest.raises((ValueError, LeolinkError)):
            UpaConfig(**bad)
    assert "element factor" in UpaConfig.model_fields["scan_loss"].description
    assert "Kymeta" in UpaConfig.model_fields["element_exponent"].description
    assert UpaConfig.model_fields["n_x"].description == "elements along x"
