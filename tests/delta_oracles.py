"""Test-side geometry of the delta robot, written from the report's vector geometry and
shared by the test modules (not a test module itself).

The sphere centres, rod matrix, elbow terms and closed forms below come straight from
report eq. (1)-(5), not from deltagen, so the tests can judge both backends independently
(only :func:`singular_band_pose` bisects with the numpy reference's status, and its
result is confirmed with :func:`det_rel`). Tolerances are derived from the conditioning
of the pose, never from what the code under test prints.
"""

from __future__ import annotations

import math

import numpy as np

from deltagen.model.delta import DeltaGeometry


def geometry(r_a, r_b, l_a, l_b, theta_deg, **kw) -> DeltaGeometry:
    return DeltaGeometry(
        r_a=r_a,
        r_b=r_b,
        l_a=l_a,
        l_b=l_b,
        theta=tuple(math.radians(t) for t in theta_deg),
        **kw,
    )


DEFAULT = DeltaGeometry.default()
#: Klipper-style drive positions (towers at 30/150/270 deg), a smaller printer-sized robot.
KLIPPER = geometry(0.15, 0.04, 0.25, 0.6, (30, 150, 270), name="klipper")
#: Unequal drive spacing (90 / 150 / 120 deg): no symmetry to hide errors behind.
IRREGULAR = geometry(0.22, 0.05, 0.3, 0.75, (10, 100, 250), name="irregular")
GEOMETRIES = {"default": DEFAULT, "klipper": KLIPPER, "irregular": IRREGULAR}
#: The irregular robot's masses, inertias and a gravity off the z axis (the dynamics tests:
#: nothing symmetric or vertical for an error to hide behind).
IRREGULAR_INERTIA = dict(
    I_a=0.02, m_a=0.9, r_ca=0.11, m_b=0.35, m_p=0.8, gravity=(0.5, -1.2, -9.7), I_4=1e-3
)


def irregular_dynamic_robot():
    """The compiled robot of IRREGULAR with IRREGULAR_INERTIA."""
    from deltagen import DeltaInertia, DeltaRobot

    g = IRREGULAR
    inertia = DeltaInertia(**IRREGULAR_INERTIA)
    return DeltaRobot(g.r_a, g.r_b, g.l_a, g.l_b, theta=g.theta, inertia=inertia)


#: A box of crank angles that is reachable and far from singular for all three geometries.
WORK_Q = (-0.6, 1.3)


def with_tol(geom: DeltaGeometry, singular_tol: float) -> DeltaGeometry:
    return DeltaGeometry(
        r_a=geom.r_a,
        r_b=geom.r_b,
        l_a=geom.l_a,
        l_b=geom.l_b,
        theta=geom.theta,
        name=geom.name,
        singular_tol=singular_tol,
    )


# ------------------------------------------------------------------ report eq. (1)-(5)


def centres(geom, q):
    """Sphere centres S_i, dS_i/dq_i, d2S_i/dq_i^2 as (N, 3 chains, 3 coords)."""
    q = np.asarray(q, dtype=float)[..., :3]
    th = np.asarray(geom.theta, dtype=float)
    rho = geom.r + geom.l_a * np.cos(q)
    S = np.stack((rho * np.cos(th), rho * np.sin(th), -geom.l_a * np.sin(q)), axis=-1)
    dS = np.stack(
        (
            -geom.l_a * np.sin(q) * np.cos(th),
            -geom.l_a * np.sin(q) * np.sin(th),
            -geom.l_a * np.cos(q),
        ),
        axis=-1,
    )
    d2S = np.stack(
        (
            -geom.l_a * np.cos(q) * np.cos(th),
            -geom.l_a * np.cos(q) * np.sin(th),
            geom.l_a * np.sin(q),
        ),
        axis=-1,
    )
    return S, dS, d2S


def rod_matrix(geom, q, p):
    """D with rows p - S_i (half the report's J_p)."""
    S, _, _ = centres(geom, q)
    return np.asarray(p, dtype=float)[..., None, :3] - S


def rod_residual(geom, q, p):
    """| |p - S_i| - l_b | / l_b per row (max over the chains): 0 when (q, p) close."""
    D = rod_matrix(geom, q, p)
    return np.max(np.abs(np.linalg.norm(D, axis=-1) - geom.l_b), axis=-1) / geom.l_b


def elbow_terms(geom, q, p):
    """j_i / (l_a l_b) with j_i = (p - S_i) . dS_i/dq_i (half the report's J_q,ii).
    Positive on the elbow-out branch, zero where crank and rod are aligned."""
    S, dS, _ = centres(geom, q)
    D = np.asarray(p, dtype=float)[..., None, :3] - S
    return np.einsum("...ci,...ci->...c", D, dS) / (geom.l_a * geom.l_b)


def det_rel(geom, q, p):
    """|det(p - S_i)| / l_b^3."""
    return np.abs(np.linalg.det(rod_matrix(geom, q, p))) / geom.l_b**3


def rod_condition(geom, q, p):
    """2-norm condition number of the rod matrix D (inf where p is not finite)."""
    D = rod_matrix(geom, q, p)
    out = np.full(D.shape[:-2], np.inf)
    finite = np.all(np.isfinite(D), axis=(-1, -2))
    out[finite] = np.linalg.cond(D[finite])
    return out


def well_conditioned(geom, q, p, margin=0.05):
    """Rows far from every singularity, on the elbow-out branch, platform below the
    centre plane (the lower intersection fk returns)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    finite = np.all(np.isfinite(p[..., :3]), axis=-1) & np.all(np.isfinite(q[..., :3]), axis=-1)
    pz = np.where(finite[..., None], p[..., :3], 0.0)
    q = np.where(finite[..., None], q[..., :3], 0.0)
    j = elbow_terms(geom, q, pz)
    D = rod_matrix(geom, q, pz)
    # lower intersection: the platform lies below each sphere centre's plane side, i.e.
    # det D has the sign of the lower solution; both oracles agree on the magnitude only,
    # so check "below" directly: p is under the plane through the three centres
    S, _, _ = centres(geom, q)
    normal = np.cross(S[..., 1, :] - S[..., 0, :], S[..., 2, :] - S[..., 0, :])
    normal = normal * np.where(normal[..., 2:3] < 0, -1.0, 1.0)  # pointing up
    below = np.einsum("...i,...i->...", pz - S[..., 0, :], normal) < 0
    det = np.abs(np.linalg.det(D)) / geom.l_b**3
    return finite & below & (det > margin) & np.all(j > margin, axis=-1)


# ---------------------------------------------------------------------- closed forms


def symmetric_fk(geom, a):
    """p for q = (a, a, a) on a robot whose drives are 120 deg apart: the platform sits on
    the base axis, x = y = 0, z = -l_a sin a - sqrt(l_b^2 - (r + l_a cos a)^2)."""
    rho = geom.r + geom.l_a * math.cos(a)
    return np.array([0.0, 0.0, -geom.l_a * math.sin(a) - math.sqrt(geom.l_b**2 - rho**2)])


def symmetric_dz_dq(geom, a):
    """dz/da of :func:`symmetric_fk` (all three cranks turning together)."""
    rho = geom.r + geom.l_a * math.cos(a)
    return -geom.l_a * math.cos(a) - rho * geom.l_a * math.sin(a) / math.sqrt(geom.l_b**2 - rho**2)


def rot_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def stretched_chain_pose(geom, q1, shrink=1e-10):
    """A platform position where chain 1's crank and rod are (almost) aligned, stretched
    out, at crank angle q1: a J_q singularity (j_1 -> 0) of the inverse kinematics."""
    c, s = math.cos(geom.theta[0]), math.sin(geom.theta[0])
    direction = np.array([math.cos(q1) * c, math.cos(q1) * s, -math.sin(q1)])
    axis = np.array([geom.r * c, geom.r * s, 0.0])
    return axis + (geom.l_a + geom.l_b) * (1.0 - shrink) * direction


# ------------------------------------------------------------------------ sampling


def random_q(rng, n, low=WORK_Q[0], high=WORK_Q[1]):
    return rng.uniform(low, high, size=(n, 3))


def random_p(rng, geom, n):
    """Platform positions over (and beyond) the workspace, for status comparisons."""
    return np.column_stack(
        [
            rng.uniform(-0.6, 0.6, n),
            rng.uniform(-0.6, 0.6, n),
            rng.uniform(-1.5 * geom.l_b, 0.2 * geom.l_b, n),
        ]
    )


def max_rel_err(actual, expected, scale):
    """max over rows of |actual - expected| / scale (row-wise 2-norms), and the row."""
    a = np.asarray(actual, dtype=float).reshape(len(scale), -1)
    e = np.asarray(expected, dtype=float).reshape(len(scale), -1)
    err = np.linalg.norm(a - e, axis=1) / scale
    if err.size == 0:
        return 0.0, -1
    i = int(np.argmax(err))
    return float(err[i]), i


def singular_band_pose(geom, inside=(1.0, 1.0, 1.0), outside=(0.86, -1.45, -2.88)):
    """Crank angles (1, 3) in the middle of the band just inside the workspace boundary
    where |det D| / l_b^3 < geom.singular_tol (the platform nears the plane of the sphere
    centres). Found by bisection along the segment inside -> outside on the status of the
    numpy reference; use a singular_tol of about 1e-6 so the band is far wider than
    rounding."""
    from deltagen.reference import delta as ref
    from deltagen.status import OK, UNREACHABLE

    inside, outside = np.asarray(inside, float), np.asarray(outside, float)
    assert ref.fk(geom, outside[None])[1][0] == UNREACHABLE

    def along(m):
        return (inside + m * (outside - inside))[None]

    def boundary(failing):
        lo, hi = 0.0, 1.0
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if failing(ref.fk(geom, along(mid))[1][0]) else (mid, hi)
        return lo

    start_singular = boundary(lambda status: status != OK)
    start_unreachable = boundary(lambda status: status == UNREACHABLE)
    assert start_singular < start_unreachable
    q = along(0.5 * (start_singular + start_unreachable))
    p, _ = ref.fk(geom, q)
    assert 0.0 < det_rel(geom, q, p)[0] < geom.singular_tol
    return q
