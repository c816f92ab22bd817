"""The compiled serial-arm modules against the independent numpy reference, finite
differences and each other; the SerialRobot API; user robot files and their cache."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import PARTS_ROWS

from deltagen import GeometryError, InputError, SerialRobot, SingularityError, cli
from deltagen.api.serial import bundled_robots, euler_zyx
from deltagen.reference import serial as ref

ROBOTS = bundled_robots()
N = 100_000


def _reach(arm) -> float:
    """A length scale of the arm: the largest frame-origin distance over sample poses."""
    q = _sample(arm, 200, seed=1)
    F = arm.frames(q)
    return float(np.max(np.linalg.norm(F[..., :3, 3], axis=-1))) + 1.0


def _sample(arm, n, seed=0):
    rng = np.random.default_rng(seed)
    lim = arm.qlim.copy()
    finite = np.isfinite(lim)
    lim[~finite[:, 0], 0], lim[~finite[:, 1], 1] = -np.pi, np.pi
    return rng.uniform(lim[:, 0], lim[:, 1], size=(n, arm.n))


@pytest.fixture(scope="module", params=ROBOTS)
def arm(request):
    return SerialRobot.load(request.param)


def test_every_bundled_robot_is_compiled_and_checked_in(arm):
    from deltagen.paths import generated_dir

    assert (generated_dir() / f"serial_{arm.name}.c").is_file()


def test_compiled_matches_reference(arm):
    q = _sample(arm, N)
    qd = np.random.default_rng(2).normal(size=q.shape)
    scale = _reach(arm)
    T, s = arm._core.fk(q)
    T_ref, s_ref = ref.fk(arm.description, q)
    assert np.all(s == 0) and np.all(s_ref == 0)
    assert np.max(np.abs(T - T_ref)[..., :3, 3]) <= 1e-12 * scale
    assert np.max(np.abs(T - T_ref)[..., :3, :3]) <= 1e-12
    J, _ = arm._core.jacobian(q[:20000])
    J_ref, _ = ref.jacobian(arm.description, q[:20000])
    assert np.max(np.abs(J - J_ref)) <= 1e-12 * scale
    Jd, _ = arm._core.jacobian_dot(q[:20000], qd[:20000])
    Jd_ref, _ = ref.jacobian_dot(arm.description, q[:20000], qd[:20000])
    assert np.max(np.abs(Jd - Jd_ref)) <= 1e-11 * scale * max(1.0, np.abs(qd).max())
    F, _ = arm._core.frames(q[:5000])
    F_ref, _ = ref.frames(arm.description, q[:5000])
    assert np.max(np.abs(F - F_ref)) <= 1e-12 * scale


def test_jacobian_against_finite_differences(arm):
    q = _sample(arm, 50, seed=3)
    h = 1e-6
    J = arm.jacobian(q)
    for i in range(arm.n):
        e = np.zeros(arm.n)
        e[i] = h
        Tp, Tm = arm.fk(q + e), arm.fk(q - e)
        v = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)
        Rdot = (Tp[:, :3, :3] - Tm[:, :3, :3]) / (2 * h)
        W = Rdot @ np.swapaxes(arm.fk(q)[:, :3, :3], -1, -2)  # skew(w)
        w = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=-1)
        np.testing.assert_allclose(J[:, :3, i], v, atol=1e-7 * _reach(arm))
        np.testing.assert_allclose(J[:, 3:, i], w, atol=1e-7)


def test_jacobian_dot_against_finite_differences(arm):
    q = _sample(arm, 50, seed=4)
    qd = np.random.default_rng(5).normal(size=q.shape)
    h = 1e-6
    fd = (arm.jacobian(q + h * qd) - arm.jacobian(q - h * qd)) / (2 * h)
    np.testing.assert_allclose(arm.jacobian_dot(q, qd), fd, atol=1e-6 * _reach(arm))
    fd_tool = (arm.jacobian(q + h * qd, frame="tool") - arm.jacobian(q - h * qd, frame="tool")) / (
        2 * h
    )
    np.testing.assert_allclose(
        arm.jacobian_dot(q, qd, frame="tool"), fd_tool, atol=1e-6 * _reach(arm)
    )


def test_tool_frame_jacobian_is_the_rotated_twist(arm):
    q = _sample(arm, 100, seed=6)
    R = arm.fk(q)[:, :3, :3]
    J, Jt = arm.jacobian(q), arm.jacobian(q, frame="tool")
    np.testing.assert_allclose(R @ Jt[:, :3], J[:, :3], atol=1e-12 * _reach(arm))
    np.testing.assert_allclose(R @ Jt[:, 3:], J[:, 3:], atol=1e-12)


def test_frames_end_in_fk_and_start_at_the_base(arm):
    q = _sample(arm, 100, seed=7)
    F = arm.frames(q)
    assert F.shape == (100, arm.n + 2, 4, 4)
    np.testing.assert_allclose(F[:, -1], arm.fk(q), atol=1e-15 * _reach(arm))
    np.testing.assert_allclose(F[:, 0], np.broadcast_to(arm.description.base, (100, 4, 4)))


def test_analytic_jacobian_matches_euler_rates(arm):
    q = _sample(arm, 30, seed=8)
    Ja, valid = arm.analytic_jacobian(q, errors="nan")
    h = 1e-6
    for i in range(arm.n):
        e = np.zeros(arm.n)
        e[i] = h
        dp = (arm.pose(q + e) - arm.pose(q - e)) / (2 * h)
        dp[:, 3:] = (np.remainder(dp[:, 3:] * 2 * h + np.pi, 2 * np.pi) - np.pi) / (2 * h)
        ok = valid & (np.abs(np.cos(arm.euler(q)[:, 1])) > 1e-3)
        np.testing.assert_allclose(Ja[ok, :, i], dp[ok], atol=1e-5 * _reach(arm))


def test_compiled_and_reference_api_agree_on_every_quantity(arm):
    q = _sample(arm, 500, seed=9)
    qd = np.random.default_rng(10).normal(size=q.shape)
    other = arm.with_backend("reference")
    scale = _reach(arm)
    for name, args in [
        ("fk", (q,)),
        ("frames", (q,)),
        ("jacobian", (q,)),
        ("jacobian_dot", (q, qd)),
        ("euler", (q,)),
        ("pose", (q,)),
    ]:
        a, b = getattr(arm, name)(*args), getattr(other, name)(*args)
        if name in ("euler", "pose"):  # angles compare modulo 2 pi (atan2 at +-pi, signed zeros)
            a, b = a[..., -3:], b[..., -3:]
            a = b + np.remainder(a - b + np.pi, 2 * np.pi) - np.pi
        np.testing.assert_allclose(a, b, atol=1e-11 * scale, err_msg=name)
    np.testing.assert_allclose(
        arm.manipulability(q), other.manipulability(q), rtol=1e-9, atol=1e-14
    )


def test_single_pose_fast_path_equals_the_batch(arm):
    q = _sample(arm, 5, seed=11)
    for row in q:
        np.testing.assert_array_equal(arm.fk(row), arm.fk(row[None])[0])
        np.testing.assert_array_equal(arm.fk(list(row)), arm.fk(row[None])[0])


def test_named_configurations_evaluate(arm):
    for _name, q in arm.configurations.items():
        T = arm.fk(q)
        assert T.shape == (4, 4) and np.all(np.isfinite(T))


def test_within_limits(arm):
    q = _sample(arm, 10, seed=12)
    assert arm.within_limits(q).shape == (10,)
    lim = arm.qlim
    if np.all(np.isfinite(lim[:, 1])):
        assert not arm.within_limits(lim[:, 1] + 1.0)


# --- one arm, three conventions -------------------------------------------------------

STANDARD = [dict(a=0.0, alpha_deg=-90, d=0.4), dict(a=0.5), dict(a=0.3, alpha_deg=45, d=0.1)]
MODIFIED = [dict(d=0.4), dict(alpha_deg=-90), dict(a=0.5, d=0.1)]
UNIVERSAL = [
    dict(axis="z", tz=0.4, rx_deg=-90),
    dict(axis="z", tx=0.5),
    dict(axis="z", tz=0.1, tx=0.3, rx_deg=45),
]


def test_same_arm_in_three_conventions_gives_one_tool_pose():
    from deltagen.model.serial import SerialDescription, transform

    std = SerialRobot.from_dh(STANDARD, "standard", name="three_std")
    tool = transform((0.3, 0, 0), (np.radians(45), 0, 0))
    mod = SerialRobot.from_dh(MODIFIED, "modified", name="three_mod", tool=tool)
    # universal: D_i = Rot_z(q_i) T(...) R(...); the standard rows rewritten in that order
    uni = SerialRobot(
        SerialDescription.from_rows(
            [
                dict(axis="z", tz=0.4, rx_deg=-90),
                dict(axis="z", tx=0.5),
                dict(axis="z", tx=0.3, tz=0.1, rx_deg=45),
            ],
            "universal",
            name="three_uni",
        )
    )
    # the universal row 3 translates along the rotated z after Rot_z: Tz(d) Tx(a) commute
    q = np.random.default_rng(13).uniform(-3, 3, (1000, 3))
    T = std.fk(q)
    np.testing.assert_allclose(mod.fk(q), T, atol=1e-14)
    np.testing.assert_allclose(uni.fk(q), T, atol=1e-14)
    np.testing.assert_allclose(mod.jacobian(q), std.jacobian(q), atol=1e-14)
    np.testing.assert_allclose(uni.jacobian(q), std.jacobian(q), atol=1e-14)


def test_lecture_scara_slide_95():
    scara = SerialRobot.from_dh([dict(a=4.0), dict(a=3.0)], "standard", name="scara_check")
    T = scara.fk(np.radians([30.0, 30.0]))
    assert round(T[0, 3], 3) == 4.964 and round(T[1, 3], 3) == 4.598
    assert np.degrees(euler_zyx(T[:3, :3]))[0] == pytest.approx(60.0, abs=1e-12)


# --- input handling ---------------------------------------------------------------------


def test_bad_inputs_name_the_problem():
    arm = SerialRobot.load(ROBOTS[0])
    with pytest.raises(InputError, match=r"shape \(\.\.\., \d+\)"):
        arm.fk(np.zeros(arm.n + 1))
    with pytest.raises(InputError, match="NaN"):
        arm.fk(np.full(arm.n, np.nan))
    q = np.zeros((3, arm.n))
    q[1, 0] = np.inf
    T, valid = arm.fk(q, errors="nan")
    assert valid.tolist() == [True, False, True] and np.isnan(T[1]).all()
    with pytest.raises(InputError, match="numeric"):
        arm.fk(["a"] * arm.n)
    with pytest.raises(InputError, match="frame"):
        arm.jacobian(np.zeros(arm.n), frame="world")
    with pytest.raises(InputError, match="no bundled serial robot"):
        SerialRobot.load("no_such_robot")
    with pytest.raises(InputError, match="convention"):
        SerialRobot.from_dh([dict(a=1.0)])
    with pytest.raises(InputError, match="configuration"):
        arm.configuration("nope")


@pytest.mark.parametrize(
    "text, words",
    [
        ('name = "x"\n[[joint]]\na = 1\n', ["convention"]),
        ('name = "x"\nconvention = "dh"\n[[joint]]\na = 1\n', ["convention"]),
        ('name = "x"\nconvention = "standard"\n[[joint]]\ntype = "spherical"\n', ["joint type"]),
        (
            'name = "x"\nconvention = "standard"\n[[joint]]\nalpha = 1\nalpha_deg = 90\n',
            ["not both"],
        ),
        ('name = "x"\nconvention = "standard"\n[[joint]]\ntx = 1\n', ["another convention"]),
        ('name = "my arm"\nconvention = "standard"\n[[joint]]\na = 1\n', ["invalid robot name"]),
        ('name = "x"\nconvention = "universal"\n[[joint]]\ntx = 1\n', ["axis"]),
        ('name = "x"\nconvention = "standard"\n[[joint]]\na = "one"\n', ["real number"]),
        (
            'name = "x"\nconvention = "standard"\n[[joint]]\na = 1\n[configurations]\nhome = [0, 0]\n',
            ["2 values"],
        ),
        (
            'name = "x"\nconvention = "standard"\n[[joint]]\ntype = "revolute"\ntheta = 1\n',
            ["offset"],
        ),
        ('name = "x"\nconvention = "standard"\n[[joint]]\na = [1\n', ["malformed TOML"]),
    ],
)
def test_malformed_robot_files(tmp_path, text, words):
    path = tmp_path / "arm.toml"
    path.write_text(text)
    with pytest.raises(GeometryError) as info:
        SerialRobot.from_toml(path)
    for word in words:
        assert word in str(info.value), str(info.value)
    assert str(path) in str(info.value)


def test_user_robot_file_is_generated_and_cached_by_content(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "arm.toml"
    path.write_text(
        'name = "user_arm"\nconvention = "standard"\n[[joint]]\na = 1.0\n[[joint]]\na = 0.5\n'
    )
    assert cli.main(["generate", str(path)]) == 0
    assert "user_arm" in capsys.readouterr().out
    arm = SerialRobot.from_toml(path)
    np.testing.assert_allclose(arm.fk([0.0, 0.0])[:3, 3], [1.5, 0, 0], atol=1e-15)
    path.write_text(
        'name = "user_arm"\nconvention = "standard"\n[[joint]]\na = 1.0\n[[joint]]\na = 0.25\n'
    )
    changed = SerialRobot.from_toml(path)  # same name, new content: a new module, not the stale one
    np.testing.assert_allclose(changed.fk([0.0, 0.0])[:3, 3], [1.25, 0, 0], atol=1e-15)
    assert len(list((tmp_path / "cache" / "sources").iterdir())) == 2


def test_cli_fk_of_a_serial_arm(capsys):
    name = "puma560" if "puma560" in ROBOTS else ROBOTS[0]
    arm = SerialRobot.load(name)
    q = _sample(arm, 1, seed=14)[0]
    assert cli.main(["fk", name, *(repr(float(v)) for v in q)]) == 0
    out = capsys.readouterr().out
    assert "T =" in out and "psi" in out
    x = arm.fk(q)[0, 3]
    assert f"{x:.9g}" in out
    assert cli.main(["fk", name, "1", "2"]) == 2


def test_cli_batch_of_a_serial_arm(tmp_path):
    name = ROBOTS[0]
    arm = SerialRobot.load(name)
    q = _sample(arm, 7, seed=15)
    np.save(tmp_path / "q.npy", q)
    assert (
        cli.main(
            ["fk", name, "--input", str(tmp_path / "q.npy"), "--output", str(tmp_path / "T.npy")]
        )
        == 0
    )
    table = np.load(tmp_path / "T.npy")  # a structured array: columns by name
    xyz = np.column_stack([table["x"], table["y"], table["z"]])
    np.testing.assert_allclose(xyz, arm.fk(q)[:, :3, 3], atol=1e-15)
    assert np.all(table["valid"])


def test_analytic_jacobian_raises_at_the_euler_singularity():
    """A two-joint pitch arm: standard DH, alpha_1 = -90 deg, so y_1 = -z_0 and the tool's
    x axis is cos(q2) x_0 - sin(q2) z_0. At q2 = 90 deg it points along -z_0: a31 = -1,
    theta = +90 deg, cos(theta) = 0, where E^-1 does not exist. One degree away the arm is
    regular and the analytic Jacobian is finite and valid."""
    arm = SerialRobot.from_dh([dict(alpha_deg=-90), dict()], "standard", name="pitch_arm")
    singular = np.array([0.3, np.pi / 2])
    regular = np.array([0.3, np.radians(89.0)])
    np.testing.assert_allclose(arm.euler(singular)[1], np.pi / 2, atol=1e-12)
    with pytest.raises(SingularityError, match="Euler-angle singularity") as caught:
        arm.analytic_jacobian(np.stack([regular, singular]))
    assert list(caught.value.rows) == [1]
    Ja, valid = arm.analytic_jacobian(np.stack([regular, singular]), errors="nan")
    assert valid.tolist() == [True, False]
    assert np.all(np.isfinite(Ja[0])) and np.all(np.isnan(Ja[1]))
    assert np.all(np.isfinite(arm.analytic_jacobian(regular)))


# -- an arm's first use waits for no dynamics --------------------------------------------------


@pytest.mark.slow  # two cold builds
def test_dynamics_are_built_on_first_use_and_agree(tmp_path, monkeypatch):
    """A new arm with inertials loads its kinematics alone (SymPy and the compiler do the
    dynamics only on the first dynamics call, and then only the part of that kernel: the
    first inverse_dynamics derives and compiles inverse_dynamics and gravity_torque alone,
    no kinematics, no ik_all, no M, h or Coriolis matrix); the first call of each dynamics
    kernel gives the reference's values; the "mass" and "coriolis" parts are built on
    their own first calls; a second robot of the same description in the same cache
    builds nothing."""
    from deltagen.native.serial import module_ready

    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path))

    rows = PARTS_ROWS[:2]  # two links with inertia
    arm = SerialRobot.from_dh(rows, "standard", name="lazy_arm")
    reference = arm.with_backend("reference")
    core = arm._core
    assert not core.dynamics_loaded
    rng = np.random.default_rng(2)
    q, qd, qdd = (rng.uniform(-2, 2, (50, 2)) for _ in range(3))
    T = arm.fk(q)
    np.testing.assert_allclose(T, reference.fk(q), rtol=0, atol=1e-14)
    assert not core.dynamics_loaded
    tau = arm.inverse_dynamics(q[0], qd[0], qdd[0])  # the one-state path, first
    assert core.dynamics_loaded
    dynamics_lib = core.load_dynamics().lib
    prefix = "deltagen_lazy_arm"
    for kernel in ("inverse_dynamics", "gravity_torque"):
        assert hasattr(dynamics_lib, f"{prefix}_{kernel}")
    for kernel in ("fk", "jacobian", "ik_newton", "jacobian_dot", "mass_matrix", "coriolis"):
        assert not hasattr(dynamics_lib, f"{prefix}_{kernel}")  # not derived nor compiled
    assert set(core._parts) == {"dynamics"}
    np.testing.assert_allclose(
        tau, reference.inverse_dynamics(q[0], qd[0], qdd[0]), rtol=1e-12, atol=1e-12
    )
    tol = dict(rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(arm.gravity_torque(q), reference.gravity_torque(q), **tol)
    assert set(core._parts) == {"dynamics"}
    # the one-state forward dynamics first: the "mass" part (M, h and the C wrapper)
    np.testing.assert_allclose(
        arm.forward_dynamics(q[1], qd[1], tau), reference.forward_dynamics(q[1], qd[1], tau), **tol
    )
    assert set(core._parts) == {"dynamics", "mass"}
    np.testing.assert_allclose(arm.mass_matrix(q), reference.mass_matrix(q), **tol)
    np.testing.assert_allclose(
        arm.nonlinear_effects(q, qd), reference.nonlinear_effects(q, qd), **tol
    )
    np.testing.assert_allclose(
        arm.forward_dynamics(q, qd, tau), reference.forward_dynamics(q, qd, tau), **tol
    )
    np.testing.assert_allclose(arm.coriolis(q, qd), reference.coriolis(q, qd), **tol)
    assert "coriolis" in core._parts
    for part in ("first", "dynamics", "mass", "coriolis"):
        desc = arm.description if part != "first" else arm.description.without_inertia()
        assert module_ready(desc, part=part)
    assert not module_ready(arm.description)  # the complete module was never built
    again = SerialRobot.from_dh(rows, "standard", name="lazy_arm")
    assert not again._core.dynamics_loaded
    assert np.array_equal(again.fk(q), T)
    assert np.array_equal(again.inverse_dynamics(q, qd, qdd), arm.inverse_dynamics(q, qd, qdd))


@pytest.mark.slow  # two cold builds
def test_jacobian_dot_and_ik_all_are_built_on_first_use_and_agree(tmp_path, monkeypatch):
    """A new arm loads fk, frames, jacobian, fk_jacobian and ik_newton alone (a short
    cold load: a UR5's closed-form ik_all was half of it); its first ik_all or
    jacobian_dot builds the "later" part alone (jacobian_dot and ik_all, not the kernels
    already built), whose results equal the reference backend's; a second robot of the
    same description loads that part from the cache."""
    import dataclasses

    from deltagen.model.serial import SerialDescription
    from deltagen.paths import robots_dir

    monkeypatch.setenv("DELTAGEN_CACHE", str(tmp_path))
    puma = SerialDescription.from_toml(robots_dir() / "puma560.toml")
    desc = dataclasses.replace(puma.without_inertia(), name="lazy_puma")
    arm = SerialRobot(desc)
    reference = arm.with_backend("reference")
    core = arm._core
    prefix = "deltagen_lazy_puma"
    assert "later" not in core._parts
    assert not hasattr(core._lib, f"{prefix}_ik_all")
    assert not hasattr(core._lib, f"{prefix}_jacobian_dot")
    rng = np.random.default_rng(12)
    lo, hi = arm.qlim[:, 0], arm.qlim[:, 1]
    q = rng.uniform(lo, hi, (300, 6))
    qd = rng.uniform(-2, 2, (300, 6))
    T = arm.fk(q)
    np.testing.assert_allclose(T, reference.fk(q), rtol=0, atol=1e-13)
    q_ik, _ = arm.ik(T[:20], q0=q[:20] + 0.03, method="numeric", errors="nan")  # ik_newton
    np.testing.assert_allclose(reference.fk(q_ik), T[:20], rtol=0, atol=1e-9)
    assert "later" not in core._parts  # the numerical IK needs no more than the first module
    Q, valid = arm.ik_all(T)
    later = core._parts["later"].lib
    assert hasattr(later, f"{prefix}_ik_all") and hasattr(later, f"{prefix}_jacobian_dot")
    for kernel in ("fk", "frames", "jacobian", "fk_jacobian", "ik_newton"):
        assert not hasattr(later, f"{prefix}_{kernel}")  # built once, in the first module
    Q_ref, valid_ref = reference.ik_all(T)
    assert np.array_equal(valid, valid_ref)
    np.testing.assert_allclose(Q[valid], Q_ref[valid], rtol=0, atol=1e-9)
    assert valid.any(axis=1).all()  # every pose fk(q) has a valid branch
    np.testing.assert_allclose(
        arm.jacobian_dot(q, qd), reference.jacobian_dot(q, qd), rtol=1e-12, atol=1e-12
    )
    again = SerialRobot(desc)
    from deltagen.native.serial import module_ready

    assert module_ready(desc, part="later")  # its first ik_all builds nothing
    assert np.array_equal(again.fk(q), T)
    Q2, valid2 = again.ik_all(T)
    assert np.array_equal(valid2, valid) and np.array_equal(Q2[valid], Q[valid])
