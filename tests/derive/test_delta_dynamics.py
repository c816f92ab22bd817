"""Delta robot inverse dynamics: the derived C kernels against independent evidence.

* the reference's Newton-Euler formulation (every body with its reaction forces, a 21 x 21
  solve per state; deltagen/reference/delta.py) written without the derivation;
* the energy identity dE/dt = qdot . tau, with the kinetic energy integrated numerically
  along the rods here (Gauss-Legendre), not taken from any formula of the code;
* the payload's share of the torques as J^T m (pddot - g) from the kinematics alone;
* a symmetric positive-definite mass matrix;
* a forward simulation of the reference's equations driven by the C feed-forward torques
  follows the report's trajectory (eqs. (40)-(42)).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from delta_oracles import irregular_dynamic_robot

from deltagen import DeltaInertia, DeltaRobot, GeometryError, InputError, SingularityError
from deltagen.apps.validate import trajectory
from deltagen.model.delta import DeltaGeometry
from deltagen.paths import robots_dir
from deltagen.reference import delta as ref

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

DEFAULT = DeltaRobot.default()
IRREGULAR = irregular_dynamic_robot()
ROBOTS = {"default": DEFAULT, "irregular": IRREGULAR}
robots = pytest.mark.parametrize("robot", list(ROBOTS.values()), ids=list(ROBOTS))


def _states(robot, n, seed):
    """Random reachable, non-singular states (q from ik of random platform positions)."""
    rng = np.random.default_rng(seed)
    g = robot.geometry
    p = np.column_stack(
        (
            rng.uniform(-0.3, 0.3, 4 * n) * g.l_b,
            rng.uniform(-0.3, 0.3, 4 * n) * g.l_b,
            rng.uniform(-0.95, -0.45, 4 * n) * g.l_b,
        )
    )
    q, ok = robot.ik(p, errors="nan")
    _, okj = robot.jacobian(np.where(ok[:, None], q, 0.0), errors="nan")
    q = q[ok & okj][:n]
    assert len(q) == n
    qd = rng.normal(0.0, 4.0, (n, 3))
    qdd = rng.normal(0.0, 60.0, (n, 3))
    payload = rng.uniform(0.0, 3.0, n)
    return q, qd, qdd, payload


@robots
@pytest.mark.parametrize("model", ["exact", "simplified"])
def test_compiled_equals_newton_euler_reference(robot, model):
    q, qd, qdd, payload = _states(robot, 1500, seed=11)
    tau = robot.inverse_dynamics(q, qd, qdd, payload=payload, model=model)
    g = robot.geometry
    tau_ref, status = ref.inverse_dynamics(g, g.inertia, q, qd, qdd, payload, model=model)
    assert (status == 0).all()
    scale = np.abs(tau_ref).max(axis=1)
    rel = np.abs(tau - tau_ref).max(axis=1) / scale
    assert rel.max() < 1e-10, rel.max()
    # and the two backends of the API agree the same way
    tau_b = robot.with_backend("reference").inverse_dynamics(q, qd, qdd, payload, model=model)
    np.testing.assert_allclose(tau_b, tau_ref, rtol=0, atol=1e-12 * scale.max())


def test_the_models_differ_and_rod_rotation_matters():
    """The test above can tell the models apart: they differ by far more than 1e-10."""
    q, qd, qdd, payload = _states(DEFAULT, 200, seed=3)
    exact = DEFAULT.inverse_dynamics(q, qd, qdd, payload)
    simple = DEFAULT.inverse_dynamics(q, qd, qdd, payload, model="simplified")
    assert np.abs(exact - simple).max() > 1e-3 * np.abs(exact).max()
    # with massless rods they coincide
    light = DEFAULT.with_inertia(replace(DEFAULT.inertia, m_b=0.0))
    np.testing.assert_allclose(
        light.inverse_dynamics(q, qd, qdd, payload),
        light.inverse_dynamics(q, qd, qdd, payload, model="simplified"),
        rtol=1e-13,
        atol=1e-12,
    )


# -- energy identity ----------------------------------------------------------------------

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(4)  # exact for the quadratic integrand


def _energy(robot, q, qd, payload):
    """Kinetic + potential energy of the bodies, from positions and velocities only:
    cranks (I_a about the axis, gravity of m_a at r_ca), rods (mass m_b spread evenly
    from B_i to C_i, kinetic energy integrated along the rod), platform."""
    g, m = robot.geometry, robot.inertia
    grav = np.asarray(m.gravity)
    p, pd = robot.fk_vel(q, qd)
    T = 0.5 * m.I_a * (qd**2).sum(axis=1)
    V = np.zeros(len(q))
    for i, th in enumerate(g.theta):
        e_r = np.array([math.cos(th), math.sin(th), 0.0])
        e_z = np.array([0.0, 0.0, 1.0])
        direction = np.cos(q[:, i, None]) * e_r - np.sin(q[:, i, None]) * e_z
        d_direction = -np.sin(q[:, i, None]) * e_r - np.cos(q[:, i, None]) * e_z
        B = g.r_a * e_r + g.l_a * direction
        vB = g.l_a * d_direction * qd[:, i, None]
        C = p + g.r_b * e_r
        crank_com = g.r_a * e_r + m.r_ca * direction
        V -= m.m_a * crank_com @ grav
        for node, weight in zip(_NODES, _WEIGHTS):
            s = 0.5 * (node + 1.0)  # 0 at B, 1 at C
            v = (1 - s) * vB + s * pd
            x = (1 - s) * B + s * C
            T += 0.5 * weight * 0.5 * m.m_b * (v**2).sum(axis=1)
            V -= 0.5 * weight * m.m_b * x @ grav
    mass = m.m_p + payload
    T += 0.5 * mass * (pd**2).sum(axis=1)
    V -= mass * p @ grav
    return T + V


@robots
def test_energy_identity_along_a_smooth_trajectory(robot):
    """dE/dt = qdot . tau along q(t) = q0 + sum of sines (no friction, no fourth axis)."""
    rng = np.random.default_rng(5)
    q0 = _states(robot, 1, seed=2)[0][0]
    amp, w, ph = (
        rng.uniform(0.02, 0.08, (3, 3)),
        rng.uniform(2, 12, (3, 3)),
        rng.uniform(0, 6, (3, 3)),
    )

    def motion(t):
        t = np.asarray(t)[:, None, None]
        q = q0 + (amp * np.sin(w * t + ph)).sum(axis=1)
        qd = (amp * w * np.cos(w * t + ph)).sum(axis=1)
        qdd = (-amp * w * w * np.sin(w * t + ph)).sum(axis=1)
        return q, qd, qdd

    t = np.linspace(0.0, 1.0, 201)
    h = 1e-4
    payload = 1.3
    q, qd, qdd = motion(t)
    power = (qd * robot.inverse_dynamics(q, qd, qdd, payload)).sum(axis=1)
    # dE/dt by a 4th-order central difference
    E = [_energy(robot, *motion(t + k * h)[:2], payload) for k in (-2, -1, 1, 2)]
    dE = (E[0] - 8 * E[1] + 8 * E[2] - E[3]) / (12 * h)
    assert np.abs(dE - power).max() < 1e-7 * np.abs(power).max(), np.abs(dE - power).max()
    # the simplified model's torques do not conserve the true bodies' energy
    simple = (qd * robot.inverse_dynamics(q, qd, qdd, payload, model="simplified")).sum(axis=1)
    assert np.abs(dE - simple).max() > 1e-4 * np.abs(power).max()


# -- structure ------------------------------------------------------------------------------


@robots
def test_payload_enters_as_jacobian_transpose(robot):
    """tau(payload m) - tau(0) = J^T m (pddot - g) with J, pddot from the kinematics."""
    q, qd, qdd, payload = _states(robot, 300, seed=8)
    diff = robot.inverse_dynamics(q, qd, qdd, payload) - robot.inverse_dynamics(q, qd, qdd, 0.0)
    J = robot.jacobian(q)
    _, _, pdd = robot.fk_acc(q, qd, qdd)
    want = np.einsum("nji,nj->ni", J, payload[:, None] * (pdd - np.asarray(robot.inertia.gravity)))
    np.testing.assert_allclose(diff, want, rtol=1e-10, atol=1e-10 * np.abs(want).max())


@robots
def test_mass_matrix_symmetric_positive_definite(robot):
    q = _states(robot, 200, seed=9)[0]
    zero = np.zeros_like(q)
    rest = robot.inverse_dynamics(q, zero, zero)
    M = np.stack(
        [robot.inverse_dynamics(q, zero, np.broadcast_to(e, q.shape)) - rest for e in np.eye(3)],
        axis=-1,
    )
    np.testing.assert_allclose(M, np.swapaxes(M, 1, 2), rtol=0, atol=1e-12 * np.abs(M).max())
    assert (np.linalg.eigvalsh(M) > 0).all()
    # tau is quadratic in qdot: tau(2 qd) - tau(0) = 4 (tau(qd) - tau(0)) at qddot = 0
    qd = _states(robot, 200, seed=9)[1]
    np.testing.assert_allclose(
        robot.inverse_dynamics(q, 2 * qd, zero) - rest,
        4 * (robot.inverse_dynamics(q, qd, zero) - rest),
        rtol=1e-9,
        atol=1e-9,
    )


def test_static_holding_torque_by_virtual_work_of_gravity():
    """At rest tau = dV/dq: finite differences of the potential energy."""
    robot = IRREGULAR
    q = _states(robot, 20, seed=4)[0]
    zero = np.zeros_like(q)
    tau = robot.inverse_dynamics(q, zero, zero, payload=0.7)
    h = 1e-6
    for k in range(3):
        dq = np.zeros(3)
        dq[k] = h
        dV = (_energy(robot, q + dq, zero, 0.7) - _energy(robot, q - dq, zero, 0.7)) / (2 * h)
        np.testing.assert_allclose(tau[:, k], dV, rtol=1e-7, atol=1e-8)


# -- API ------------------------------------------------------------------------------------


def test_broadcasting_fourth_axis_and_payload_rows():
    q, qd, qdd, payload = _states(DEFAULT, 6, seed=1)
    flat = DEFAULT.inverse_dynamics(q, qd, qdd, payload)
    shaped = DEFAULT.inverse_dynamics(
        q.reshape(2, 3, 3), qd.reshape(2, 3, 3), qdd.reshape(2, 3, 3), payload.reshape(2, 3)
    )
    np.testing.assert_allclose(shaped.reshape(6, 3), flat, rtol=1e-14)
    one = DEFAULT.inverse_dynamics(q[2], qd[2], qdd[2], float(payload[2]))
    np.testing.assert_allclose(one, flat[2], rtol=1e-14)  # vector vs scalar cos/sin
    four = np.column_stack((qdd, np.linspace(-5, 5, 6)))
    tau4 = DEFAULT.inverse_dynamics(
        np.column_stack((q, np.zeros(6))), np.column_stack((qd, np.ones(6))), four, payload
    )
    np.testing.assert_allclose(tau4[:, :3], flat, rtol=1e-14)
    np.testing.assert_allclose(tau4[:, 3], DEFAULT.inertia.I_4 * four[:, 3], rtol=1e-15)


def test_from_platform_equals_ik_acc_then_inverse_dynamics():
    t = np.linspace(0.0, 2.0, 50)
    p, pd, pdd = trajectory(t)
    tau = DEFAULT.inverse_dynamics_from_platform(p, pd, pdd, payload=0.4, model="simplified")
    q, qd, qdd = DEFAULT.ik_acc(p, pd, pdd)
    np.testing.assert_array_equal(
        tau, DEFAULT.inverse_dynamics(q, qd, qdd, 0.4, model="simplified")
    )
    bad = p.copy()
    bad[3, 0] = 5.0  # unreachable
    tau_nan, valid = DEFAULT.inverse_dynamics_from_platform(bad, pd, pdd, errors="nan")
    assert valid.tolist() == [i != 3 for i in range(50)]
    assert np.isnan(tau_nan[3]).all() and np.isfinite(tau_nan[valid]).all()


def test_errors():
    q, qd, qdd, _ = _states(DEFAULT, 4, seed=6)
    with pytest.raises(InputError, match="non-negative.*rows \\[2\\]"):
        DEFAULT.inverse_dynamics(q, qd, qdd, payload=[0, 1, -1, 0])
    with pytest.raises(InputError, match="payload"):
        DEFAULT.inverse_dynamics(q, qd, qdd, payload="heavy")
    with pytest.raises(InputError, match="broadcast"):
        DEFAULT.inverse_dynamics(q, qd, qdd, payload=[1.0, 2.0])
    with pytest.raises(InputError, match="model"):
        DEFAULT.inverse_dynamics(q, qd, qdd, model="lumped")
    with pytest.raises(InputError, match="rows \\[1\\]"):
        DEFAULT.inverse_dynamics(q, qd, qdd, payload=[0, np.nan, 0, 0])
    tau, valid = DEFAULT.inverse_dynamics(q, qd, qdd, payload=[0, np.nan, 0, 0], errors="nan")
    assert valid.tolist() == [True, False, True, True] and np.isnan(tau[1]).all()
    with pytest.raises(GeometryError, match="inertia"):
        DeltaRobot(0.2, 0.045, 0.35, 0.8).inverse_dynamics(q, qd, qdd)
    with pytest.raises(GeometryError, match="m_b"):
        DeltaInertia(I_a=0.01, m_a=0.1, r_ca=0.1, m_b=-1.0, m_p=0.1)
    with pytest.raises(GeometryError, match="gravity"):
        DeltaInertia(I_a=0.01, m_a=0.1, r_ca=0.1, m_b=1.0, m_p=0.1, gravity=(0, 9.81))


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_singular_pose_has_no_torque(backend):
    """Short rods (l_b = 0.3 m): at cos q = (l_b - r) / l_a for all three cranks the rods
    lie flat (det J_p = 0, eq. (30)); just inside, the torques to hold the platform grow
    without bound and a pose within singular_tol of it is SINGULAR: no torque."""
    g = DEFAULT.geometry
    robot = DeltaRobot(
        g.r_a, g.r_b, g.l_a, 0.3, singular_tol=1e-2, inertia=g.inertia, backend=backend
    )
    q_flat = math.acos((0.3 - g.r) / g.l_a)
    zero = np.zeros((1, 3))
    held = [
        DeltaRobot(
            g.r_a, g.r_b, g.l_a, 0.3, singular_tol=0.0, inertia=g.inertia, backend=backend
        ).inverse_dynamics(np.full((1, 3), q_flat + d), zero, zero)[0, 0]
        for d in (1e-3, 1e-5)
    ]
    assert abs(held[1]) > 5 * abs(held[0])  # ~ 1/sqrt(d): the singularity is real
    q = np.full((1, 3), q_flat + 1e-7)
    with pytest.raises(SingularityError):
        robot.inverse_dynamics(q, zero, zero)
    tau, valid = robot.inverse_dynamics(q, zero, zero, errors="nan")
    assert not valid[0] and np.isnan(tau).all()


def test_inertia_from_the_robot_file():
    g = DeltaGeometry.from_toml(robots_dir() / "default_delta.toml")
    assert g.inertia == DeltaInertia.default() == DEFAULT.inertia
    assert DeltaRobot.from_toml(robots_dir() / "default_delta.toml").inertia == g.inertia


# -- forward simulation on the report's trajectory -----------------------------------------


@pytest.mark.slow
def test_simulation_driven_by_feedforward_follows_the_report_trajectory():
    """The reference's multibody equations, integrated (DOP853) under the C kernel's
    feed-forward torques along the first 0.5 s of eqs. (40)-(42), stay on the planned path.
    Open loop: any model error would make the platform drift off."""
    robot = DEFAULT
    g = robot.geometry
    duration = 0.5

    def torque(t):
        p, pd, pdd = trajectory(np.array([t]))
        return robot.inverse_dynamics_from_platform(p[:, :3], pd[:, :3], pdd[:, :3])[0]

    t = np.linspace(0.0, duration, 101)
    p, pd, pdd = trajectory(t)
    q, qd, _ = robot.ik_acc(p[:, :3], pd[:, :3], pdd[:, :3])
    qs, _ = ref.simulate(g, g.inertia, torque, (0.0, duration), q[0], qd[0], t, rtol=1e-10)
    err = np.linalg.norm(robot.fk(qs) - p[:, :3], axis=1).max()
    assert err < 1e-7, err  # measured ~1e-10 m

    # the simplified model's torques drive the true bodies off the path
    def simple(t):
        p, pd, pdd = trajectory(np.array([t]))
        return robot.inverse_dynamics_from_platform(
            p[:, :3], pd[:, :3], pdd[:, :3], model="simplified"
        )[0]

    qs2, _ = ref.simulate(g, g.inertia, simple, (0.0, duration), q[0], qd[0], t, rtol=1e-8)
    assert np.linalg.norm(robot.fk(qs2) - p[:, :3], axis=1).max() > 100 * max(err, 1e-9)


# -- deltagen validate ------------------------------------------------------------------------


def test_validate_reports_torques_peaks_and_the_simplified_models_error(tmp_path, capsys):
    import csv

    from deltagen.cli import main as cli_main

    out = tmp_path / "val"
    rc = cli_main(["validate", "--rate", "200", "--duration", "2", "--out", str(out), "--quiet"])
    text = capsys.readouterr().out
    assert rc == 0
    with open(out / "validation.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    header, data = rows[0], np.array(rows[1:], dtype=float)

    def cols(*names):
        return data[:, [header.index(n) for n in names]]

    q, qd, qdd = cols("q1", "q2", "q3"), cols("qd1", "qd2", "qd3"), cols("qdd1", "qdd2", "qdd3")
    tau = cols("tau1", "tau2", "tau3")
    # the CSV's torques are the Newton-Euler reference's for the CSV's motion
    g = DEFAULT.geometry
    tau_ref = ref.inverse_dynamics(g, g.inertia, q, qd, qdd, np.zeros(len(q)))[0]
    np.testing.assert_allclose(tau, tau_ref, rtol=0, atol=1e-9 * np.abs(tau_ref).max())
    # the summary lines hold the peaks, RMS and peak power of those columns
    lines = {
        line.split()[0] + line.split()[1]: line for line in text.splitlines() if line[:2] == "  "
    }
    numbers = lambda key: [float(v) for v in lines[key].split()[2:5]]  # noqa: E731
    np.testing.assert_allclose(numbers("peak|tau|"), np.abs(tau).max(axis=0), rtol=1e-3)
    np.testing.assert_allclose(numbers("RMStau"), np.sqrt((tau**2).mean(axis=0)), rtol=1e-3)
    np.testing.assert_allclose(numbers("peakpower"), np.abs(tau * qd).max(axis=0), rtol=1e-3)
    simple = ref.inverse_dynamics(g, g.inertia, q, qd, qdd, np.zeros(len(q)), model="simplified")[0]
    peak_diff = [float(v) for v in lines["peak|diff|"].split()[2:5]]
    np.testing.assert_allclose(peak_diff, np.abs(simple - tau_ref).max(axis=0), rtol=1e-3)
    png = (out / "validation_torques.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


# -- deltagen dynamics ROBOT --input -----------------------------------------------------------


def test_cli_dynamics_from_platform_samples_and_from_crank_samples(tmp_path, capsys):
    from deltagen.apps.tables import Columns, read_table
    from deltagen.cli import main as cli_main

    t = np.linspace(0.0, 0.5, 501)
    p, pd, pdd = trajectory(t)
    given = tmp_path / "given.csv"
    names = "t,x,y,z,xd,yd,zd,xdd,ydd,zdd"
    np.savetxt(
        given,
        np.column_stack((t, p[:, :3], pd[:, :3], pdd[:, :3])),
        delimiter=",",
        header=names,
        comments="",
    )
    out = tmp_path / "tau.npy"
    assert (
        cli_main(
            ["dynamics", "default", "--input", str(given), "--output", str(out), "--payload", "0.3"]
        )
        == 0
    )
    table = np.load(out)
    want = DEFAULT.inverse_dynamics_from_platform(p[:, :3], pd[:, :3], pdd[:, :3], payload=0.3)
    np.testing.assert_allclose(
        np.column_stack([table[f"tau{i}"] for i in (1, 2, 3)]), want, rtol=0, atol=1e-9
    )
    assert table["valid"].all()
    # positions only: rates by second-order differences, close to the analytic ones
    q = DEFAULT.ik(p[:, :3])
    positional = tmp_path / "q.csv"
    np.savetxt(positional, np.column_stack((t, q)), delimiter=",")
    assert cli_main(["dynamics", "--input", str(positional), "--model", "simplified"]) == 0
    text = capsys.readouterr().out
    csv_text = text[text.index("t,q1") :]
    (tmp_path / "out.csv").write_text(csv_text)
    data, _, _ = read_table(
        tmp_path / "out.csv", [Columns(("tau1", "tau2", "tau3"), positional=False)], "test"
    )
    exact_simple = DEFAULT.inverse_dynamics_from_platform(
        p[:, :3], pd[:, :3], pdd[:, :3], model="simplified"
    )
    inner = slice(5, -5)  # one-sided differences at the ends are less accurate
    scale = np.abs(exact_simple).max()
    err = np.abs(data[inner] - exact_simple[inner]).max()
    assert err < 2e-3 * scale, err / scale
    # a platform-motion file for a serial arm (it reads q columns) and bad files: exit 2
    assert cli_main(["dynamics", "puma560", "--input", str(given)]) == 2
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x,y,z\n0,0,0,-0.8\n0,0,0,-0.8\n0,0,0,-0.8\n")
    assert cli_main(["dynamics", "--input", str(bad)]) == 2
    assert "strictly increasing" in capsys.readouterr().err


@pytest.mark.parametrize(
    "table, message",
    [
        (
            "I_a = 0.01\nm_a = 0.1\nr_ca = 0.1\nm_b = 0.1\n",
            "missing keys in \\[inertia\\]: \\['m_p'\\]",
        ),
        ("I_a = 0.01\nm_a = 0.1\nr_ca = 0.1\nm_b = 0.1\nm_p = 1\nmass = 2\n", "unknown keys"),
        ("I_a = 0.01\nm_a = 0.1\nr_ca = 0.1\nm_b = 0.1\nm_p = -1\n", "m_p must be non-negative"),
        ("I_a = 0.01\nm_a = 0.1\nr_ca = 0.1\nm_b = 0.1\nm_p = 1\ngravity = 9.81\n", "gravity"),
        ("I_a = 'heavy'\nm_a = 0.1\nr_ca = 0.1\nm_b = 0.1\nm_p = 1\n", "I_a must be a real"),
    ],
)
def test_bad_inertia_tables_name_the_file_and_key(tmp_path, table, message):
    path = tmp_path / "robot.toml"
    path.write_text(
        "[delta]\nr_a = 0.2\nr_b = 0.045\nl_a = 0.35\nl_b = 0.8\ntheta_deg = [0, 120, 240]\n"
        f"[inertia]\n{table}"
    )
    with pytest.raises(GeometryError, match=message) as info:
        DeltaRobot.from_toml(path)
    assert str(path) in str(info.value)
