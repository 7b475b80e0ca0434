"""Parameter sets, validation, serialisation and the defaults table."""
import json
import math
import os

import numpy as np
import pytest

from szdyn import defaults, params
from szdyn.errors import ParameterError
from szdyn.params import CHOICE, POSINT, ParameterSet, _bounds


@pytest.fixture(scope="module")
def names():
    return params.param_names()


@pytest.fixture(scope="module")
def ps(names):
    return defaults.default_parameters()


# --- defaults table (no generated module needed) ---------------------------------------------
def test_every_default_has_unit_description_provenance():
    seen = set()
    for d in defaults.ALL_DEFAULTS:
        assert d.name not in seen, f"duplicate default {d.name}"
        seen.add(d.name)
        assert d.unit.strip(), d.name
        assert d.description.strip(), d.name
        assert d.provenance.strip(), d.name
        assert "\n" not in d.provenance, f"{d.name}: provenance must be one line"
        assert math.isfinite(d.value), d.name
        assert defaults.PARAMETER_DOCS[d.name] == (d.unit, d.description)


def test_default_units_match_bounds_table():
    PARAMETER_BOUNDS = _bounds()
    for d in defaults.PARAMETER_DEFAULTS:
        assert d.name in PARAMETER_BOUNDS, d.name
        assert PARAMETER_BOUNDS[d.name][0] == d.unit, d.name


def test_thesis_unit_conversions():
    v = defaults.default_values()
    assert v["k_c"] == pytest.approx(50e-3)      # 50 N*mm/rad
    assert v["b_c"] == pytest.approx(7.5e-3)     # 7.5 N*mm*s/rad
    assert v["k_imp"] == pytest.approx(4000 / (1e-3) ** 3)   # 4000 N/mm^3
    assert v["b_imp"] == pytest.approx(20 / (1e-3) ** 4)     # 20 N*s/mm^4
    assert v["n_imp"] == 3 and v["n_rollers"] == 8
    est = defaults.omni_wheel_inertia_estimate()
    assert v["I_W"] == pytest.approx(est["total"], rel=0.01)
    assert 1e-6 < v["I_W"] < 1e-4


# --- parameter set -----------------------------------------------------------------------------
def test_defaults_cover_names_and_validate(names, ps):
    PARAMETER_BOUNDS = _bounds()
    for n in names:
        assert n in PARAMETER_BOUNDS, f"{n}: no unit/bound entry"
        assert n in defaults.PARAMETER_DOCS, f"{n}: no docs entry"
    assert tuple(ps.values) == names
    assert ps.n_circles == 100
    assert ps.interference == pytest.approx(0.19e-3, rel=1e-9)
    assert ps.geometry.diameter == pytest.approx(2 * ps["R_bo"])


def test_to_array_follows_param_names(names, ps):
    p = ps.to_array()
    assert p.dtype == np.float64 and p.shape == (len(names),)
    index = params.param_index()
    for n in names:
        assert p[index[n]] == ps[n]
        assert p[names.index(n)] == ps[n]


def test_replace(ps):
    q = ps.replace(b_c=7.5e-4, n_circles=96)
    assert q["b_c"] == 7.5e-4 and q.n_circles == 96
    assert ps["b_c"] == 7.5e-3 and ps.n_circles == 100   # original unchanged
    assert q.replace(b_c=7.5e-3, n_circles=100) == ps
    with pytest.raises(TypeError):
        ps.values["b_c"] = 1.0                            # read-only mapping


def test_unknown_key_suggests_nearest(ps):
    with pytest.raises(ParameterError, match=r"'mu_ss'.*did you mean 'mu_s'"):
        ps.replace(mu_ss=0.4)
    with pytest.raises(ParameterError, match=r"did you mean 'R_bo'"):
        ps.replace(r_bo=0.04)
    with pytest.raises(ParameterError, match=r"did you mean 'k_imp'"):
        ps["k_impp"]


def _bad_values(name):
    yield float("nan")
    yield float("inf")
    yield -float("inf")
    kind = _bounds()[name][1]
    if kind != params.REAL:    # every other parameter is >= 0 (or a choice, or a positive integer)
        yield -1.0
        yield -0.004
    if kind == params.POSITIVE:
        yield 0.0
    if kind == POSINT:
        yield 2.5
        yield 0.0
    if kind.startswith(CHOICE):
        yield 0.5
        yield max(float(c) for c in kind[len(CHOICE):].split(",")) + 1
    yield "abc"


def test_every_bad_value_raises_naming_the_parameter(names, ps):
    checked = 0
    for name in names:
        for bad in _bad_values(name):
            with pytest.raises(ParameterError, match=f"'{name}'") as info:
                ps.replace(**{name: bad})
            assert "parameter" in str(info.value)
            checked += 1
    assert checked >= 3 * len(names) + 2 * sum(_bounds()[n][1] != params.REAL for n in names)


def test_message_format(ps):
    with pytest.raises(ParameterError) as info:
        ps.replace(m_c=-0.004)
    assert str(info.value) == "parameter 'm_c' must be > 0 kg, got -0.004"


@pytest.mark.parametrize("changes, key", [
    (dict(mu_k=0.4), "mu_k"),                       # mu_k > mu_s
    (dict(d=0.031), "'d'"),                          # arm longer than band radius
    (dict(R_w=0.025), "R_w"),                        # rollers do not fit inside the band
    (dict(t_c=0.013), "t_c"),                        # circle bigger than the arm
    (dict(contact_model=1, F_nw=0.0), "F_nw"),       # friction counter-model without normal force
    (dict(mu_wk=0.95), "mu_wk"),                     # mu_wk > mu_ws
    (dict(n_circles=0), "n_circles"),
    (dict(n_circles=12.5), "n_circles"),
    (dict(n_circles=10_001), "n_circles.*at most 10000"),   # a mistyped N_c, before any memory is taken
    # integers beyond a float's range (JSON reads them exactly): refused, not an OverflowError
    (dict(n_circles=10 ** 400), r"n_circles.*at most 10000.*got 100000\.\.\. \(an integer of 401 digits\)$"),
    # a mistyped N_r: each step searches every roller's contacts (1e9 would run for hours)
    (dict(n_rollers=1e9), r"'n_rollers' \(N_r\) must be at most 1000 .*got 1000000000\.0$"),
    (dict(k_c=10 ** 400), "'k_c' must be a finite number, got an integer too large for a float"),
])
def test_cross_checks(ps, changes, key):
    with pytest.raises(ParameterError, match=key):
        ps.replace(**changes)


def test_n_rollers_up_to_its_cap(ps):
    assert ps.replace(n_rollers=1000.0)["n_rollers"] == 1000.0


def test_zero_allowed_for_nonnegative(ps):
    q = ps.replace(k_c=0.0, b_c=0.0, mu_s=0.0, mu_k=0.0, m_b=0.0, b_imp=0.0)
    assert q["b_c"] == 0.0


def test_initial_state(ps):
    x0 = ps.initial_state()
    assert x0.shape == (2 * (ps.n_circles + 2) + 1,) and x0.dtype == np.float64  # + LuGre z
    assert np.count_nonzero(x0) == 1
    # N_c = 100 is not a multiple of 8 rollers: best offset is a quarter circle pitch
    assert x0[0] == pytest.approx(math.pi / 200)
    q = ps.replace(n_circles=96)
    assert q.initial_state()[0] == pytest.approx(math.pi / 96)   # half a circle pitch
    assert ps.initial_state(q_w0=0.3)[0] == 0.3
    # rollers end up as far from any circle as possible
    for s in (ps, q, ps.replace(n_circles=30)):
        nr, nc = int(s["n_rollers"]), s.n_circles
        pitch = 2 * math.pi / nc
        off = (s.initial_state()[0] + 2 * math.pi * np.arange(nr) / nr) / pitch
        dist = np.abs(off - np.round(off))
        m = nr // math.gcd(nr, nc)
        assert dist.min() == pytest.approx(0.5 / m)


def test_dict_and_json_round_trip(ps, tmp_path):
    assert ParameterSet.from_dict(ps.to_dict()) == ps
    path = tmp_path / "p.json"
    q = ps.replace(b_c=7.5e-4, n_circles=96)
    q.to_json(path)
    back = ParameterSet.from_json(path)
    assert back == q
    np.testing.assert_array_equal(back.to_array(), q.to_array())
    assert json.loads(path.read_text())["values"]["b_c"] == 7.5e-4
    assert sorted(os.listdir(tmp_path)) == ["p.json"]       # no temp file left


def test_json_write_is_atomic(ps, tmp_path, monkeypatch):
    path = tmp_path / "p.json"
    ps.to_json(path)
    before = path.read_bytes()

    def boom(src, dst):
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError, match="simulated"):
        ps.replace(b_c=1e-4).to_json(path)
    assert path.read_bytes() == before                       # old content intact
    assert sorted(os.listdir(tmp_path)) == ["p.json"]       # temp file removed


def test_json_errors_name_file_and_key(ps, tmp_path):
    data = ps.to_dict()
    data["values"]["m_c"] = -1.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(ParameterError, match=r"bad\.json.*'m_c'"):
        ParameterSet.from_json(bad)

    data = ps.to_dict()
    data["values"]["mu_kk"] = 0.2
    bad.write_text(json.dumps(data))
    with pytest.raises(ParameterError, match=r"bad\.json.*'mu_kk'.*did you mean 'mu_k'"):
        ParameterSet.from_json(bad)

    # a null geometry is refused (it once meant the default silently); leaving it out is the default
    for geo, say in ((None, "got null"), ([1, 2], "got list")):
        data = ps.to_dict()
        data["geometry"] = geo
        bad.write_text(json.dumps(data))
        with pytest.raises(ParameterError, match=rf"bad\.json.*key 'geometry' must be a mapping.*{say}$"):
            ParameterSet.from_json(bad)
    data = ps.to_dict()
    del data["geometry"]
    bad.write_text(json.dumps(data))
    assert ParameterSet.from_json(bad).geometry == ps.geometry

    data = ps.to_dict()
    data["geometry"]["diameter"] = -1.0
    bad.write_text(json.dumps(data))
    with pytest.raises(ParameterError, match=r"bad\.json.*'diameter'"):
        ParameterSet.from_json(bad)

    # integers beyond a float's range, which JSON reads exactly: refused by name, no OverflowError
    for where, key, say in (("geometry", "teeth_per_wrap", "at most 10000"),
                            ("geometry", "diameter", "must be finite"),
                            (None, "n_circles", "at most 10000")):
        data = ps.to_dict()
        (data[where] if where else data)[key] = 10 ** 400
        bad.write_text(json.dumps(data))
        with pytest.raises(ParameterError, match=rf"bad\.json.*'{key}'.*{say}") as ei:
            ParameterSet.from_json(bad)
        assert len(str(ei.value)) < 400   # the 401 digits are not echoed back

    bad.write_text("{not json")
    with pytest.raises(ParameterError, match=r"bad\.json.*not valid JSON"):
        ParameterSet.from_json(bad)


def test_missing_values_filled_from_defaults_with_warning(ps):
    data = ps.to_dict()
    del data["values"]["gamma"]
    with pytest.warns(UserWarning, match="gamma"):
        back = ParameterSet.from_dict(data)
    assert back["gamma"] == defaults.default_values()["gamma"]
    with pytest.raises(ParameterError, match="'gamma'"):
        ParameterSet.from_dict(data, missing="error")
