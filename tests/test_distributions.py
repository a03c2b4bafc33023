"""simucal.distributions against scipy's (the runtime avoids importing scipy.special)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import special

from simucal.distributions import chi2_isf, chi2_sf, f_sf


@settings(max_examples=300, deadline=None)
@given(x=st.floats(1e-6, 2000), k=st.integers(1, 500))
def test_chi2_sf(x, k):
    ref = special.chdtrc(k, x)
    assert chi2_sf(x, k) == pytest.approx(ref, rel=1e-6, abs=1e-300)


@settings(max_examples=300, deadline=None)
@given(F=st.floats(1e-6, 1e4), d1=st.integers(1, 60), d2=st.integers(1, 500))
def test_f_sf(F, d1, d2):
    assert f_sf(F, d1, d2) == pytest.approx(special.fdtrc(d1, d2, F), rel=1e-6, abs=1e-300)


@pytest.mark.parametrize("p,k", [(1e-3, 3), (0.01 / 40, 1), (0.5, 10), (1e-9, 25)])
def test_chi2_isf(p, k):
    assert chi2_isf(p, k) == pytest.approx(special.chdtri(k, p), rel=1e-9)


def test_tiny_tails_stay_positive():
    assert 0 < chi2_sf(900.0, 7) == pytest.approx(special.chdtrc(7, 900.0), rel=1e-8)
    assert np.isclose(chi2_sf(0.0, 3), 1.0)
