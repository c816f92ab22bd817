"""Closed-form inverse kinematics (deltagen.solve.analytic) of the bundled serial arms.

Evidence used here, independent of the solver's own construction where possible:
* round trips through the numpy reference forward kinematics (plain 4x4 products);
* the printed formulas of the sources: Paul's method for the lecture SCARA (lecture slides
  103-105) with the slide-95 numbers, and the Miskolc paper's eqs. (4)-(9);
* geometric meaning of the configuration names, measured on the arm's own frames;
* Corke's Robotics Toolbox ``Puma560.ikine_a`` when roboticstoolbox is installed.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from deltagen.inputs import InputError
from deltagen.model.serial import SerialDescription, transform
from deltagen.paths import robots_dir
from deltagen.reference import serial as reference
from deltagen.solve.analytic import AnalyticSolver, analytic_solver

EXPECTED = {
    "lecture_scara": ("planar", ("elbow_up", "elbow_down")),
    "manutec_h5": ("planar", ("elbow_up", "elbow_down")),
    "bosch_sr800": ("planar", ("elbow_up", "elbow_down")),
    "miskolc_rrrr": ("elbow_4r", ("front_up", "front_down", "back_up", "back_down")),
    "puma560": ("spherical_wrist_6r", None),
    "motoman_up6": ("spherical_wrist_6r", None),
    "manutec_r15": ("spherical_wrist_6r", None),
    "lecture_prp": (None, None),  # P-R-P cylindrical arm: no closed form here
}
SOLVABLE = [k for k, v in EXPECTED.items() if v[0] is not None]
SIX_R = [k for k, v in EXPECTED.items() if v[0] == "spherical_wrist_6r"]
EIGHT = tuple(
    f"{s}_{e}_{f}" for s in ("front", "back") for e in ("up", "down") for f in ("noflip", "flip")
)
N_SAMPLES = 2000


def _load(name: str) -> SerialDescription:
    return SerialDescription.from_toml(robots_dir() / f"{name}.toml")


def _random_q(desc, rng, k):
    lim = desc.qlim.copy()
    lim[~np.isfinite(lim)] = np.sign(lim[~np.isfinite(lim)]) * math.pi
    return rng.uniform(lim[:, 0], lim[:, 1], size=(k, desc.n))


def _joint_diff(desc, a, b):
    """|a - b| per joint, revolute joints modulo 2 pi (desc None: all revolute)."""
    d = np.asarray(a, float) - np.asarray(b, float)
    rev = (
        np.ones(d.shape[-1], bool) if desc is None else np.array([j.revolute for j in desc.joints])
    )
    d[..., rev] = np.mod(d[..., rev] + math.pi, 2 * math.pi) - math.pi
    return np.abs(d)


def _fk(desc, q):
    q = np.asarray(q, float)
    T, _ = reference.fk(desc, q.reshape(-1, desc.n))
    return T.reshape(q.shape[:-1] + (4, 4))


def _singular(desc, q, thresh=1e-6):
    """Smallest singular value of the reference geometric Jacobian (6 x n) below thresh."""
    J, _ = reference.jacobian(desc, np.atleast_2d(q))
    return np.linalg.svd(J, compute_uv=False)[:, -1] < thresh


def _solve_quietly(solver, T, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning may escape
        return solver.solve(T, **kw)


# -- detection ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(EXPECTED))
def test_structure_detection_of_the_bundled_arms(name):
    structure, configs = EXPECTED[name]
    solver = analytic_solver(_load(name))
    if structure is None:
        assert solver is None
        return
    assert isinstance(solver, AnalyticSolver)
    assert solver.structure == structure
    assert solver.configs == (configs or EIGHT)
    assert len(set(solver.configs)) == len(solver.configs)


def _puma_rows(changes=None):
    rows = [
        dict(a=0.0, alpha_deg=90, d=0.6718),
        dict(a=0.4318, alpha_deg=0, d=0.0),
        dict(a=0.0203, alpha_deg=-90, d=0.15005),
        dict(a=0.0, alpha_deg=90, d=0.4318),
        dict(a=0.0, alpha_deg=-90, d=0.0),
        dict(a=0.0, alpha_deg=0, d=0.0),
    ]
    for (i, key), value in (changes or {}).items():
        rows[i][key] = value
    return rows


@pytest.mark.parametrize(
    "change",
    [
        {(4, "a"): 0.05},  # axis 6 no longer meets axes 4/5: no central wrist
        {(4, "d"): 0.04},  # axis 6 meets axis 5 at another point than axis 4 does
        {(1, "alpha_deg"): 10.0},  # axes 2 and 3 not parallel
        {(0, "alpha_deg"): 0.0},  # axis 1 parallel to axis 2
    ],
    ids=["offset_wrist_a5", "offset_wrist_d5", "axes23_skew", "axes12_parallel"],
)
def test_structures_without_a_closed_form_are_refused(change):
    desc = SerialDescription.from_rows(_puma_rows(change), "standard", name="variant")
    assert analytic_solver(desc) is None


def _round_trip(desc, solver, q, **kw):
    T = _fk(desc, q)
    qs, valid = _solve_quietly(solver, T, **kw)
    assert qs.shape == (len(q), len(solver.configs), desc.n)
    assert valid.shape == (len(q), len(solver.configs))
    Tq = _fk(desc, np.where(valid[..., None], qs, 0.0))
    err_p = np.max(np.abs(Tq[..., :3, 3] - T[:, None, :3, 3]), axis=-1)
    err_r = np.max(np.abs(Tq[..., :3, :3] - T[:, None, :3, :3]), axis=(-1, -2))
    return T, qs, valid, err_p, err_r


def test_modified_dh_puma_with_base_and_tool():
    """Craig's modified-DH Puma 560 on a tilted base with an offset tool: the structure is
    read from the axes, whatever the convention, and base / tool are handled."""
    rows = [
        dict(a=0.0, alpha=0.0, d=0.0, qlim_deg=[-160, 160]),
        dict(a=0.0, alpha_deg=-90, d=0.0, qlim_deg=[-225, 45]),
        dict(a=0.4318, alpha=0.0, d=0.15005, qlim_deg=[-45, 225]),
        dict(a=0.0203, alpha_deg=-90, d=0.4318, qlim_deg=[-110, 170]),
        dict(a=0.0, alpha_deg=90, d=0.0, qlim_deg=[-100, 100]),
        dict(a=0.0, alpha_deg=-90, d=0.0, qlim_deg=[-266, 266]),
    ]
    desc = SerialDescription.from_rows(
        rows,
        "modified",
        name="craig_puma",
        base=transform((0.3, -0.2, 0.5), (0.2, -0.1, 0.7)),
        tool=transform((0.01, -0.02, 0.12), (0.3, 0.4, -0.5)),
    )
    solver = analytic_solver(desc)
    assert solver is not None and solver.structure == "spherical_wrist_6r"
    q = _random_q(desc, np.random.default_rng(11), 300)
    T, qs, valid, err_p, err_r = _round_trip(desc, solver, q)
    assert valid.sum(axis=1).min() >= 1
    assert err_p[valid].max() < 1e-10 and err_r[valid].max() < 1e-10
    hit = (_joint_diff(desc, qs, q[:, None]).max(-1) < 1e-6) & valid
    assert hit.any(axis=1).all()


# -- the round trip on every bundled arm ----------------------------------------------------


@pytest.mark.parametrize("name", SOLVABLE)
def test_round_trip_of_random_configurations(name):
    desc = _load(name)
    solver = analytic_solver(desc)
    rng = np.random.default_rng(sum(map(ord, name)))
    q = _random_q(desc, rng, N_SAMPLES)
    T, qs, valid, err_p, err_r = _round_trip(desc, solver, q)
    # every valid branch reproduces the target
    assert valid.any()
    assert err_p[valid].max() <= 1e-10, err_p[valid].max()
    assert err_r[valid].max() <= 1e-10, err_r[valid].max()
    # valid branches are inside the joint limits; empty branches are NaN
    lim = desc.qlim
    inside = (qs >= lim[:, 0]) & (qs <= lim[:, 1])
    assert inside[valid].all()
    assert np.isfinite(qs[valid]).all()
    # the original configuration is among the valid branches (modulo 2 pi)
    hit = (_joint_diff(desc, qs, q[:, None]).max(-1) < 1e-6) & valid
    missed = ~hit.any(axis=1)
    excused = _singular(desc, q[missed]) if missed.any() else np.zeros(0, bool)
    print(
        f"{name}: original found for {N_SAMPLES - missed.sum()} of {N_SAMPLES}, "
        f"{missed.sum()} missed, all at singular configurations: {excused.all()}"
    )
    assert excused.all()
    assert missed.sum() <= N_SAMPLES // 100


@pytest.mark.parametrize("name", SIX_R)
def test_six_axis_arms_have_eight_solutions_ignoring_limits(name):
    """Away from the workspace boundary a spherical-wrist arm has 8 solutions (EASY-ROB
    paper: "acht Gelenkwinkelstellungen"), all reaching the pose, all distinct."""
    desc = _load(name)
    solver = analytic_solver(desc)
    q = _random_q(desc, np.random.default_rng(5), 300)
    T, qs, valid, err_p, err_r = _round_trip(desc, solver, q, limits=False)
    assert err_p[valid].max() < 1e-10 and err_r[valid].max() < 1e-10
    full = valid.all(axis=1)
    assert full.mean() > 0.6  # the arms with a shoulder offset lose some back solutions
    for i in np.flatnonzero(full)[:50]:
        d = _joint_diff(desc, qs[i][:, None], qs[i][None, :]).max(-1)
        assert (d + np.eye(8) > 1e-6).all()  # pairwise distinct


# -- singular and unreachable targets -------------------------------------------------------


@pytest.mark.parametrize("name", SOLVABLE)
def test_unreachable_and_bad_targets(name):
    desc = _load(name)
    solver = analytic_solver(desc)
    T = np.tile(np.eye(4), (6, 1, 1))
    T[0, :3, 3] = [100.0, 0.0, 0.0]
    T[1, :3, 3] = [0.0, -30.0, 80.0]
    T[2, 0, 0] = np.nan
    T[3, :3, 3] = np.inf
    T[4] = _fk(desc, _random_q(desc, np.random.default_rng(1), 1))[0]
    T[4, :3, :3] *= 1.5  # not a rotation
    T[5] = _fk(desc, _random_q(desc, np.random.default_rng(2), 1))[0]
    T[5, :3, 3] += 50.0  # a reachable orientation far away
    qs, valid = _solve_quietly(solver, T)
    assert not valid.any()
    assert np.isnan(qs).all()
    # leading shapes: a single pose and a (2, 3) grid
    q1, v1 = _solve_quietly(solver, np.eye(4))
    assert q1.shape == (len(solver.configs), desc.n) and v1.shape == (len(solver.configs),)
    q23, v23 = _solve_quietly(solver, np.broadcast_to(T[5], (2, 3, 4, 4)))
    assert q23.shape == (2, 3, len(solver.configs), desc.n) and not v23.any()
    with pytest.raises(InputError):
        solver.solve(np.eye(3))


@pytest.mark.parametrize("name", SIX_R)
def test_wrist_singularity_sets_q4_to_zero(name):
    desc = _load(name)
    solver = analytic_solver(desc)
    q = _random_q(desc, np.random.default_rng(9), 100)
    q[:, 4] = 0.0  # axis 6 in line with axis 4 (q5s = 0 for the bundled arms)
    q[:50, 4] = 1e-13
    T, qs, valid, err_p, err_r = _round_trip(desc, solver, q)
    assert valid.any(axis=1).all()
    assert err_p[valid].max() < 1e-10 and err_r[valid].max() < 1e-10
    straight = valid & (np.abs(np.sin(qs[..., 4])) < 1e-9)
    assert straight.any(axis=1).all()
    assert np.all(qs[..., 3][straight] == 0.0)


def test_shoulder_and_elbow_singularities_of_the_manutec_r15():
    desc = _load("manutec_r15")
    solver = analytic_solver(desc)
    L1, L2, L3 = 0.65, 0.70, 0.15
    # Wrist centre on axis 1: upper arm at elevation e2 (q2 = -e2), forearm at elevation e3
    # (q2 + q3 = -e3) with L1 cos e2 + L2 cos e3 = 0 (no horizontal reach).
    e2 = math.radians(50.0)
    e3 = math.acos(-L1 * math.cos(e2) / L2)
    cases = np.array(
        [
            [0.0, 0.0, 0.0, 0.0, 0.3, 0.0],  # stretched elbow (as qz), bent wrist
            [0.5, -1.2, 0.0, 0.2, -0.4, 0.9],  # stretched elbow, raised arm
            [0.3, -e2, e2 - e3, 0.4, 0.5, -0.6],  # shoulder singularity
            [0.0, -e2, e2 - e3, 0.0, 0.5, 0.0],
        ]
    )
    T, qs, valid, err_p, err_r = _round_trip(desc, solver, cases, limits=False)
    Wc = T[:, :3, 3] - L3 * T[:, :3, 2]
    assert np.hypot(Wc[2:, 0], Wc[2:, 1]).max() < 1e-12
    assert valid.any(axis=1).all()
    assert err_p[valid].max() < 1e-10 and err_r[valid].max() < 1e-10
    # at the stretched elbow the original is found (its elbow angle good to ~1e-8 rad only)
    hit = (_joint_diff(desc, qs, cases[:, None]).max(-1) < 1e-6) & valid
    assert hit[:2].any(axis=1).all()
    assert _singular(desc, cases).all()


# -- lecture: the planar SCARA (slides 95, 103-105) -------------------------------------------


def test_slide_95_numbers_give_30_30_on_one_branch():
    desc = _load("lecture_scara")
    solver = analytic_solver(desc)
    # position only (x, y from slide 95, rounded to 3 decimals there): both elbows
    T = np.eye(4)
    T[:2, 3] = [4.964, 4.598]
    qs, valid = _solve_quietly(solver, T, position_only=True)
    assert valid.all()
    deg = np.degrees(qs)
    near = np.abs(deg - 30.0).max(axis=1) < 0.05
    assert near.tolist() == [False, True]  # elbow_down: the elbow lies below the line
    # the same target with the orientation psi = 60 deg of the pose (slide 95): one branch
    T = _fk(desc, np.radians([30.0, 30.0]))
    assert T[:2, 3] == pytest.approx([4.964, 4.598], abs=5e-4)
    assert math.degrees(math.atan2(T[1, 0], T[0, 0])) == pytest.approx(60.0)
    qs, valid = _solve_quietly(solver, T)
    assert valid.tolist() == [False, True]
    assert np.degrees(qs[1]) == pytest.approx([30.0, 30.0], abs=1e-12)


def test_lecture_scara_agrees_with_pauls_method_of_slide_105():
    desc = _load("lecture_scara")
    solver = analytic_solver(desc)
    L1, L2 = 4.0, 3.0
    q = _random_q(desc, np.random.default_rng(105), 500)
    T = _fk(desc, q)
    qs, valid = _solve_quietly(solver, T)
    assert (valid.sum(axis=1) == 1).all()  # the pose fixes the elbow
    ours = qs[valid]
    x, y = T[:, 0, 3], T[:, 1, 3]
    psi = np.arctan2(T[:, 1, 0], T[:, 0, 0])  # slide 104: psi = q1 + q2
    q1 = np.arctan2((y - L2 * np.sin(psi)) / L1, (x - L2 * np.cos(psi)) / L1)  # slide 105
    q2 = psi - q1
    assert _joint_diff(desc, ours, np.stack([q1, q2], axis=1)).max() < 1e-12
    # position only: both elbows, the law of cosines: q2 = +-arccos(...)
    qp, vp = _solve_quietly(solver, T, position_only=True)
    assert vp.all()
    c2 = (x**2 + y**2 - L1**2 - L2**2) / (2 * L1 * L2)
    assert np.cos(qp[:, :, 1]) == pytest.approx(np.repeat(c2[:, None], 2, 1), abs=1e-9)
    assert (np.sin(qp[:, 0, 1]) <= 1e-12).all() and (np.sin(qp[:, 1, 1]) >= -1e-12).all()


@pytest.mark.parametrize("name", ["manutec_h5", "bosch_sr800"])
def test_scara_position_only_and_yaw(name):
    """4-axis SCARA: both elbows reach the point; the roll axis takes the target's yaw."""
    desc = _load(name)
    solver = analytic_solver(desc)
    q = _random_q(desc, np.random.default_rng(98), 300)
    T = _fk(desc, q)
    qs, valid = _solve_quietly(solver, T, limits=False)
    assert valid.all()  # both elbows reach the full 4-DOF pose
    Tq = _fk(desc, qs)
    assert np.abs(Tq - T[:, None]).max() < 1e-10
    # a tilted target cannot be reached by a SCARA; position only can
    Tt = T.copy()
    Tt[:, :3, :3] = Tt[:, :3, :3] @ transform(rpy=(0.2, 0.0, 0.0))[:3, :3]
    assert not _solve_quietly(solver, Tt)[1].any()
    qp, vp = _solve_quietly(solver, Tt, position_only=True, limits=False)
    assert vp.all()
    assert np.abs(_fk(desc, qp)[..., :3, 3] - T[:, None, :3, 3]).max() < 1e-10


# -- Miskolc paper: the RRRR robot, eqs. (4)-(9) ----------------------------------------------


def test_miskolc_rrrr_agrees_with_the_papers_equations():
    desc = _load("miskolc_rrrr")
    solver = analytic_solver(desc)
    s1, a2, s4 = 0.50, 0.60, 0.50
    q = _random_q(desc, np.random.default_rng(4), 500)
    T = _fk(desc, q)
    xc, yc, zc = T[:, 0, 3], T[:, 1, 3], T[:, 2, 3]
    th1 = np.arctan2(yc, xc)  # (4)
    r, s = np.hypot(xc, yc), zc - s1
    D = (r**2 + s**2 - a2**2 - s4**2) / (2 * a2 * s4)  # (5), (6)
    paper = {}
    for label, sign in (("front_up", -1.0), ("front_down", 1.0)):  # (7): upper / lower elbow
        th3 = np.arctan2(sign * np.sqrt(np.clip(1 - D * D, 0, None)), D)
        th2 = np.arctan2(s, r) - np.arctan2(s4 * np.sin(th3), a2 + s4 * np.cos(th3))  # (9)
        paper[label] = np.stack([th1, th2, th3], axis=1)
    qp, vp = _solve_quietly(solver, T, position_only=True, limits=False)
    for label, expected in paper.items():
        b = solver.configs.index(label)
        assert vp[:, b].all()
        assert _joint_diff(None, qp[:, b, :3], expected).max() < 1e-6
    # with limits: the construction allows the upper elbow only (q3 in [-90, 0] deg)
    _, vlim = _solve_quietly(solver, T, position_only=True)
    assert vlim[:, solver.configs.index("front_up")].all()
    assert not vlim[:, solver.configs.index("front_down")].any()
    # the full pose fixes the elbow: exactly the original (front_up), q4 included
    qs, valid = _solve_quietly(solver, T)
    assert (valid.sum(axis=1) == 1).all() and valid[:, 0].all()
    assert _joint_diff(desc, qs[:, 0], q).max() < 1e-9


# -- meaning of the configuration names -----------------------------------------------------


@pytest.mark.parametrize("name", SIX_R)
def test_configuration_names_mean_what_they_say(name):
    desc = _load(name)
    solver = analytic_solver(desc)
    q = _random_q(desc, np.random.default_rng(12), 300)
    T = _fk(desc, q)
    qs, valid = _solve_quietly(solver, T, limits=False)
    k = len(solver.configs)
    qf = np.where(valid[..., None], qs, 0.0).reshape(-1, desc.n)
    ok = valid.reshape(-1)
    o, w = reference.joint_axes(desc, qf)
    o0, w0 = reference.joint_axes(desc, np.zeros((1, desc.n)))

    def wrist_centre(o, w):
        out = []
        for oi, wi in zip(o, w):
            A = sum(np.eye(3) - np.outer(u, u) for u in wi[3:6])
            b = sum((np.eye(3) - np.outer(u, u)) @ p for u, p in zip(wi[3:6], oi[3:6]))
            out.append(np.linalg.solve(A, b))
        return np.array(out)

    W, W0 = wrist_centre(o, w), wrist_centre(o0, w0)[0]
    w1, w2 = w[:, 0], w[:, 1]
    fwd = np.cross(w2, w1)
    fwd0 = np.cross(w0[0, 1], w0[0, 0])
    sgn = np.sign(fwd0 @ (W0 - o0[0, 0]))
    front = sgn * np.sum(fwd * (W - o[:, 0]), axis=-1) > 0
    # elbow above the shoulder-wrist line (towards w1), in the plane normal to w2
    S, E = o[:, 1], o[:, 2]
    line = W - S
    line -= np.sum(line * w2, -1)[:, None] * w2
    line /= np.linalg.norm(line, axis=-1)[:, None]
    h = E - S
    h -= np.sum(h * line, -1)[:, None] * line
    above = np.sum(h * w1, axis=-1) > 0
    outward = np.abs(np.sum(line * fwd, -1)) > 0.3 * np.linalg.norm(fwd, axis=-1)
    outward &= np.sign(np.sum(line * fwd, -1)) == np.sign(np.sum((W - o[:, 0]) * fwd, -1))
    # q5s: q5 that lines axis 6 up with axis 4 (0 for these arms, computed anyway)
    w4, w5, w6 = w0[0, 3], w0[0, 4], w0[0, 5]
    a6, a4 = w6 - (w6 @ w5) * w5, w4 - (w4 @ w5) * w5
    q5s = math.atan2(np.cross(a6, a4) @ w5, a6 @ a4)
    for b, label in enumerate(solver.configs):
        sel = ok.reshape(-1, k)[:, b]
        idx = np.flatnonzero(sel) * k + b
        assert idx.size > 50
        shoulder, elbow, wrist = label.split("_")
        assert (front[idx] == (shoulder == "front")).all(), label
        out = idx[outward[idx]]
        assert out.size > 20
        assert (above[out] == (elbow == "up")).all(), label
        s5 = np.sin(qf[idx, 4] - q5s)
        assert ((s5 <= 1e-12) if wrist == "noflip" else (s5 >= -1e-12)).all(), label


# -- an independent closed form: Corke's Robotics Toolbox -----------------------------------


def test_puma560_agrees_with_robotics_toolbox_ikine_a():
    rtb = pytest.importorskip("roboticstoolbox")
    puma = rtb.models.DH.Puma560()
    desc = _load("puma560")
    solver = analytic_solver(desc)
    q = _random_q(desc, np.random.default_rng(560), 12)
    T = _fk(desc, q)
    for Ti, qi in zip(T, q):
        assert np.abs(puma.fkine(qi).A - Ti).max() < 1e-12  # same model (d1 = 0.6718)
    qs, valid = _solve_quietly(solver, T, limits=False)  # rtb ignores the limits
    letters = {"front": "r", "back": "l", "up": "u", "down": "d", "noflip": "n", "flip": "f"}
    for i, Ti in enumerate(T):
        theirs = []
        for b, label in enumerate(solver.configs):
            config = "".join(letters[p] for p in label.split("_"))
            sol = puma.ikine_a(Ti, config=config)
            assert sol.success == valid[i, b]
            if sol.success:
                theirs.append(np.asarray(sol.q))
                # same solution under the same name
                assert _joint_diff(desc, qs[i, b], sol.q).max() < 1e-8
        # and the same set
        ours = qs[i][valid[i]]
        d = _joint_diff(desc, ours[:, None], np.array(theirs)[None]).max(-1)
        assert (d.min(axis=1) < 1e-8).all() and (d.min(axis=0) < 1e-8).all()


def test_solver_refuses_position_only_where_the_tool_point_moves_with_the_roll():
    rows = [
        dict(a=0.45, alpha=0.0, d=0.5),
        dict(a=0.35, alpha_deg=180, d=0.0),
        dict(type="prismatic", a=0.0, alpha=0.0, theta=0.0),
        dict(a=0.05, alpha=0.0, d=0.0),
    ]  # tool point 5 cm off the roll axis
    desc = SerialDescription.from_rows(rows, "standard", name="offset_scara")
    solver = analytic_solver(desc)
    assert solver is not None and solver.structure == "planar"
    q = _random_q(desc, np.random.default_rng(3), 200)
    q[:, 2] = np.random.default_rng(4).uniform(0, 0.3, 200)
    T, qs, valid, err_p, err_r = _round_trip(desc, solver, q)
    assert valid.any(axis=1).all() and max(err_p[valid].max(), err_r[valid].max()) < 1e-10
    with pytest.raises(InputError):
        solver.solve(T, position_only=True)


def test_the_numpy_solver_runs_the_recipes_without_sympy():
    """solve/analytic.py runs the closed forms of derive/serial/ik_recipes.py (one recipe,
    two back ends: docs/architecture.md): importing it and solving must not load SymPy,
    which only the C kernel's back end (derive/serial/ik_closed_form.py) uses."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import numpy as np\n"
        "from deltagen.model.serial import SerialDescription\n"
        "from deltagen.paths import robots_dir\n"
        "from deltagen.solve.analytic import analytic_solver\n"
        "s = analytic_solver(SerialDescription.from_toml(robots_dir() / 'puma560.toml'))\n"
        "T = np.eye(4)\n"
        "T[:3, 3] = 0.3, 0.2, 0.4\n"
        "s.solve(T)\n"
        "print('sympy' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
