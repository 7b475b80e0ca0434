"""Another program can use the generated RHS with numpy, numba and scipy only: no SymPy and no
szdyn runtime on the import path. Its solve_ivp result agrees with szdyn's own integrator."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np

from szdyn.defaults import default_parameters
from szdyn.drive import RampHold
from szdyn.integrators import integrate

CONSUMER = textwrap.dedent("""
    import json, sys
    sys.modules["sympy"] = None   # any import of sympy now fails
    sys.modules["szdyn"] = None   # ... and so does the szdyn runtime
    import numpy as np
    from scipy.integrate import solve_ivp
    from szdyn_generated.spiral_zipper import PARAM_NAMES, make_ivp_fun

    cfg = json.loads(sys.stdin.read())
    p = np.array([cfg["values"][name] for name in PARAM_NAMES])
    sol = solve_ivp(make_ivp_fun(p, cfg["drive"]), (0.0, cfg["t_end"]), cfg["x0"], method="DOP853",
                    rtol=1e-10, atol=1e-12)
    print(json.dumps({"status": sol.status, "y": sol.y[:, -1].tolist(),
                      "sympy_loaded": any(m.startswith("sympy") and sys.modules[m] is not None
                                          for m in sys.modules)}))
""")


def test_generated_rhs_with_solve_ivp_in_a_clean_process():
    params = default_parameters(n_circles=16).replace(drive_mode=0)
    drive = RampHold(a=30.0, t_ramp=0.1, t_hold=0.1)
    x0 = params.initial_state()
    arr = drive.to_array(angle0=x0[0])
    cfg = {"values": dict(params.values), "drive": arr.tolist(), "x0": x0.tolist(), "t_end": 0.2}
    r = subprocess.run([sys.executable, "-c", CONSUMER], input=json.dumps(cfg), capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    assert res["status"] == 0 and not res["sympy_loaded"]
    ours = integrate(x0, params.to_array(), arr, 0.2, method="dopri5", rtol=1e-10, atol=1e-12)
    n = 16 + 2
    y = np.array(res["y"])
    assert np.abs(ours.x[:, n + 1]).max() > 0.05  # the band was driven (contacts acted)
    np.testing.assert_allclose(ours.x[-1, 1:n], y[1:n], rtol=0, atol=1e-6)      # angles (rad)
    np.testing.assert_allclose(ours.x[-1, n + 1:], y[n + 1:], rtol=0, atol=1e-4)  # speeds (rad/s)
