"""The hexapod (Stewart-Gough platform): compiled core against the numpy reference and
against independent evidence -- LinuxCNC genhexkins' default geometry and inverse
kinematics rewritten here, round trips ik(fk) and fk(ik), finite differences of the
Jacobian, virtual work for the leg forces -- the fk convergence rate from the home pose,
bad input, and the generated C built strictly and under sanitizers."""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
from helpers import GCC, compile_c

from deltagen import GeometryError, Hexapod, InputError, SingularityError, UnreachableError, paths
from deltagen import status as st
from deltagen.geometry.rotations import rot_exp
from deltagen.model.hexapod import HexapodGeometry
from deltagen.native.hexapod import geometry_struct

# LinuxCNC src/emc/kinematics/genhexkins.h (DEFAULT_BASE_i_X/Y/Z, DEFAULT_PLATFORM_i_X/Y/Z),
# in the machine's unit (inch), strut i = 0 .. 5, rewritten here from the header
LINUXCNC_BASE = [
    [-22.950, 13.250, 0.0],
    [22.950, 13.250, 0.0],
    [22.950, 13.250, 0.0],
    [0.000, -26.500, 0.0],
    [0.000, -26.500, 0.0],
    [-22.950, 13.250, 0.0],
]
LINUXCNC_PLATFORM = [
    [-1.000, 11.500, 0.0],
    [1.000, 11.500, 0.0],
    [10.459, -4.884, 0.0],
    [9.459, -6.616, 0.0],
    [-9.459, -6.616, 0.0],
    [-10.459, -4.884, 0.0],
]


def linuxcnc_inverse(base, platform, xyz, abc_deg):
    """genhexkins.c's genhexKinematicsInverse, rewritten: its platform point a_i (platform
    frame) is rotated by the roll-pitch-yaw matrix of (A, B, C) in degrees (pmRpyMatConvert:
    R = Rz(C) Ry(B) Rx(A)), added to the position, and the base point b_i subtracted; the
    strut length is the magnitude."""
    r, p, y = np.radians(abc_deg)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    R = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    return np.array(
        [
            np.linalg.norm(np.asarray(xyz) + R @ np.array(a) - np.array(b))
            for a, b in zip(platform, base)
        ]
    )


@pytest.fixture(scope="module")
def robot():
    return Hexapod.genhexkins()


@pytest.fixture(scope="module")
def reference():
    return Hexapod.genhexkins(backend="reference")


def random_poses(robot, n, seed, spread=(0.1, 0.1, 0.08), tilt=0.3):
    rng = np.random.default_rng(seed)
    home = np.array(robot.geometry.home_position)
    p = home + rng.uniform(-1, 1, (n, 3)) * spread
    return robot.pose(p, rpy=rng.uniform(-tilt, tilt, (n, 3)))


@pytest.fixture(scope="module")
def reachable(robot):
    """Random poses within every limit (legs, joint cones, non-singular)."""
    T = random_poses(robot, 4000, seed=7)
    return T[robot.within_limits(T)]


# ----------------------------------------------------------------- geometry


def test_genhexkins_geometry_is_linuxcncs_in_metres():
    g = HexapodGeometry.genhexkins()
    np.testing.assert_allclose(g.base_joints, np.array(LINUXCNC_BASE) * 0.0254, rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        g.platform_joints, np.array(LINUXCNC_PLATFORM) * 0.0254, rtol=0, atol=1e-15
    )


def test_robot_file_is_the_genhexkins_geometry():
    g = HexapodGeometry.from_toml(paths.robots_dir() / "hexapod_genhex.toml")
    ref = HexapodGeometry.genhexkins()
    np.testing.assert_allclose(g.base_joints, ref.base_joints, atol=1e-12)
    np.testing.assert_allclose(g.platform_joints, ref.platform_joints, atol=1e-12)
    assert g.leg_limits == ref.leg_limits and g.home_position == pytest.approx(ref.home_position)
    assert g.base_cone == pytest.approx(ref.base_cone)


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(base_joints=[[0, 0, 0]] * 5), "6 points"),
        (dict(base_joints=[[k, 0, 0] for k in range(6)]), "collinear"),
        (dict(leg_limits=(0.5, 0.4)), "l_min < l_max"),
        (dict(base_cone=0.0), "base_cone"),
        (dict(platform_axes=[[0, 0, 0]] * 6), "zero vector"),
        (dict(platform_joints=[[math.nan, 0, 0]] * 6), "finite"),
    ],
)
def test_bad_geometry_is_rejected(change, words):
    kwargs = dict(base_joints=LINUXCNC_BASE, platform_joints=LINUXCNC_PLATFORM) | change
    with pytest.raises(GeometryError, match=words):
        HexapodGeometry(**kwargs)


# ----------------------------------------------------------------- inverse kinematics


def test_ik_is_linuxcncs_inverse(robot):
    """Compiled ik against genhexkins' inverse rewritten above, in LinuxCNC's own units and
    angle convention, on the default geometry (inches in, inches out)."""
    rng = np.random.default_rng(3)
    hexapod = Hexapod(LINUXCNC_BASE, LINUXCNC_PLATFORM)
    for _ in range(50):
        xyz = rng.uniform([-3, -3, 17], [3, 3, 23])
        abc = rng.uniform(-10, 10, 3)
        T = hexapod.pose(xyz, rpy=np.radians(abc))
        expected = linuxcnc_inverse(LINUXCNC_BASE, LINUXCNC_PLATFORM, xyz, abc)
        np.testing.assert_allclose(hexapod.ik(T), expected, rtol=1e-14, atol=1e-12)


def test_compiled_matches_reference(robot, reference):
    T = random_poses(robot, 500, seed=11)
    np.testing.assert_allclose(robot.ik(T), reference.ik(T), rtol=0, atol=1e-14)
    np.testing.assert_allclose(robot.jacobian(T), reference.jacobian(T), rtol=0, atol=1e-13)
    np.testing.assert_allclose(
        robot.joint_angles(T), reference.joint_angles(T), rtol=0, atol=1e-7
    )  # the reference's arccos loses digits near 0; the kernel uses atan2


def test_single_and_batched_shapes(robot):
    T = robot.home
    assert robot.ik(T).shape == (6,)
    assert robot.ik(np.stack([T, T])).shape == (2, 6)
    assert robot.ik(np.broadcast_to(T, (2, 3, 4, 4))).shape == (2, 3, 6)
    assert robot.fk(robot.ik(T)).shape == (4, 4)
    assert robot.jacobian(T).shape == (6, 6)


def test_pose_from_rotation_vector_and_rpy_agree(robot):
    rv = np.array([0.1, -0.2, 0.05])
    a = robot.pose([0.0, 0.01, 0.5], rotvec=rv)
    np.testing.assert_allclose(a[:3, :3], rot_exp(rv[None])[0], atol=1e-15)
    b = robot.pose([0.0, 0.01, 0.5], rpy=[0.0, 0.0, 0.3])
    np.testing.assert_allclose(
        b[:2, :2], [[math.cos(0.3), -math.sin(0.3)], [math.sin(0.3), math.cos(0.3)]]
    )


# ----------------------------------------------------------------- forward kinematics


def test_fk_ik_round_trips(robot, reachable):
    """fk(ik(T)) = T to 1e-12 and ik(fk(l)) = l to 1e-12 m over random reachable poses."""
    assert len(reachable) > 1000
    lengths = robot.ik(reachable)
    result = robot.fk_result(lengths)
    ok = result.status == st.OK
    assert ok.all(), f"{(~ok).sum()} reachable poses did not converge from home"
    assert np.abs(result.pose - reachable).max() < 1e-12
    assert np.abs(robot.ik(result.pose) - lengths).max() < 1e-12
    assert result.residual.max() <= 1e-11 and result.iterations.max() <= 50


def linuxcnc_forward(base, platform, lengths, xyz, abc_deg, criterion=1e-13, limit=500):
    """genhexkins.c's genhexKinematicsForward, rewritten: Newton-Raphson from the pose
    (xyz, abc) on the strut lengths, its inverse Jacobian rows (u_i, (R a_i) x u_i),
    subtracting J^-1 (l(pose) - l) from the position and the roll-pitch-yaw angles
    themselves, until every |strut length difference| <= criterion (None after ``limit``
    iterations)."""
    q = np.array(xyz, dtype=float)
    rpy = np.radians(abc_deg)
    for _ in range(limit):
        R = Hexapod.pose([0, 0, 0], rpy=rpy)[:3, :3]
        rows, diff = [], []
        for a, b, length in zip(platform, base, lengths):
            ra = R @ np.array(a)
            strut = q + ra - np.array(b)
            unit = strut / np.linalg.norm(strut)
            diff.append(np.linalg.norm(strut) - length)
            rows.append([*unit, *np.cross(ra, unit)])
        delta = np.linalg.solve(np.array(rows), np.array(diff))
        q -= delta[:3]
        rpy -= delta[3:]
        if np.all(np.abs(diff) <= criterion):
            return q, np.degrees(rpy)
    return None


def test_fk_is_linuxcncs_forward():
    """Compiled fk against genhexkins' forward iteration rewritten above, both from the
    same start (20 in above the base, level), in LinuxCNC's units (inch, degrees)."""
    hexapod = Hexapod(LINUXCNC_BASE, LINUXCNC_PLATFORM, home_position=(0, 0, 20))
    rng = np.random.default_rng(13)
    for _ in range(20):
        xyz = rng.uniform([-3, -3, 17], [3, 3, 23])
        abc = rng.uniform(-10, 10, 3)
        lengths = linuxcnc_inverse(LINUXCNC_BASE, LINUXCNC_PLATFORM, xyz, abc)
        found = linuxcnc_forward(LINUXCNC_BASE, LINUXCNC_PLATFORM, lengths, [0, 0, 20], [0, 0, 0])
        assert found is not None
        T = hexapod.fk(lengths)
        np.testing.assert_allclose(T[:3, 3], found[0], rtol=0, atol=1e-10)
        np.testing.assert_allclose(
            T[:3, :3], hexapod.pose([0, 0, 0], rpy=np.radians(found[1]))[:3, :3], atol=1e-11
        )
        np.testing.assert_allclose(T[:3, 3], xyz, rtol=0, atol=1e-10)


def test_fk_matches_the_reference_solver(robot, reference, reachable):
    """The C damped Newton and SciPy's least squares (reference) reach the same pose."""
    lengths = robot.ik(reachable[:15])
    np.testing.assert_allclose(robot.fk(lengths), reference.fk(lengths), rtol=0, atol=1e-10)


def test_fk_convergence_rate_from_home(robot):
    """Over random poses in a wide box (many beyond the limits, some far from home), fk from
    the home pose converges to the pose that made the lengths on at least 95 % of the
    reachable ones (measured: all of them, in 5 to 6 steps); every point marked OK
    reproduces its lengths, every other is NaN."""
    T = random_poses(robot, 3000, seed=21, spread=(0.25, 0.25, 0.2), tilt=0.8)
    reach = robot.within_limits(T)
    lengths = robot.ik(T)
    result = robot.fk_result(lengths)
    ok = result.status == st.OK
    same = ok & (np.abs(result.pose - T).max(axis=(1, 2)) < 1e-9)
    rate = same[reach].mean()
    assert rate >= 0.95, rate
    # OK rows reproduce their lengths to fk's tolerance (1e-11 m; to rounding except
    # near singular poses far outside the limits)
    assert np.abs(robot.ik(result.pose[ok]) - lengths[ok]).max() <= 1e-11
    assert np.isnan(result.pose[~ok]).all()
    assert set(np.unique(result.status[~ok])) <= {st.UNREACHABLE, st.SINGULAR}


def test_unreachable_lengths_are_flagged_never_ok(robot):
    """Legs 1 and 2 share a base joint (genhexkins' default), their platform joints are
    0.48 m apart: lengths differing by more violate the triangle inequality."""
    lengths = np.array(
        [[0.1, 2.0, 0.1, 2.0, 0.1, 2.0], [0.75, 0.75, 1.5, 0.75, 0.75, 0.75], [0.76] * 6]
    )
    result = robot.fk_result(lengths)
    assert result.status[0] != st.OK and result.status[1] != st.OK
    assert np.isnan(result.pose[:2]).all()
    assert result.status[2] == st.OK
    with pytest.raises((UnreachableError, SingularityError), match=r"rows \[0"):
        robot.fk(lengths)
    poses, valid = robot.fk(lengths, errors="nan")
    assert valid.tolist() == [False, False, True] and np.isnan(poses[0]).all()


def test_fk_trajectory_warm_start(robot):
    """A path the home start cannot follow in one jump (a 1.2 rad turn about z) is solved
    point by point from the previous pose."""
    s = np.linspace(0.0, 1.0, 60)
    T = robot.pose(
        np.column_stack([0.02 * s, 0 * s, 0.5 + 0.02 * s]),
        rpy=np.column_stack([0 * s, 0 * s, 1.2 * s]),
    )
    lengths = robot.ik(T)
    path = robot.fk(lengths, guess=T[0], trajectory=True)
    np.testing.assert_allclose(path, T, rtol=0, atol=1e-12)
    per_point = robot.fk(lengths, guess=T)  # each from its own pose: the same answer
    np.testing.assert_allclose(per_point, T, rtol=0, atol=1e-12)


# ----------------------------------------------------------------- rates and forces


def test_jacobian_by_finite_differences(robot, reachable):
    h = 1e-6
    for T in reachable[:20]:
        J = robot.jacobian(T)
        fd = np.empty((6, 6))
        for k in range(6):
            twist = np.zeros(6)
            twist[k] = h
            plus, minus = T.copy(), T.copy()
            for sign, P in ((1, plus), (-1, minus)):
                P[:3, 3] += sign * twist[:3]
                P[:3, :3] = rot_exp(sign * twist[None, 3:])[0] @ T[:3, :3]
            fd[:, k] = (robot.ik(plus) - robot.ik(minus)) / (2 * h)
        np.testing.assert_allclose(J, fd, rtol=0, atol=1e-8)


def test_velocity_round_trip_and_leg_rates_by_differences(robot, reachable):
    rng = np.random.default_rng(5)
    T = reachable[:200]
    twist = rng.normal(size=(len(T), 6))
    ld = robot.leg_rates(T, twist)
    np.testing.assert_allclose(robot.twist(T, ld), twist, rtol=0, atol=1e-10)
    # leg rates by differences of ik along the motion
    dt = 1e-7
    moved = T.copy()
    moved[:, :3, 3] += twist[:, :3] * dt
    moved[:, :3, :3] = rot_exp(twist[:, 3:] * dt) @ T[:, :3, :3]
    np.testing.assert_allclose((robot.ik(moved) - robot.ik(T)) / dt, ld, rtol=0, atol=1e-5)


def test_leg_forces_balance_the_wrench_by_virtual_work(robot, reachable):
    """J^T F = w, and the power of the leg forces on the leg rates equals the power of
    the wrench on the twist (virtual work), for random twists."""
    rng = np.random.default_rng(9)
    T = reachable[:100]
    w = rng.normal(size=(len(T), 6)) * [100, 100, 100, 10, 10, 10]
    F = robot.leg_forces(T, w)
    J = robot.jacobian(T)
    np.testing.assert_allclose(np.einsum("nji,nj->ni", J, F), w, rtol=1e-10, atol=1e-9)
    twist = rng.normal(size=(len(T), 6))
    power_legs = np.sum(F * robot.leg_rates(T, twist), axis=1)
    np.testing.assert_allclose(power_legs, np.sum(w * twist, axis=1), rtol=1e-9, atol=1e-9)


def test_condition_grows_at_a_singular_pose(robot):
    """A platform whose joints sit above the base joints in plan (six vertical, parallel
    legs) cannot resist translation in x, y nor rotation about z: J has rank 3."""
    base = np.array(LINUXCNC_PLATFORM) * 0.0254
    flat = Hexapod(base, base, leg_limits=(0.1, 1.0))
    T = flat.pose([0.0, 0.0, 0.5])
    assert flat.condition(T) > 1e12
    with pytest.raises(SingularityError):
        flat.twist(T, np.zeros(6))
    assert not flat.within_limits(T)
    assert robot.condition(robot.home) < 100


# ----------------------------------------------------------------- limits and workspace


def test_joint_angles_against_the_geometry(robot):
    """At home the base joint angle of leg i is the angle of the leg vector from vertical,
    computed here from the points; the platform angle equals it (parallel platform)."""
    g = robot.geometry
    d = np.array(g.platform_joints) + g.home_position - np.array(g.base_joints)
    expected = np.arctan2(np.hypot(d[:, 0], d[:, 1]), d[:, 2])
    angles = robot.joint_angles(robot.home)
    np.testing.assert_allclose(angles[:6], expected, atol=1e-14)
    np.testing.assert_allclose(angles[6:], expected, atol=1e-14)


def test_limits_report_each_cause(robot):
    g = robot.geometry
    low = robot.pose([0, 0, 0.2])  # legs too short for leg_limits? and cones exceeded
    high = robot.pose([0, 0, 0.9])
    lim = robot.limits(np.stack([robot.home, low, high]))
    assert lim["reachable"].tolist() == [True, False, False]
    lengths = robot.ik(np.stack([low, high]))
    assert (lengths[0] < g.leg_limits[0]).any() or (robot.joint_angles(low)[:6] > g.base_cone).any()
    assert not lim["legs"][2] and (lengths[1] > g.leg_limits[1]).any()


def test_workspace_grids(robot):
    x = np.linspace(-0.15, 0.15, 7)
    ws = robot.position_workspace(x, x, np.linspace(0.4, 0.65, 6))
    assert ws.reachable.shape == (7, 7, 6) and 0 < ws.fraction < 1
    assert ws.reachable[3, 3].any()  # on the axis at some height
    # every reachable grid pose is within the limits by its own test
    i = np.argwhere(ws.reachable)[0]
    p = [ws.axes[k][i[k]] for k in range(3)]
    assert robot.within_limits(robot.pose(p))
    assert np.isnan(ws.condition[~ws.reachable]).all()
    a = np.radians(np.linspace(-30, 30, 5))
    ows = robot.orientation_workspace(a, a, a)
    assert ows.reachable[2, 2, 2] and 0 < ows.fraction <= 1


# ----------------------------------------------------------------- bad input


def test_bad_input_is_an_input_error(robot):
    T = robot.home.copy()
    T[0, 3] = math.nan
    with pytest.raises(InputError, match=r"rows \[0\]"):
        robot.ik(T)
    _, valid = robot.ik(np.stack([robot.home, T]), errors="nan")
    assert valid.tolist() == [True, False]
    skew = robot.home.copy()
    skew[0, 0] = 2.0
    with pytest.raises(InputError, match="not a rotation"):
        robot.ik(skew)
    with pytest.raises(InputError, match="shape"):
        robot.ik(np.eye(3))
    with pytest.raises(InputError, match="lengths"):
        robot.fk([1.0] * 5)
    with pytest.raises(InputError, match="lengths: a non-finite value"):
        robot.fk([math.nan] * 6)
    with pytest.raises(InputError, match="guess"):
        robot.fk([0.75] * 6, guess=skew)
    with pytest.raises(InputError, match="max_iter"):
        robot.fk([0.75] * 6, max_iter=0)
    with pytest.raises(InputError, match="backend"):
        Hexapod.genhexkins(backend="gpu")


# ----------------------------------------------------------------- the C


DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include "hexapod_kinematics.h"

int main(void)
{
    const deltagen_hexapod_geometry g = {
        {%(base)s}, {%(platform)s}, {%(base_axes)s}, {%(platform_axes)s}, %(scale)s, %(tol)s};
    const deltagen_hexapod_fk_options options = {1e-9, 1.0, 0.5, 50, 0};
    double pose[3 * 16] = {0}, lengths[3 * 6], J[3 * 36], angles[3 * 12];
    int8_t status[3];
    for (int k = 0; k < 3; ++k) {
        pose[16 * k + 0] = cos(0.1 * k);
        pose[16 * k + 1] = -sin(0.1 * k);
        pose[16 * k + 4] = sin(0.1 * k);
        pose[16 * k + 5] = cos(0.1 * k);
        pose[16 * k + 10] = 1.0;
        pose[16 * k + 3] = 0.01 * k;
        pose[16 * k + 11] = %(z)s;
        pose[16 * k + 15] = 1.0;
    }
    if (deltagen_hexapod_ik(&g, 3, pose, lengths, status) != 0) return 1;
    if (deltagen_hexapod_jacobian(&g, 3, pose, lengths, J, status) != 0) return 1;
    if (deltagen_hexapod_joint_angles(&g, 3, pose, angles, status) != 0) return 1;
    double guess[3 * 16], out[3 * 16], residual[3];
    int32_t iterations[3];
    for (int k = 0; k < 3; ++k) {
        for (int j = 0; j < 16; ++j) guess[16 * k + j] = pose[j];
    }
    lengths[12] = NAN; /* the third point: invalid */
    if (deltagen_hexapod_fk(&g, 3, &options, lengths, guess, out, residual, iterations, status) != 0) return 1;
    for (int k = 0; k < 3; ++k) {
        double err = 0.0;
        for (int j = 0; j < 12; ++j) err = fmax(err, fabs(out[16 * k + j] - pose[16 * k + j]));
        printf("%%d %%.3e\n", status[k], err);
    }
    return 0;
}
"""


def _hex(values):
    return ", ".join(float(v).hex() for v in values)


@pytest.mark.skipif(GCC is None, reason="gcc not installed")
@pytest.mark.parametrize("sanitize", [False, True], ids=["strict", "asan-ubsan"])
def test_generated_c_strict_and_under_sanitizers(robot, tmp_path, sanitize):
    """The checked-in module and its runtime compile as strict C99 (-pedantic -Werror) and
    a driver's ik, jacobian, joint_angles and fk run clean (under ASan and UBSan too):
    fk returns the poses ik started from, and flags the NaN row INVALID."""
    for ext in (".c", ".h"):
        shutil.copy(paths.generated_dir() / f"hexapod_kinematics{ext}", tmp_path)
    for name in ("deltagen_hexapod_fk", "deltagen_linalg"):
        for ext in (".c", ".h"):
            shutil.copy(paths.runtime_dir() / f"{name}{ext}", tmp_path)
    s = geometry_struct(robot.geometry)
    (tmp_path / "driver.c").write_text(
        DRIVER
        % dict(
            base=_hex(s["base_joints"]),
            platform=_hex(s["platform_joints"]),
            base_axes=_hex(s["base_axes"]),
            platform_axes=_hex(s["platform_axes"]),
            scale=float(s["scale"]).hex(),
            tol=float(s["singular_tol"]).hex(),
            z=float(robot.geometry.home_position[2]).hex(),
        )
    )
    flags = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O1", "-g"]
    sources = ["driver.c", "hexapod_kinematics.c", "deltagen_hexapod_fk.c", "deltagen_linalg.c"]
    compile_c(sources, tmp_path / "driver", flags=flags, cwd=tmp_path, sanitize=sanitize)
    run = subprocess.run(["./driver"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and not run.stderr.strip(), run.stderr[-3000:]
    rows = [line.split() for line in run.stdout.split("\n") if line]
    assert [int(r[0]) for r in rows] == [st.OK, st.OK, st.INVALID]
    assert max(float(r[1]) for r in rows[:2]) < 1e-12


# ----------------------------------------------------------------- the command line


def test_cli_fk_ik_of_the_robot_file(capsys, tmp_path):
    """`deltagen ik` then `deltagen fk` of robots/hexapod_genhex.toml give the pose back;
    `deltagen workspace` draws its slices; commands that do not serve a hexapod refuse with
    exit status 2."""
    from deltagen.cli import main

    robot_file = str(paths.robots_dir() / "hexapod_genhex.toml")
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,z,roll,pitch,yaw\n0.01,-0.02,0.5,0.05,0.02,-0.1\n0,0,0.52,0,0,0\n")
    lengths = tmp_path / "lengths.csv"
    assert main(["ik", robot_file, "--input", str(poses), "--output", str(lengths)]) == 0
    back = tmp_path / "back.csv"
    assert main(["fk", robot_file, "--input", str(lengths), "--output", str(back)]) == 0
    table = np.genfromtxt(back, delimiter=",", names=True)
    got = np.column_stack([table[k] for k in ("x", "y", "z", "roll", "pitch", "yaw")])
    np.testing.assert_allclose(
        got, [[0.01, -0.02, 0.5, 0.05, 0.02, -0.1], [0, 0, 0.52, 0, 0, 0]], atol=1e-9
    )
    assert main(["fk", robot_file, "0.1", "2", "0.1", "2", "0.1", "2"]) == 1
    assert main(["validate", "--robot", robot_file]) == 2
    assert "the robot given is a hexapod" in capsys.readouterr().err
    assert main(["workspace", robot_file, "--out", str(tmp_path / "ws"), "--quiet"]) == 0
    assert (tmp_path / "ws" / "workspace_slices.png").stat().st_size > 10_000
    page = (tmp_path / "ws" / "workspace.html").read_text()  # the 3D page, plotly inlined
    assert "Scatter3d" in page or "scatter3d" in page
    summary = (tmp_path / "ws" / "workspace_summary.csv").read_text()
    assert "position_reachable_fraction" in summary


@pytest.mark.skipif(GCC is None, reason="gcc not installed")
def test_export_builds_and_its_example_agrees(robot, tmp_path, capsys):
    """`deltagen export` of the robot file writes a C package whose example, built with
    make, prints the leg lengths deltagen computes for the example's pose and fk's
    answer (the pose's position)."""
    from deltagen.apps.hexapod import EXAMPLE_POSITION, EXAMPLE_RPY
    from deltagen.cli import main

    out = tmp_path / "export"
    robot_file = str(paths.robots_dir() / "hexapod_genhex.toml")
    assert main(["export", robot_file, "--out", str(out)]) == 0
    capsys.readouterr()
    built = subprocess.run(["make", "-s"], cwd=out, capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stderr
    run = subprocess.run(["./example"], cwd=out, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    ik_line, fk_line = run.stdout.splitlines()
    position = np.add(robot.geometry.home_position, EXAMPLE_POSITION)
    expected = robot.ik(robot.pose(position, rpy=EXAMPLE_RPY))
    printed = np.array([float(v) for v in ik_line.split("=")[1].split()[:6]])
    np.testing.assert_allclose(printed, expected, atol=1e-9)
    found = np.array([float(v) for v in fk_line.split("=")[1].split()[:3]])
    np.testing.assert_allclose(found, position, atol=1e-9)


def test_threads_give_the_bits_of_one_thread():
    """A batch split across threads (native.parallel, at 40,000 rows and more) gives the
    single-threaded bits, fk included (each point iterates on its own)."""
    one = Hexapod.genhexkins()
    one._core.threads = 1
    two = Hexapod.genhexkins()
    two._core.threads = 2
    T = random_poses(one, 45_000, seed=31)
    lengths = one.ik(T)
    assert np.array_equal(lengths, two.ik(T))
    assert np.array_equal(one.jacobian(T), two.jacobian(T))
    a, b = one.fk_result(lengths[:41_000]), two.fk_result(lengths[:41_000])
    assert np.array_equal(a.status, b.status) and np.array_equal(a.pose, b.pose, equal_nan=True)


# ----------------------------------------------------------------- the shared base


def test_with_backend_round_trip_agrees_with_the_compiled_core(robot, reachable):
    """RobotFamily.with_backend: the same geometry on the numpy reference (its ReferenceCore
    over reference/hexapod.py) and back; the two backends agree on every quantity, fk by
    two different solvers (C damped Newton, SciPy least squares) from the same start."""
    ref = robot.with_backend("reference")
    assert ref.backend == "reference" and ref.geometry is robot.geometry
    back = ref.with_backend("compiled")
    assert back.backend == "compiled" and back.geometry is robot.geometry
    T = reachable[:40]
    lengths = robot.ik(T)
    np.testing.assert_allclose(ref.ik(T), lengths, rtol=0, atol=1e-12)
    assert np.array_equal(back.ik(T), lengths)
    np.testing.assert_allclose(ref.jacobian(T), robot.jacobian(T), rtol=0, atol=1e-12)
    twist = np.linspace(-0.1, 0.1, 6)
    np.testing.assert_allclose(
        ref.twist(T, robot.leg_rates(T, twist)),
        robot.twist(T, ref.leg_rates(T, twist)),
        rtol=0,
        atol=1e-12,
    )
    np.testing.assert_allclose(ref.fk(lengths), robot.fk(lengths), rtol=0, atol=1e-12)
    # warm start: the reference also starts each point from the previous converged pose
    s = np.linspace(0.0, 1.0, 12)
    path = robot.pose(
        np.column_stack([0.02 * s, 0 * s, 0.5 + 0.02 * s]),
        rpy=np.column_stack([0 * s, 0 * s, 1.2 * s]),
    )
    np.testing.assert_allclose(
        ref.fk(robot.ik(path), guess=path[0], trajectory=True), path, rtol=0, atol=1e-12
    )


def test_reference_backend_flags_bad_lengths_like_the_compiled_core(robot):
    """Non-finite lengths are INVALID on both backends (the reference's solver never sees
    them), unreachable ones UNREACHABLE or SINGULAR, never OK."""
    ref = robot.with_backend("reference")
    lengths = np.array([[math.nan] * 6, [0.75, 0.75, 1.5, 0.75, 0.75, 0.75], [0.76] * 6])
    for r in (robot, ref):
        result = r.fk_result(lengths)
        assert result.status[0] == st.INVALID and result.status[1] != st.OK
        assert result.status[2] == st.OK
        with pytest.raises(InputError, match=r"lengths: a non-finite value.* in rows \[0\]"):
            r.fk(lengths)
        _, valid = r.fk(lengths, errors="nan")
        assert valid.tolist() == [False, False, True]


def test_default_from_toml_and_threads_come_from_the_base(tmp_path):
    """default() is genhexkins' robot; from_toml and the constructors take threads=; the
    threads property checks its value and reaches the compiled core; the reference
    backend is single-threaded."""
    robot = Hexapod.default(threads=2)
    assert robot.geometry == HexapodGeometry.genhexkins() and robot.name == "genhex"
    assert robot.threads == 2 and robot._core.threads == 2
    robot.threads = 1
    assert robot._core.threads == 1
    with pytest.raises(InputError, match="threads"):
        robot.threads = 0
    with pytest.raises(InputError, match="threads"):
        Hexapod.genhexkins(threads=-1)
    loaded = Hexapod.from_toml(paths.robots_dir() / "hexapod_genhex.toml", threads=1)
    assert loaded.threads == 1 and loaded.with_backend("reference").threads == 1
    assert loaded.with_backend("reference")._core.threads is None
