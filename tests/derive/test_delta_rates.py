"""The restructured rate levels of the delta core (derive/delta/velocity.py,
acceleration.py), checked numerically against independent evidence: numpy's inverse for
the adjugate built from cross products of the rod vectors, and finite differences in time
of |p - S_i|^2 for J_q,ii / 2 and h_i / 2 along arbitrary (unconstrained) paths."""

from __future__ import annotations

import numpy as np
import sympy as sp

from deltagen.derive.delta import acceleration as acc
from deltagen.derive.delta import fk as fkd
from deltagen.derive.delta import symbols as s
from deltagen.derive.delta import velocity as vel


def _stage_values(stage, values: dict) -> dict:
    """Evaluate a stage's assignments in order (later ones may use earlier ones)."""
    out = dict(values)
    for sym, expr in stage.assignments:
        out[sym] = float(sp.sympify(expr).subs(out))
    return out


def test_adjugate_from_rod_cross_products_is_det_times_inverse(rng):
    for _ in range(5):
        xi, a, b = rng.normal(size=(3, 3))
        e = np.cross(a, b)
        values = {
            **dict(zip(fkd.xi, xi)),
            **dict(zip(fkd.a, a)),
            **dict(zip(fkd.b, b)),
            **dict(zip(fkd.e, e)),
        }
        D = np.array([xi, xi - a, xi - b])
        values[fkd.det_D] = float(np.linalg.det(D))
        got = _stage_values(vel.inverse_stage(), values)
        adj = np.array([[got[vel.adjD[i, j]] for j in range(3)] for i in range(3)])
        np.testing.assert_allclose(adj, np.linalg.det(D) * np.linalg.inv(D), atol=1e-12)
        # the solve without the first column: D^-1 w
        w = rng.normal(size=3)
        solved = vel.solve(sp.Matrix(w)).subs({**values, **{k: got[k] for k in got}})
        np.testing.assert_allclose(
            np.array(solved, dtype=float).ravel(), np.linalg.solve(D, w), rtol=1e-10
        )


def test_rate_terms_are_time_derivatives_of_the_rod_length(rng):
    """Along any p(t), q_i(t) (not on the constraint): d/dt |p - S_i|^2 / 2 =
    D_i . pdot - jq_i qdot_i and d^2/dt^2 |p - S_i|^2 / 2 = D_i . pddot - h_i / 2."""
    geometry = {
        **{s.chain_r[i]: 0.1 + 0.05 * i for i in range(3)},
        **{s.chain_l_a[i]: 0.3 + 0.02 * i for i in range(3)},
        **{s.cos_theta[i]: np.cos(2.0 + 2.1 * i) for i in range(3)},
        **{s.sin_theta[i]: np.sin(2.0 + 2.1 * i) for i in range(3)},
    }
    jq_stage, h_stage = vel.jq_stage(), acc.h_stage()
    # the position stages they read: l_a,i cos q_i and the centres S_i (S_z,i)
    crank, centres = fkd.fk_stages()[:2]
    for _ in range(3):
        p0, p1, p2 = rng.normal(scale=0.3, size=(3, 3))
        q0, q1, q2 = rng.normal(size=(3, 3))

        coeffs = (p0, p1, p2, q0, q1, q2)

        def path(t, c=coeffs):
            return c[0] + c[1] * t + c[2] * t**2, c[3] + c[4] * t + c[5] * t**2

        def half_sq(t, i, path=path):
            p, q = path(t)
            S = np.array(
                s.sphere_centre(i, np.cos(q[i]), np.sin(q[i])).subs(geometry), dtype=float
            ).ravel()
            return 0.5 * np.sum((p - S) ** 2)

        t, dt = 0.3, 1e-4
        p, q = path(t)
        values = {
            **geometry,
            **dict(zip((s.x, s.y, s.z), p)),
            **dict(zip(s.pd, p1 + 2 * p2 * t)),
            **dict(zip(s.qd, q1 + 2 * q2 * t)),
            **dict(zip(s.qdd, 2 * q2)),
            **{s.cos_q[i]: np.cos(q[i]) for i in range(3)},
            **{s.sin_q[i]: np.sin(q[i]) for i in range(3)},
        }
        for i in range(3):
            S = s.sphere_centre(i).subs(values)
            for k in range(3):
                values[vel.D[i, k]] = float(p[k] - S[k])
        values = _stage_values(centres, _stage_values(crank, values))
        values = _stage_values(jq_stage, values)
        values = _stage_values(h_stage, values)
        D = np.array([[values[vel.D[i, k]] for k in range(3)] for i in range(3)])
        for i in range(3):
            f = [half_sq(t + k * dt, i) for k in (-1, 0, 1)]
            rate = (f[2] - f[0]) / (2 * dt)
            second = (f[2] - 2 * f[1] + f[0]) / dt**2
            pd, pdd = p1 + 2 * p2 * t, 2 * p2
            np.testing.assert_allclose(
                D[i] @ pd - values[vel.jq[i]] * values[s.qd[i]], rate, atol=1e-7
            )
            np.testing.assert_allclose(D[i] @ pdd - values[acc.hh[i]], second, atol=1e-5)
