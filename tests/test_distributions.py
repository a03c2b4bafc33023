"""simucal.distributions against scipy's (the runtime avoids importing scipy.special)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import special

from simucal.fit.distributions import chi2_isf, chi2_sf, chi2_sf_estimated, f_sf, t_isf


@settings(max_examples=300, deadline=None)
@given(x=st.floats(1e-6, 2000), k=st.integers(1, 500))
def test_chi2_sf(x, k):
    _close(chi2_sf(x, k), special.chdtrc(k, x))


@settings(max_examples=300, deadline=None)
@given(F=st.floats(1e-6, 1e4), d1=st.integers(1, 60), d2=st.integers(1, 500))
def test_f_sf(F, d1, d2):
    _close(f_sf(F, d1, d2), special.fdtrc(d1, d2, F))


def _close(got, ref):
    """1e-9 relative down to p = 1e-100, 1e-2 down to 1e-250; below, only tiny (no test reports
    such a p with more than its exponent)."""
    if ref > 1e-250:
        assert got == pytest.approx(ref, rel=1e-9 if ref > 1e-100 else 1e-2)
    else:
        assert 0 <= got < 1e-240


@pytest.mark.parametrize("p,k", [(1e-3, 3), (0.01 / 40, 1), (0.5, 10), (1e-9, 25)])
def test_chi2_isf(p, k):
    assert chi2_isf(p, k) == pytest.approx(special.chdtri(k, p), rel=1e-9)


@pytest.mark.parametrize("p,nu", [(1e-3, 5), (0.025, 1), (1.4e-7, 12.5), (0.1, 300)])
def test_t_isf(p, nu):
    assert t_isf(p, nu) == pytest.approx(special.stdtrit(nu, 1 - p), rel=1e-9)
    assert t_isf(p, np.inf) == pytest.approx(-special.ndtri(p), rel=1e-9)


def test_chi2_sf_estimated_is_f_for_estimated_covariances():
    assert chi2_sf_estimated(9.0, 3, np.inf) == pytest.approx(special.chdtrc(3, 9.0), rel=1e-12)
    assert chi2_sf_estimated(9.0, 3, 7.5) == pytest.approx(special.fdtrc(3, 7.5, 3.0), rel=1e-9)


def test_tiny_tails_stay_positive():
    assert 0 < chi2_sf(900.0, 7) == pytest.approx(special.chdtrc(7, 900.0), rel=1e-8)
    assert np.isclose(chi2_sf(0.0, 3), 1.0)


def test_f_tail_at_any_denominator_dof():
    """A Satterthwaite dof can come out at 1e15 or more: F(d1, d2)'s tail then is chi-square(d1)'s at d1 F
    (lgamma's differences there lost every digit: p = -12.8 on numpy 2.0's sums, -13797 at 1e16)."""
    from simucal.fit.distributions import chi2_sf, f_sf
    for d2 in (1e6, 1e8, 1e12, 1e15, 1e16, 1e300):
        p = f_sf(1.0037, 3, d2)
        assert 0.0 <= p <= 1.0 and abs(p - chi2_sf(3 * 1.0037, 3)) < 1e-5, (d2, p)
