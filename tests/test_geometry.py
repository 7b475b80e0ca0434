"""Band geometry, thesis eqs 1-5, against hand-computed numbers."""
import math

import numpy as np
import pytest

from szdyn.errors import ParameterError
from szdyn.geometry import BandGeometry


def unit_case():
    # H_B - H_T = 1 m and pi D = 2 m: sin(beta) = 1/2, beta = pi/6 exactly.
    return BandGeometry(band_height=1.5, tooth_height=0.5, diameter=2 / math.pi, teeth_per_wrap=4)


def test_eqs_1_to_5_exact_case():
    g = unit_case()
    assert g.helix_angle == pytest.approx(math.pi / 6, rel=1e-14)            # eq 1
    assert g.pitch == pytest.approx(2 / math.sqrt(3), rel=1e-14)              # eq 2: 1/cos(30 deg)
    assert g.wrap_length == pytest.approx(4 / math.sqrt(3), rel=1e-14)        # eq 5: sqrt(4/3 + 4)
    assert g.tooth_pitch == pytest.approx(1 / math.sqrt(3), rel=1e-14)        # eq 3: S_B / 4
    # eq 4: three wraps of band give three pitches of column
    assert g.column_height(3 * g.wrap_length) == pytest.approx(3 * g.pitch, rel=1e-14)


def test_default_like_numbers_by_hand():
    # H_B = 45.72 mm, H_T = 5 mm, D = 60 mm, N = 24; computed by hand:
    # sin b = 40.72 / 188.4956 = 0.216026, b = 0.217743 rad, cos b = 0.976387,
    # P_B = 41.7048 mm, S_B = pi D / cos b = 193.054 mm, P_T = 8.0439 mm.
    g = BandGeometry(45.72e-3, 5e-3, 60e-3, 24)
    assert g.helix_angle == pytest.approx(0.217743, abs=2e-6)
    assert g.pitch == pytest.approx(41.7048e-3, rel=1e-5)
    assert g.wrap_length == pytest.approx(193.054e-3, rel=1e-5)
    assert g.tooth_pitch == pytest.approx(8.0439e-3, rel=1e-4)
    # identities: P_B = pi D tan b, S_B = pi D / cos b
    assert g.pitch == pytest.approx(math.pi * g.diameter * math.tan(g.helix_angle), rel=1e-13)
    assert g.wrap_length == pytest.approx(math.pi * g.diameter / math.cos(g.helix_angle), rel=1e-13)


def test_stroke_one_revolution_is_pitch_and_vectorised():
    g = BandGeometry(45.72e-3, 5e-3, 60e-3, 24)
    assert g.stroke(2 * math.pi) == pytest.approx(g.pitch, rel=1e-15)
    assert isinstance(g.stroke(1.0), float)
    q = np.array([[0.0, math.pi], [-2 * math.pi, 4 * math.pi]])
    s = g.stroke(q)
    assert s.shape == (2, 2)
    np.testing.assert_allclose(s, g.pitch * np.array([[0.0, 0.5], [-1.0, 2.0]]), rtol=1e-15)
    np.testing.assert_allclose(g.stroke_error([0.1, -0.2]), g.pitch * np.array([0.1, -0.2]) / (2 * math.pi))
    h = g.column_height(np.array([0.0, g.wrap_length]))
    np.testing.assert_allclose(h, [0.0, g.pitch])


@pytest.mark.parametrize("field, bad", [
    ("band_height", 0.0), ("band_height", -1e-3), ("band_height", float("nan")),
    ("tooth_height", -1e-3), ("tooth_height", float("inf")), ("diameter", 0.0),
    ("diameter", float("nan")), ("teeth_per_wrap", 0), ("teeth_per_wrap", 2.5),
    ("teeth_per_wrap", 10_001), ("diameter", -10 ** 400),
])
def test_invalid_field_named(field, bad):
    kw = dict(band_height=45.72e-3, tooth_height=5e-3, diameter=60e-3, teeth_per_wrap=24)
    kw[field] = bad
    with pytest.raises(ParameterError, match=field):
        BandGeometry(**kw)


def test_a_huge_integer_is_not_echoed_in_full():
    kw = dict(band_height=45.72e-3, tooth_height=5e-3, diameter=60e-3, teeth_per_wrap=-10 ** 400)
    with pytest.raises(ParameterError) as ei:
        BandGeometry(**kw)
    assert str(ei.value) == ("band geometry 'teeth_per_wrap' must be a positive integer, "
                             "got -100000... (an integer of 401 digits)")
    kw["teeth_per_wrap"] = 10 ** 15 + 1       # 16 digits: shortened; 15 would be shown whole
    with pytest.raises(ParameterError, match=r"got 100000\.\.\. \(an integer of 16 digits\)$"):
        BandGeometry(**kw)
    kw["teeth_per_wrap"] = 10 ** 14
    with pytest.raises(ParameterError, match=r"got 100000000000000$"):
        BandGeometry(**kw)


def test_rise_must_be_below_circumference():
    with pytest.raises(ParameterError, match="diameter"):
        BandGeometry(band_height=1.0 + 2.0, tooth_height=1.0, diameter=2 / math.pi, teeth_per_wrap=4)
    with pytest.raises(ParameterError, match="tooth_height"):
        BandGeometry(band_height=5e-3, tooth_height=5e-3, diameter=60e-3, teeth_per_wrap=24)


def test_frozen_and_bad_inputs():
    g = unit_case()
    with pytest.raises(AttributeError):
        g.diameter = 1.0
    with pytest.raises(ParameterError, match="band_length"):
        g.column_height(-1.0)
    with pytest.raises(ParameterError, match="q_b"):
        g.stroke([0.0, float("nan")])
