"""Shared fixtures for the integrator and drive tests.

``smooth_case`` is the ONE model-specific piece of setup for tests/test_integrators.py: a smooth,
non-stiff, contact-free case of the generated model, built by parameter *name*, so that the
convergence-order tests stay in the asymptotic regime. Replace its body if the model changes.
"""
from __future__ import annotations

import numpy as np
import pytest

from szdyn_generated.spiral_zipper import PARAM_NAMES, state_size


def params_by_name(**values) -> np.ndarray:
    """Parameter vector in PARAM_NAMES order from keyword values; names not given take their
    szdyn default (the candidate effects are off there), so new parameters need no edit here."""
    from szdyn.defaults import default_values

    unknown = sorted(set(values) - set(PARAM_NAMES))
    assert not unknown, f"unknown {unknown}"
    full = {**default_values(), **values}
    return np.array([float(full[n]) for n in PARAM_NAMES])


@pytest.fixture(scope="session")
def smooth_case():
    """``(x0, p, drive, t_end)``: a smooth nonlinear case with time scales ~0.1-1 s.

    Real Spiral Zipper model with 3 circles, chosen so that the right-hand side is smooth along
    the whole trajectory (asymptotic convergence tests need that):
    * no roller-circle contacts: reach t_c + t_r = 2 mm, while a roller centre (R_w = 18.17 mm)
      is always >= R_bo - d - R_w = 6.8 mm from any circle centre;
    * no slider friction (mu_s = mu_k = 0): the friction law has kinks at |u_b| = gamma, 1.5 gamma;
    * soft, lightly damped arms (omega ~ 10 rad/s, damping ratio 0.1) and a light band, so the
      arms' centrifugal and inertial coupling to the band is strongly nonlinear but not stiff;
    * a prescribed wheel ramp with no knot inside [0, t_end]: at a knot the drive acceleration
      jumps, and a fixed step straddling it drops to first order (first knot at -0.5 s).
    """
    p = params_by_name(
        I_W=5.3e-6, I_B=2e-5, m_c=4e-3, R_bo=0.03, d=5e-3, t_c=1e-3, R_w=0.01817, t_r=1e-3,
        n_rollers=8, k_c=1e-5, b_c=2e-7, k_imp=4e12, b_imp=2e13, n_imp=3, impact_clamp=1,
        mu_s=0.0, mu_k=0.0, gamma=0.01, m_b=1.0, g=9.80665, drive_mode=0,
        contact_model=0, F_nw=10.0, mu_ws=0.9, mu_wk=0.8, v_ws=0.01, v_weps=1e-4,
        sigma0=1e5, sigma1=316.0, sigma2=0.4)
    n_c = 3
    n = n_c + 2
    x0 = np.zeros(state_size(n_c))
    x0[2:n] = [0.6, -0.4, 0.9]  # arm angles (rad), band at q_b = 0
    x0[n + 1] = 2.0  # band speed (rad/s)
    x0[n + 2:2 * n] = [3.0, -1.0, 0.5]  # arm speeds (rad/s)
    t_k = np.array([-0.5, 5.0])
    v_k = np.array([1.0, 12.0])  # wheel speed ramp, 2 rad/s^2
    c_k = np.array([0.0, 0.5 * (t_k[1] - t_k[0]) * (v_k[0] + v_k[1])])
    drive = np.concatenate(([2.0], t_k, v_k, c_k))
    x0[0] = 0.5 * 0.5 * (1.0 + 2.0)  # wheel angle at t = 0 consistent with the drive
    x0[n] = 2.0  # wheel speed at t = 0
    return x0, p, drive, 1.0


@pytest.fixture
def diagnose_options(monkeypatch, tmp_path):
    """``options(flags)`` -> the keyword arguments ``python -m szdyn.run diagnose`` passes to
    :class:`szdyn.diagnose.diagnosis.Diagnosis` with those command-line flags. The command's inputs
    are stubbed (a manifest of no recordings) and the Diagnosis is stopped at its construction."""
    from types import SimpleNamespace

    import szdyn.diagnose.data as data
    import szdyn.manifest as manifest
    from szdyn.diagnose import diagnosis as dmod
    from szdyn.run import main as run_main

    seen = {}

    class Stop(Exception):
        pass

    def init(self, *a, **kw):
        seen.update(kw)
        raise Stop

    monkeypatch.setattr(manifest, "read_manifest", lambda path: SimpleNamespace(entries=[], heldout=["a.csv"]))
    monkeypatch.setattr(data, "prepare", lambda man: [])
    monkeypatch.setattr(dmod.Diagnosis, "__init__", init)

    def options(flags):
        seen.clear()
        with pytest.raises(Stop):
            run_main(["diagnose", str(tmp_path / "m.toml"), "--out", str(tmp_path / "o"), "--quiet",
                      "--no-checkpoint", *flags])
        return dict(seen)

    return options
