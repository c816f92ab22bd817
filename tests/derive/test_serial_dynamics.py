"""Serial-arm dynamics (derive/serial/dynamics.py, generated C, reference, API) against
independent evidence:

* pinocchio (rnea, crba, computeGeneralizedGravity, aba) on a model built here from the
  same description (joint placements from the DH / universal-coordinate rows, link inertias
  appended in link frame i, armature in model.armature; friction added here from its
  definition in model/serial.py), >= 1000 random states, to 1e-10 relative;
* roboticstoolbox's Puma560 (its own parameters): rne with its friction off, rne with its
  friction model, inertia, gravload;
* the energy identity dE/dt = qd . tau (rigid-body torques) along a random trajectory, the
  energy from M and the link centres of mass, the power integrated finely;
* Mdot - 2C skew-symmetric and C built from the Christoffel symbols of finite-difference dM/dq;
* forward(inverse(qdd)) = qdd; compiled against the Jacobian-form numpy reference to 1e-12.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.errors import GeometryError, SingularityError
from deltagen.inputs import InputError
from deltagen.model.serial import SerialDescription, transform

COUNT = 1000
REL = 1e-10


def _rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(1.0, np.max(np.abs(b))))


# A made-up 4-joint arm, modified DH, revolute-prismatic-revolute-revolute, with a rotated
# and shifted base, a tool, products of inertia, armature, asymmetric friction and a tilted
# gravity vector (numbers chosen here, no source).
TOY_ROWS = [
    dict(
        type="revolute",
        a=0.0,
        alpha=0.0,
        d=0.3,
        offset=0.2,
        mass=3.0,
        com=[0.02, -0.01, -0.1],
        inertia=[0.05, 0.06, 0.04, 0.002, -0.001, 0.003],
        armature=0.4,
        viscous=1.5,
        coulomb=[2.0, -1.5],
    ),
    dict(
        type="prismatic",
        a=0.1,
        alpha_deg=-90,
        theta=0.3,
        offset=0.15,
        mass=2.0,
        com=[0.0, 0.05, -0.2],
        inertia=[0.03, 0.03, 0.01, 0.0, 0.001, 0.0],
        armature=1.2,
        viscous=20.0,
        coulomb=5.0,
    ),
    dict(
        type="revolute",
        a=0.05,
        alpha_deg=90,
        d=0.12,
        mass=1.5,
        com=[0.1, 0.0, 0.02],
        inertia=[0.01, 0.02, 0.02, -0.002, 0.0, 0.001],
        armature=0.2,
        viscous=0.5,
        coulomb=[0.3, -0.4],
    ),
    dict(
        type="revolute",
        a=0.25,
        alpha=0.4,
        d=-0.05,
        offset=-0.3,
        mass=0.8,
        com=[0.05, 0.02, 0.0],
        inertia=[0.004, 0.006, 0.005, 0.0, 0.0005, 0.0],
        armature=0.05,
    ),
]
TOY_BASE = transform([0.1, -0.2, 0.4], [0.1, -0.2, 0.5])
TOY_TOOL = transform([0.0, 0.0, 0.07], [0.0, 0.3, 0.0])
TOY_GRAVITY = (0.4, -0.3, -9.7)


def toy(convention="modified", rows=TOY_ROWS):
    return SerialDescription.from_rows(
        rows,
        convention,
        name=f"toy_dyn_{convention}",
        base=TOY_BASE,
        tool=TOY_TOOL,
        gravity=TOY_GRAVITY,
    )


def toy_universal():
    axes = ["z", "x", "y", "z"]
    rows = []
    for row, axis, k in zip(TOY_ROWS, axes, range(4)):
        r = {key: row[key] for key in ("type", "mass", "com", "inertia") if key in row}
        r.update(
            axis=axis,
            tx=0.1 * k,
            ty=-0.05,
            tz=0.2,
            rx=0.3,
            ry=-0.2 * k,
            rz=0.1,
            offset=row.get("offset", 0.0),
            armature=row.get("armature", 0.0),
        )
        rows.append(r)
    return toy("universal", rows)


@pytest.fixture(scope="module")
def puma():
    return SerialRobot.load("puma560")


@pytest.fixture(scope="module")
def toy_arm():
    """The made-up modified-DH arm, compiled through the build cache (about a minute on a
    busy machine the first time: its tests are marked slow)."""
    return SerialRobot(toy())


ARMS = ["puma", pytest.param("toy", marks=pytest.mark.slow)]


@pytest.fixture
def arm(request):
    """The arm a test is parametrised with: the bundled Puma560 or the made-up toy."""
    return request.getfixturevalue("puma" if request.param == "puma" else "toy_arm")


def _states(robot, count, seed):
    rng = np.random.default_rng(seed)
    n = robot.n
    lim = np.where(np.isfinite(robot.qlim), robot.qlim, [-1.0, 1.0])
    q = rng.uniform(lim[:, 0], lim[:, 1], (count, n))
    qd = rng.uniform(-3, 3, (count, n))
    qdd = rng.uniform(-10, 10, (count, n))
    return q, qd, qdd


def _friction(desc, qd):
    """viscous qd + Tc+ (qd > 0) / Tc- (qd < 0): the definition in model/serial.py."""
    inertials = [j.inertial for j in desc.joints]
    viscous = np.array([x.viscous for x in inertials])
    plus = np.array([x.coulomb[0] for x in inertials])
    minus = np.array([x.coulomb[1] for x in inertials])
    return viscous * qd + np.where(qd > 0, plus, 0.0) + np.where(qd < 0, minus, 0.0)


# ------------------------------------------------------------------------- pinocchio


def _rot(axis, angle):
    c, s = math.cos(angle), math.sin(angle)
    R = {
        "x": [[1, 0, 0], [0, c, -s], [0, s, c]],
        "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
        "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]],
    }[axis]
    T = np.eye(4)
    T[:3, :3] = R
    return T


def _trans(axis, dist):
    T = np.eye(4)
    T["xyz".index(axis), 3] = dist
    return T


def _split(desc, i):
    """(pre, axis, post) of A_i = pre . Motion_axis(q_i) . post, written from the
    conventions of model/serial.py's docstring (the offset goes into pre)."""
    j = desc.joints[i]
    if desc.convention == "universal":
        pre = _rot(j.axis, j.offset) if j.revolute else _trans(j.axis, j.offset)
        post = (
            _trans("x", j.tx)
            @ _trans("y", j.ty)
            @ _trans("z", j.tz)
            @ _rot("x", j.rx)
            @ _rot("y", j.ry)
            @ _rot("z", j.rz)
        )
        return pre, j.axis, post
    if desc.convention == "standard":
        if j.revolute:
            return (
                _rot("z", j.offset),
                "z",
                _trans("z", j.d) @ _trans("x", j.a) @ _rot("x", j.alpha),
            )
        return (
            _rot("z", j.theta) @ _trans("z", j.offset),
            "z",
            _trans("x", j.a) @ _rot("x", j.alpha),
        )
    before = _rot("x", j.alpha) @ _trans("x", j.a)
    if j.revolute:
        return before @ _rot("z", j.offset), "z", _trans("z", j.d)
    return before @ _rot("z", j.theta) @ _trans("z", j.offset), "z", np.eye(4)


def pinocchio_model(desc):
    pin = pytest.importorskip("pinocchio")
    model = pin.Model()
    parent, placement = 0, desc.base
    for i, joint in enumerate(desc.joints):
        pre, axis, post = _split(desc, i)
        kind = {
            ("revolute", "x"): pin.JointModelRX,
            ("revolute", "y"): pin.JointModelRY,
            ("revolute", "z"): pin.JointModelRZ,
            ("prismatic", "x"): pin.JointModelPX,
            ("prismatic", "y"): pin.JointModelPY,
            ("prismatic", "z"): pin.JointModelPZ,
        }[(joint.type, axis)]()
        M = placement @ pre
        parent = model.addJoint(parent, kind, pin.SE3(M[:3, :3].copy(), M[:3, 3].copy()), f"j{i}")
        x = joint.inertial
        body = pin.Inertia(x.mass, np.array(x.com), x.inertia_matrix)
        model.appendBodyToJoint(parent, body, pin.SE3(post[:3, :3].copy(), post[:3, 3].copy()))
        placement = post
    model.armature = np.array([j.inertial.armature for j in desc.joints])
    model.gravity.linear = np.array(desc.gravity)
    return pin, model, model.createData()


def _pinocchio_all(desc, q, qd, qdd):
    pin, model, data = pinocchio_model(desc)
    out = {k: [] for k in ("tau", "M", "g", "qdd", "C")}
    for a, b, c in zip(q, qd, qdd):
        tau = pin.rnea(model, data, a, b, c).copy()
        out["tau"].append(tau)
        out["M"].append(pin.crba(model, data, a).copy())
        out["g"].append(pin.computeGeneralizedGravity(model, data, a).copy())
        out["qdd"].append(pin.aba(model, data, a, b, tau).copy())
        out["C"].append(pin.computeCoriolisMatrix(model, data, a, b).copy())
    out = {k: np.array(v) for k, v in out.items()}
    out["M"] = np.triu(out["M"]) + np.triu(out["M"], 1).transpose(0, 2, 1)  # crba: upper
    return out


@pytest.mark.parametrize("arm", ARMS, indirect=True)
def test_against_pinocchio(arm):
    robot = arm
    desc = robot.description
    q, qd, qdd = _states(robot, COUNT, 11)
    pin = _pinocchio_all(desc, q, qd, qdd)
    friction = _friction(desc, qd)
    tau = robot.inverse_dynamics(q, qd, qdd)
    assert _rel(tau, pin["tau"] + friction) <= REL
    assert _rel(robot.mass_matrix(q), pin["M"]) <= REL
    assert _rel(robot.gravity_torque(q), pin["g"]) <= REL
    # forward dynamics of the rigid-body torque (friction added back) is pinocchio's aba
    assert _rel(robot.forward_dynamics(q, qd, pin["tau"] + friction), qdd) <= 1e-9
    assert _rel(robot.forward_dynamics(q, qd, tau), pin["qdd"]) <= 1e-9
    # C qd: pinocchio's C is Mdot - 2C skew too, and C qd is the same Coriolis vector
    Cqd = np.einsum("nij,nj->ni", robot.coriolis(q, qd), qd)
    assert _rel(Cqd, np.einsum("nij,nj->ni", pin["C"], qd)) <= REL


@pytest.mark.parametrize("convention", ["standard", "modified", "universal"])
def test_reference_against_pinocchio_every_convention(convention):
    """The numpy reference (which the compiled core matches, below) in all three
    conventions, with a prismatic joint, base, tool and tilted gravity."""
    desc = toy_universal() if convention == "universal" else toy(convention)
    robot = SerialRobot(desc, backend="reference")
    q, qd, qdd = _states(robot, 200, 3)
    pin = _pinocchio_all(desc, q, qd, qdd)
    assert _rel(robot.inverse_dynamics(q, qd, qdd), pin["tau"] + _friction(desc, qd)) <= REL
    assert _rel(robot.mass_matrix(q), pin["M"]) <= REL
    assert _rel(robot.gravity_torque(q), pin["g"]) <= REL


# ---------------------------------------------------------------- roboticstoolbox Puma560


@pytest.fixture(scope="module")
def rtb_puma():
    rtb = pytest.importorskip("roboticstoolbox")
    return rtb.models.DH.Puma560()


def test_puma_against_rtb_rne(puma, rtb_puma):
    q, qd, qdd = _states(puma, COUNT, 5)
    # its friction off (both kinds; nofriction() alone keeps the viscous part)
    rigid = rtb_puma.nofriction(coulomb=True, viscous=True).rne(q, qd, qdd)
    frictionless = SerialRobot(puma.description.without_friction(), backend="reference")
    assert _rel(frictionless.inverse_dynamics(q, qd, qdd), rigid) <= REL
    # its friction model (B G^2 qd + |G| Tc at the motor, reflected): our compiled arm
    assert _rel(puma.inverse_dynamics(q, qd, qdd), rtb_puma.rne(q, qd, qdd)) <= REL
    assert _rel(puma.mass_matrix(q[:200]), rtb_puma.inertia(q[:200])) <= REL
    assert _rel(puma.gravity_torque(q[:200]), rtb_puma.gravload(q[:200])) <= REL


def test_puma_parameters_are_rtbs(puma, rtb_puma):
    for j, link in zip(puma.description.joints, rtb_puma.links):
        x = j.inertial
        assert x.mass == link.m
        np.testing.assert_array_equal(x.com, link.r)
        np.testing.assert_array_equal(x.inertia_matrix, link.I)
        assert math.isclose(x.armature, link.Jm * link.G**2, rel_tol=1e-15)
        assert math.isclose(x.viscous, link.B * link.G**2, rel_tol=1e-15)
        np.testing.assert_allclose(x.coulomb, abs(link.G) * np.asarray(link.Tc), rtol=1e-15)
    np.testing.assert_array_equal(puma.description.gravity, rtb_puma.gravity)


# ------------------------------------------------------------- laws of mechanics


def _energy(robot, q, qd):
    """Kinetic 1/2 qd M qd (armature included) plus potential -sum m_i g . c_i, with the
    centres of mass c_i from the frames (kinematics only)."""
    desc = robot.description
    M = robot.mass_matrix(q)
    F = robot.frames(q)  # base, links 1..n, tool
    V = np.zeros(q.shape[0])
    for i, j in enumerate(desc.joints):
        c = F[:, i + 1, :3, :3] @ np.array(j.inertial.com) + F[:, i + 1, :3, 3]
        V -= j.inertial.mass * c @ np.array(desc.gravity)
    return 0.5 * np.einsum("ni,nij,nj->n", qd, M, qd) + V


@pytest.mark.parametrize("arm", ARMS, indirect=True)
def test_energy_identity(arm):
    """E(t1) - E(t0) = integral of qd . tau_rigid dt along a random smooth trajectory
    (Simpson's rule on 4001 points); tau_rigid = tau - friction."""
    robot = arm
    rng = np.random.default_rng(7)
    n = robot.n
    t = np.linspace(0.0, 1.0, 4001)[:, None]
    amp, freq, phase = rng.uniform(0.2, 0.8, n), rng.uniform(1, 4, n), rng.uniform(0, 6, n)
    q = amp * np.sin(freq * t + phase)
    qd = amp * freq * np.cos(freq * t + phase)
    qdd = -amp * freq**2 * np.sin(freq * t + phase)
    power = np.einsum(
        "ni,ni->n", qd, robot.inverse_dynamics(q, qd, qdd) - _friction(robot.description, qd)
    )
    h = t[1, 0] - t[0, 0]
    work = h / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
    E = _energy(robot, q[[0, -1]], qd[[0, -1]])
    assert abs((E[1] - E[0]) - work) <= 1e-9 * max(1.0, np.abs(power).max())


@pytest.mark.parametrize("arm", ARMS, indirect=True)
def test_coriolis_is_christoffel_and_skew(arm):
    robot = arm
    q, qd, _ = _states(robot, 50, 9)
    n, eps = robot.n, 1e-6
    C = robot.coriolis(q, qd)
    # Mdot along qd by central differences: Mdot - 2C skew-symmetric
    Mdot = (robot.mass_matrix(q + eps * qd) - robot.mass_matrix(q - eps * qd)) / (2 * eps)
    S = Mdot - 2 * C
    scale = np.abs(Mdot).max()
    assert np.abs(S + S.transpose(0, 2, 1)).max() <= 1e-7 * scale
    # C_kj = sum_i 1/2 (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k) qd_i (Christoffel symbols)
    dM = np.stack(
        [
            (robot.mass_matrix(q + eps * e) - robot.mass_matrix(q - eps * e)) / (2 * eps)
            for e in np.eye(n)
        ],
        axis=1,
    )  # (N, i, k, j) = dM_kj / dq_i
    christoffel = 0.5 * (
        np.einsum("nikj,ni->nkj", dM, qd)
        + np.einsum("njki,ni->nkj", dM, qd)
        - np.einsum("nkij,ni->nkj", dM, qd)
    )
    assert np.abs(C - christoffel).max() <= 1e-7 * max(1.0, np.abs(C).max())
    # and C qd + g + friction is the torque at qdd = 0
    h = np.einsum("nij,nj->ni", C, qd) + robot.gravity_torque(q) + _friction(robot.description, qd)
    assert _rel(h, robot.nonlinear_effects(q, qd)) <= REL
    assert _rel(h, robot.inverse_dynamics(q, qd, 0.0 * qd)) <= REL


@pytest.mark.parametrize("arm", ARMS, indirect=True)
def test_forward_inverse_round_trip(arm):
    robot = arm
    q, qd, qdd = _states(robot, COUNT, 13)
    tau = robot.inverse_dynamics(q, qd, qdd)
    assert _rel(robot.forward_dynamics(q, qd, tau), qdd) <= 1e-10


@pytest.mark.parametrize("arm", ARMS, indirect=True)
def test_compiled_matches_reference(arm):
    robot = arm
    ref = robot.with_backend("reference")
    q, qd, qdd = _states(robot, COUNT, 17)
    tau = robot.inverse_dynamics(q, qd, qdd)
    pairs = [
        (tau, ref.inverse_dynamics(q, qd, qdd)),
        (robot.mass_matrix(q), ref.mass_matrix(q)),
        (robot.gravity_torque(q), ref.gravity_torque(q)),
        (robot.coriolis(q, qd), ref.coriolis(q, qd)),
        (robot.nonlinear_effects(q, qd), ref.nonlinear_effects(q, qd)),
        (robot.forward_dynamics(q, qd, tau), ref.forward_dynamics(q, qd, tau)),
    ]
    for got, want in pairs:
        assert _rel(got, want) <= 1e-12


# ---------------------------------------------------------------- API behaviour


def test_single_call_matches_batch_and_broadcasts(puma):
    q, qd, qdd = _states(puma, 4, 1)
    tau = puma.inverse_dynamics(q, qd, qdd)
    for k in range(4):
        # (the batch's vectorised loops may round the last bit differently)
        np.testing.assert_allclose(puma.inverse_dynamics(q[k], qd[k], qdd[k]), tau[k], rtol=1e-13)
        np.testing.assert_allclose(
            puma.inverse_dynamics(list(q[k]), qd[k], qdd[k]), tau[k], rtol=1e-13
        )
        np.testing.assert_allclose(
            puma.forward_dynamics(q[k], qd[k], tau[k]),
            puma.forward_dynamics(q, qd, tau)[k],
            rtol=1e-13,
        )
    M = puma.mass_matrix(q)
    for k in range(4):
        np.testing.assert_allclose(puma.mass_matrix(q[k]), M[k], rtol=1e-13, atol=1e-15)
    with pytest.raises(InputError, match=r"rows \[0\]"):
        puma.mass_matrix(np.full(6, np.nan))  # the single-call path checks too
    assert puma.inverse_dynamics(q[0], np.zeros((2, 3, 6)), qdd[0]).shape == (2, 3, 6)
    assert puma.mass_matrix(q.reshape(2, 2, 6)).shape == (2, 2, 6, 6)
    assert puma.coriolis(q[0], qd).shape == (4, 6, 6)


def test_bad_rows_raise_or_nan(puma):
    q, qd, qdd = _states(puma, 5, 2)
    q[1, 3] = np.nan
    qd[3, 0] = np.inf
    with pytest.raises(InputError, match=r"rows \[1, 3\]"):
        puma.inverse_dynamics(q, qd, qdd)
    with pytest.raises(InputError, match=r"rows \[0\]"):
        puma.inverse_dynamics(q[1], qd[1], qdd[1])  # the single-call path checks too
    tau, valid = puma.inverse_dynamics(q, qd, qdd, errors="nan")
    assert valid.tolist() == [True, False, True, False, True]
    assert np.isnan(tau[[1, 3]]).all() and np.isfinite(tau[[0, 2, 4]]).all()
    qdd_out, valid = puma.forward_dynamics(q, qd, np.zeros_like(q), errors="nan")
    assert valid.tolist() == [True, False, True, False, True]
    assert np.isnan(qdd_out[[1, 3]]).all()
    # an overflowing result is never valid
    tau, valid = puma.inverse_dynamics(q[0], np.full(6, 1e200), qdd[0], errors="nan")
    assert not valid and np.isnan(tau).all()
    with pytest.raises(InputError, match=r"shape \(\.\.\., 6\)"):
        puma.mass_matrix(np.zeros(5))


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_arm_without_inertia_says_so(backend):
    arm = SerialRobot.load("manutec_r15", backend=backend)
    for call in (
        lambda: arm.inverse_dynamics(np.zeros(6), np.zeros(6), np.zeros(6)),
        lambda: arm.mass_matrix(np.zeros(6)),
        lambda: arm.forward_dynamics(np.zeros(6), np.zeros(6), np.zeros(6)),
    ):
        with pytest.raises(InputError, match="no inertial parameters"):
            call()


@pytest.mark.slow  # compiles a small arm
def test_massless_arm_forward_dynamics_is_singular():
    desc = SerialDescription.from_rows(
        [dict(type="revolute", a=0.3, mass=0.0), dict(type="revolute", a=0.2, mass=1.0)],
        "standard",
        name="toy_dyn_massless",
    )
    for backend in ("compiled", "reference"):
        arm = SerialRobot(desc, backend=backend)
        with pytest.raises(SingularityError, match="not positive definite"):
            arm.forward_dynamics(np.zeros(2), np.zeros(2), np.ones(2))
        qdd, valid = arm.forward_dynamics(np.zeros((2, 2)), np.zeros(2), np.ones(2), errors="nan")
        assert not valid.any() and np.isnan(qdd).all()


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(mass=-1.0), "mass must be >= 0"),
        (dict(inertia=[1.0, 1.0, -1.0, 0, 0, 0]), "not positive semidefinite"),
        (dict(inertia=[1.0, 1.0]), "6 numbers"),
        (dict(com=[0.0, 0.0]), "3 numbers"),
        (dict(coulomb=[-1.0, 1.0]), "Tc\\+ >= 0"),
        (dict(viscous=-0.1), "viscous must be >= 0"),
        (dict(armature="heavy"), "armature must be a real number"),
    ],
)
def test_inertial_parameters_are_validated(change, message):
    rows = [dict(type="revolute", a=0.3, mass=1.0), dict(type="revolute", a=0.2, mass=1.0)]
    rows[1].update(change)
    with pytest.raises(GeometryError, match=message):
        SerialDescription.from_rows(rows, "standard")


def test_inertials_all_or_nothing_and_gravity_checked():
    with pytest.raises(GeometryError, match="all or nothing"):
        SerialDescription.from_rows(
            [dict(type="revolute", a=0.3, mass=1.0), dict(type="revolute", a=0.2)], "standard"
        )
    with pytest.raises(GeometryError, match="without mass"):
        SerialDescription.from_rows([dict(type="revolute", com=[0, 0, 0])], "standard")
    with pytest.raises(GeometryError, match="gravity"):
        SerialDescription.from_mapping(
            dict(convention="standard", gravity=[0, 0], joint=[dict(type="revolute", mass=1.0)])
        )
