"""The delta robot's exact inverse dynamics against MuJoCo, a multibody engine that knows
nothing of the derivation (a multibody simulation written independently of deltagen).

The closed chain is built here from MuJoCo bodies: three cranks on hinges about their drive
axes, three rod pairs (each a slender rod of mass m_b on a universal joint at the crank tip:
a first hinge parallel to the drive axis, as the parallelogram's knee axis is, then a second
one across it), the platform on three slides (the parallelograms keep it from turning), and
three `connect` equality constraints closing each loop at C_i = P + r_b e_i (delta report,
Figure 4). MuJoCo computes the bodies' dynamics (its recursive Newton-Euler, mj_rne) and the
constraint Jacobian (efc_J) itself.

* Inverse dynamics: for a consistent state the motor torques are tau = G^T f, with f the
  unconstrained generalized forces of MuJoCo's tree (mj_rne: M xdd + bias - gravity) and G
  the map from crank rates to all joint rates read off MuJoCo's own constraint Jacobian
  (the principle of virtual work on MuJoCo's model). That must equal deltagen's exact model.
* Forward simulation: MuJoCo integrates its constrained equations of motion driven by
  deltagen's feed-forward torques, open loop, along the report's trajectory; the platform
  must follow the plan (any model error makes it drift) and the simplified model's torques
  must not.

The rod's spin about its own axis carries no energy in deltagen's model (slender rods);
MuJoCo gets a spin inertia 1e-9 of the transverse one, too small to show at the tolerances
asserted (its largest effect, I_spin w_spin^2, is ~1e-9 of the rod's rotational terms).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from delta_oracles import irregular_dynamic_robot

from deltagen import DeltaRobot
from deltagen.apps.validate import trajectory

mujoco = pytest.importorskip("mujoco", reason="MuJoCo (pip install mujoco) is the oracle here")

SPIN = 1e-9  # rod spin inertia relative to the transverse one (slender rod: 0)

IRREGULAR = irregular_dynamic_robot()
ROBOTS = {"default": DeltaRobot.default(), "irregular": IRREGULAR}


def _v(x):
    return " ".join(repr(float(c)) for c in x)


def _frames(theta):
    """Radial e_i and tangential e_t = e_z x e_i unit vectors of drive i. Turning about e_t
    by q takes e_i to cos q e_i - sin q e_z: q positive = crank down (the report's sign)."""
    e = np.array([math.cos(theta), math.sin(theta), 0.0])
    return e, np.array([-math.sin(theta), math.cos(theta), 0.0])


def delta_mjcf(robot: DeltaRobot, timestep: float = 1e-4) -> str:
    """MJCF of the closed-chain delta robot, from the geometry and DeltaInertia alone."""
    g, m = robot.geometry, robot.inertia
    assert m is not None
    I_crank = m.I_a - m.m_a * m.r_ca**2  # about the centre of mass: I_a is about the axis
    assert I_crank > 0.0
    I_rod = m.m_b * g.l_b**2 / 12.0
    parts = []
    for i, th in enumerate(g.theta):
        e, et = _frames(th)
        # rod frame = world frame at zero joint angles, rod hanging along -z
        parts.append(
            f"""
    <body name="crank{i}" pos="{_v(g.r_a * e)}">
      <joint name="q{i}" type="hinge" axis="{_v(et)}"/>
      <inertial pos="{_v(m.r_ca * e)}" mass="{m.m_a!r}"
                diaginertia="{I_crank!r} {I_crank!r} {I_crank!r}"/>
      <body name="rod{i}" pos="{_v(g.l_a * e)}">
        <joint name="alpha{i}" type="hinge" axis="{_v(et)}"/>
        <joint name="beta{i}" type="hinge" axis="{_v(e)}"/>
        <inertial pos="0 0 {-g.l_b / 2!r}" mass="{m.m_b!r}"
                  diaginertia="{I_rod!r} {I_rod!r} {SPIN * I_rod!r}"/>
        <site name="rod_end{i}" pos="0 0 {-g.l_b!r}"/>
      </body>
    </body>"""
        )
    sites = "".join(
        f'\n      <site name="platform{i}" pos="{_v(g.r_b * _frames(th)[0])}"/>'
        for i, th in enumerate(g.theta)
    )
    connects = "".join(
        f'\n    <connect site1="rod_end{i}" site2="platform{i}" solref="{4 * timestep!r} 1"'
        ' solimp="0.9999 0.9999 0.001 0.5 2"/>'
        for i in range(3)
    )
    motors = "".join(f'\n    <motor joint="q{i}" gear="1"/>' for i in range(3))
    return f"""<mujoco model="delta">
  <option timestep="{timestep!r}" gravity="{_v(m.gravity)}" integrator="RK4">
    <flag contact="disable"/>
  </option>
  <worldbody>{"".join(parts)}
    <body name="platform">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="{m.m_p!r}" diaginertia="1e-3 1e-3 1e-3"/>{sites}
    </body>
  </worldbody>
  <equality>{connects}
  </equality>
  <actuator>{motors}
  </actuator>
</mujoco>"""


def _rod_angles(e, et, u):
    """Universal-joint angles (alpha_total, beta) putting the rod along unit vector u:
    u = Rot(e_t, alpha) Rot(e_i, beta) (-e_z), so u . e_t = sin(beta) and
    -u . e_i = cos(beta) sin(alpha), -u . e_z = cos(beta) cos(alpha)."""
    return np.arctan2(-u @ e, -u @ np.array([0.0, 0.0, 1.0])), np.arcsin(u @ et)


def full_position(robot, q):
    """MuJoCo qpos (q_i, alpha_i, beta_i per chain, then x, y, z) of crank angles q: the
    platform from deltagen's fk (kinematics, checked elsewhere against Klipper and the
    report), the rods pointing from crank tip B_i to C_i."""
    g = robot.geometry
    p = robot.fk(q)[:3]
    x = []
    for i, th in enumerate(g.theta):
        e, et = _frames(th)
        B = g.r_a * e + g.l_a * (math.cos(q[i]) * e - math.sin(q[i]) * np.array([0, 0, 1.0]))
        u = (p + g.r_b * e - B) / g.l_b
        alpha, beta = _rod_angles(e, et, u)
        x += [q[i], alpha - q[i], beta]  # the rod's first hinge turns relative to the crank
    return np.array(x + list(p))


CRANKS = [0, 3, 6]
OTHERS = [1, 2, 4, 5, 7, 8, 9, 10, 11]


def crank_map(model, data):
    """G (12 x 3): all joint rates per unit crank rate, from MuJoCo's constraint Jacobian
    efc_J (9 x 12): J_q qd + J_o xd_o = 0 -> xd_o = -J_o^-1 J_q qd."""
    mujoco.mj_forward(model, data)
    Jc = data.efc_J.reshape(data.nefc, model.nv)
    assert data.nefc == 9
    G = np.zeros((12, 3))
    G[CRANKS, :] = np.eye(3)
    G[OTHERS, :] = -np.linalg.solve(Jc[:, OTHERS], Jc[:, CRANKS])
    return G, Jc


def _site_acceleration(model, data, name):
    acc = np.zeros(6)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    mujoco.mj_objectAcceleration(model, data, mujoco.mjtObj.mjOBJ_SITE, site, acc, 0)
    return acc[3:]


def _consistent_state(model, data, robot, q, qd, qdd):
    """Set qpos, qvel, qacc on the constraint manifold: qvel = G qd; qacc from the
    acceleration-level constraint J xdd + Jdot xd = 0. Jdot xd is the relative acceleration
    of the two sites of each loop closure when xdd = 0, from MuJoCo's own body accelerations
    (gravity, which MuJoCo adds to every body alike, cancels in the difference)."""
    data.qpos[:] = full_position(robot, q)
    G, Jc = crank_map(model, data)
    xd = G @ qd
    data.qvel[:] = xd
    mujoco.mj_forward(model, data)  # velocity-dependent kinematics (cdof_dot)
    data.qacc[:] = 0.0
    mujoco.mj_rnePostConstraint(model, data)
    Jdot_xd = np.concatenate(
        [
            _site_acceleration(model, data, f"rod_end{i}")
            - _site_acceleration(model, data, f"platform{i}")
            for i in range(3)
        ]
    )
    xdd = np.zeros(12)
    xdd[CRANKS] = qdd
    xdd[OTHERS] = -np.linalg.solve(Jc[:, OTHERS], Jc[:, CRANKS] @ qdd + Jdot_xd)
    data.qacc[:] = xdd
    return G


@pytest.fixture(scope="module", params=list(ROBOTS), ids=list(ROBOTS))
def robot_model(request):
    robot = ROBOTS[request.param]
    model = mujoco.MjModel.from_xml_string(delta_mjcf(robot))
    return robot, model


def test_assembled_pose_satisfies_mujocos_constraints(robot_model):
    """The state construction is right before anything is compared: MuJoCo's own
    constraint residual vanishes at the assembled pose, for every rod."""
    robot, model = robot_model
    data = mujoco.MjData(model)
    q = robot.ik(np.array([0.05, -0.08, -0.7 * robot.geometry.l_b]))
    data.qpos[:] = full_position(robot, q)
    mujoco.mj_forward(model, data)
    assert np.abs(data.efc_pos[:9]).max() < 1e-13 * robot.geometry.l_b
    # and a crank displaced alone violates them: the loops really are closed
    data.qpos[0] += 1e-3
    mujoco.mj_forward(model, data)
    assert np.abs(data.efc_pos[:9]).max() > 1e-5


def test_exact_model_equals_mujocos_virtual_work(robot_model):
    """tau = G^T f on MuJoCo's tree equals deltagen's exact model on random states."""
    robot, model = robot_model
    data = mujoco.MjData(model)
    rng = np.random.default_rng(5)
    lb = robot.geometry.l_b
    n = 0
    worst = 0.0
    while n < 40:
        p = np.array([*rng.uniform(-0.3, 0.3, 2) * lb, rng.uniform(-0.9, -0.5) * lb])
        q, ok = robot.ik(p, errors="nan")
        if not ok:
            continue
        n += 1
        qd = rng.normal(0.0, 3.0, 3)
        qdd = rng.normal(0.0, 40.0, 3)
        G = _consistent_state(model, data, robot, q, qd, qdd)
        f = np.zeros(12)
        mujoco.mj_rne(model, data, 1, f)  # M qacc + bias forces incl. gravity
        tau_mujoco = G.T @ f
        tau = robot.inverse_dynamics(q, qd, qdd)[:3]
        scale = np.abs(tau_mujoco).max() + 1.0
        worst = max(worst, np.abs(tau - tau_mujoco).max() / scale)
        # the simplified model is a different model: it differs by far more
        simple = robot.inverse_dynamics(q, qd, qdd, model="simplified")[:3]
        assert np.abs(simple - tau_mujoco).max() / scale > 1e3 * max(worst, 1e-9)
    assert worst < 1e-10, worst  # measured 7e-12 and 9e-12 (relative to |tau| + 1 N m)


def test_mujoco_driven_by_feedforward_follows_the_report_trajectory():
    """MuJoCo's constrained forward dynamics (RK4, 0.1 ms, stiff loop closures) under
    deltagen's exact feed-forward torques, open loop over the first 0.3 s of the report's
    trajectory (eqs. (40)-(42)): the platform stays on the plan; the simplified model's
    torques drive it off by far more."""
    robot = DeltaRobot.default()
    dt = 1e-4
    model = mujoco.MjModel.from_xml_string(delta_mjcf(robot, dt))
    steps = 3000

    def run(model_name):
        data = mujoco.MjData(model)
        t = np.arange(steps + 1) * dt
        p, pd, pdd = trajectory(t)
        q, qd, qdd = robot.ik_acc(p[:, :3], pd[:, :3], pdd[:, :3])
        tau = robot.inverse_dynamics(q, qd, qdd, model=model_name)[:, :3]
        _consistent_state(model, data, robot, q[0], qd[0], qdd[0])
        err = 0.0
        for k in range(steps):
            # zero-order hold at the step's midpoint torque: RK4 sees one torque per step
            data.ctrl[:] = 0.5 * (tau[k] + tau[k + 1])
            mujoco.mj_step(model, data)
            err = max(err, float(np.linalg.norm(data.qpos[9:12] - p[k + 1, :3])))
        return err

    exact = run("exact")
    simplified = run("simplified")
    # measured: 2.0e-6 m (exact; the loop closures' compliance and the torque hold) and
    # 0.20 m (simplified) with MuJoCo 4.0 on x86_64
    assert exact < 1e-5, exact
    assert simplified > 1e3 * exact, (exact, simplified)
