# ----------------------------------------------------------------------------
# szdyn generated code (package) -- DO NOT EDIT.
# Source: derive/codegen.py (run as `python -m derive`), SymPy 1.14.0.
# Regenerate with `make derive`; tests check that this file is reproduced byte for byte.
# State order: x = [q_w, q_b, q_1 .. q_Nc, u_w, u_b, u_1 .. u_Nc, z_lugre]  (rad, rad/s, m)
# Parameter order (p): I_W, I_B, m_c, R_bo, d, t_c, R_w, t_r, n_rollers, k_c, b_c, k_imp, b_imp, n_imp, impact_clamp, mu_s, mu_k, gamma, m_b, g, drive_mode, contact_model, F_nw, mu_ws, mu_wk, v_ws, v_weps, sigma0, sigma1, sigma2, c_visc, mu_st, v_st, fric_asym, tau_lift, a_rev, phi_rev, a_tooth, phi_tooth, n_teeth, k_drift, mu_t, v_teps, k_drive, c_drive
# ----------------------------------------------------------------------------
"""Generated Spiral Zipper model code (numpy + numba only; no SymPy).

``spiral_zipper`` holds the right-hand side ``rhs(t, x, p, drive, out)``, the parameter order
``PARAM_NAMES`` and helpers; ``kernels`` holds the per-circle and per-contact kernels.
"""
