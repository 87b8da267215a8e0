"""DH tables of the fixed-base test models, written out independently of the model files,
and the standard DH transform in numpy and sympy (A = Rz(theta) Tz(d) Tx(a) Rx(alpha))."""

import numpy as np
import sympy as sp

# Gierlak (2014), Table 1, with the published Scorbot-ER 4pc dimensions [m].
SCORBOT = dict(d1=0.349, l1=0.025, l2=0.22, l3=0.22, d5=0.145)
# Corke's Robotics Toolbox mdl_puma560 [m].
PUMA = dict(a2=0.4318, a3=0.0203, d3=0.15005, d4=0.4318)


def scorbot_table(theta, g=SCORBOT, pi=np.pi):
    """Rows (theta_i, d_i, a_i, alpha_i) of Gierlak's Table 1."""
    t1, t2, t3, t4, t5 = theta
    return [(t1, g["d1"], g["l1"], pi / 2), (t2, 0, g["l2"], 0), (t3, 0, g["l3"], 0),
            (pi / 2 + t4, 0, 0, pi / 2), (t5, g["d5"], 0, 0)]


def puma_table(theta, g=PUMA, pi=np.pi):
    """Rows (theta_i, d_i, a_i, alpha_i) of the standard-DH PUMA 560."""
    t1, t2, t3, t4, t5, t6 = theta
    return [(t1, 0, 0, pi / 2), (t2, 0, g["a2"], 0), (t3, g["d3"], g["a3"], -pi / 2),
            (t4, g["d4"], 0, pi / 2), (t5, 0, 0, -pi / 2), (t6, 0, 0, 0)]


def dh_matrix(theta, d, a, alpha, lib=np):
    ct, st, ca, sa = lib.cos(theta), lib.sin(theta), lib.cos(alpha), lib.sin(alpha)
    rows = [[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]]
    return sp.Matrix(rows) if lib is sp else np.array(rows, dtype=float)


def dh_frames(table, lib=np):
    """Frames 0..n of a DH chain: [T_0, T_0 A_1, T_0 A_1 A_2, ...], T_0 = identity."""
    T = sp.eye(4) if lib is sp else np.eye(4)
    frames = [T]
    for row in table:
        T = T * dh_matrix(*row, lib=sp) if lib is sp else T @ dh_matrix(*row)
        frames.append(T)
    return frames


def symbolic_geometric_jacobian(frames, point):
    """Columns (z_{i-1} x (point - o_{i-1}); z_{i-1}) of a revolute DH chain, world axes."""
    columns = []
    for F in frames[:-1]:
        z, o = F[:3, 2], F[:3, 3]
        columns.append(list(z.cross(point - o)) + list(z))
    return sp.Matrix(columns).T


def trig_to_symbols(expr, angles):
    """Replace sin/cos of each angle by a plain symbol (s_i, c_i), so sympy factors polynomials."""
    s = sp.symbols(f"s0:{len(angles)}")
    c = sp.symbols(f"c0:{len(angles)}")
    mapping = {}
    for i, angle in enumerate(angles):
        mapping[sp.sin(angle)] = s[i]
        mapping[sp.cos(angle)] = c[i]
    return expr.subs(mapping), s, c
