"""Gantry robots in closed form (model/structure.py GantryArm, solve/analytic.py
_GantrySolver, the ik_all kernel of derive/serial/ik_closed_form.py).

Evidence, independent of the solver:
* a homogeneous-transform chain written in this file from the tables in the robot files'
  comments (4 x 4 matrices multiplied out; neither model.serial nor the product of
  exponentials): the arms' fk agrees with it, and every valid branch of ik_all reproduces
  the target through it to 1e-12 (the 5-axis head: the tool point and tool z axis);
* completeness: solutions from many starts of scipy's least squares on that chain (no
  joint limits) all appear among the closed form's branches;
* the generated C against the numpy solver;
* detection: a URDF gantry, a gantry with a squareness error and a wrist offset (still in
  closed form, still exact), and chains that are not gantries (a revolute first joint,
  parallel wrist axes, coplanar slides, a head whose tool axis lies along its last axis:
  no closed form, the numeric solver answers).
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess

import numpy as np
import pytest
from helpers import compile_c
from scipy.optimize import least_squares

from deltagen import SerialRobot, paths
from deltagen.model import structure as st
from deltagen.model.serial import SerialDescription
from deltagen.paths import robots_dir
from deltagen.solve.analytic import analytic_solver
from deltagen.status import INVALID, OK, UNREACHABLE

PI = math.pi
GANTRIES = {
    "gantry_xyz_wrist": ("gantry_wrist_3r", ("noflip", "flip")),
    "gantry_xyz_ac": ("gantry_head_2r", ("noflip", "flip")),
    "palletiser_xyzc": ("gantry_rotary_1r", ("single",)),
}


# ------------------------------------------------ an independent transform chain


def _trans(x=0.0, y=0.0, z=0.0):
    T = np.eye(4)
    T[:3, 3] = x, y, z
    return T


def _rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    T = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def _chain(name, q):
    """The tool pose of the bundled gantry ``name`` at q, multiplied out from the table in
    its robot file's comment (universal coordinates, slides first, tool Rot_x(180 deg))."""
    q = [float(v) for v in q]
    if name == "gantry_xyz_wrist":
        parts = [
            _trans(x=q[0]), _trans(z=2.0), _trans(y=q[1]), _trans(z=-0.15),
            _trans(z=-q[2]), _trans(z=-0.60), _rot("z", q[3]), _trans(z=-0.25),
            _rot("y", q[4]), _rot("z", q[5]), _trans(z=-0.12),
        ]  # fmt: skip
    elif name == "gantry_xyz_ac":
        parts = [
            _trans(x=q[0]), _trans(z=1.5), _trans(y=q[1]), _trans(z=-0.10),
            _trans(z=-q[2]), _trans(z=-0.40), _rot("z", q[3]), _trans(z=-0.18),
            _rot("x", q[4]), _trans(z=-0.22),
        ]  # fmt: skip
    else:
        parts = [
            _trans(x=q[0]), _trans(z=2.8), _trans(y=q[1]), _trans(z=-0.20),
            _trans(z=-q[2]), _trans(z=-0.80), _rot("z", q[3]), _trans(0.08, 0.0, -0.35),
        ]  # fmt: skip
    T = np.eye(4)
    for P in parts + [_rot("x", PI)]:
        T = T @ P
    return T


def _pose_error(name, q, T):
    """Largest difference of the chain's pose at q from T: position and, for the 5-axis
    head, the tool z axis only (its rotation about the tool axis is free)."""
    Tq = _chain(name, q)
    if name == "gantry_xyz_ac":
        return float(np.max(np.abs(Tq[:3, 2:] - T[:3, 2:])))
    return float(np.max(np.abs(Tq[:3, :] - T[:3, :])))


def _in_limits(arm, count, seed):
    rng = np.random.default_rng(seed)
    lim = arm.qlim
    return rng.uniform(np.maximum(lim[:, 0], -PI), np.minimum(lim[:, 1], PI), (count, arm.n))


def _angle_diff(a, b):
    return np.remainder(a - b + PI, 2 * PI) - PI


def _same(arm, qa, qb, tol=1e-6):
    rev = np.array([j.revolute for j in arm.description.joints])
    d = np.where(rev, _angle_diff(qa, qb), qa - qb)
    return np.all(np.abs(d) < tol, axis=-1)


@pytest.fixture(scope="module", params=list(GANTRIES))
def gantry(request):
    return request.param, SerialRobot.load(request.param, backend="reference")


# -------------------------------------------------------------------- detection


@pytest.mark.parametrize("name", list(GANTRIES))
def test_bundled_gantries_are_detected(name):
    desc = SerialDescription.from_toml(robots_dir() / f"{name}.toml")
    found = st.detect(desc)
    assert type(found) is st.GantryArm
    assert (found.kind, found.configs) == GANTRIES[name]
    # the slides' inverse is the inverse of their directions
    W = found.axes.directions[:3].T
    np.testing.assert_allclose(found.slide_inverse @ W, np.eye(3), atol=1e-15)


def test_fk_matches_the_independent_chain(gantry):
    name, arm = gantry
    q = _in_limits(arm, 50, seed=3)
    T = arm.fk(q)
    for k in range(q.shape[0]):
        np.testing.assert_allclose(T[k], _chain(name, q[k]), atol=1e-13)


# ------------------------------------------------------------------- round trips


def test_every_valid_branch_reproduces_the_target(gantry):
    name, arm = gantry
    q = _in_limits(arm, 300, seed=5)
    T = arm.fk(q)
    result = arm.ik_all(T)
    qa, va = result
    assert result.complete
    assert va.all(axis=1).mean() > 0.9  # both branches inside the ranges for most poses
    worst = 0.0
    for i, k in zip(*np.nonzero(va)):
        worst = max(worst, _pose_error(name, qa[i, k], T[i]))
    assert worst < 1e-12
    # the configuration the pose came from is among the valid branches
    assert np.all((_same(arm, qa, q[:, None]) & va).any(axis=1))
    # valid means inside the joint limits (travel ranges of the slides included)
    inside = np.all((qa >= arm.qlim[:, 0]) & (qa <= arm.qlim[:, 1]), axis=-1)
    np.testing.assert_array_equal(va, inside & np.isfinite(qa).all(-1))


def test_no_solution_is_missing(gantry):
    """Least squares from 30 random starts on the independent chain (no limits): every
    converged solution is one of the closed form's branches (limits off)."""
    name, arm = gantry
    solver = analytic_solver(arm.description)
    rng = np.random.default_rng(11)
    rev = np.array([j.revolute for j in arm.description.joints])
    for q in _in_limits(arm, 4, seed=13):
        T = _chain(name, q)
        qa, va = solver.solve(T, limits=False)
        assert va.any()

        def residual(x, T=T):
            Tq = _chain(name, x)
            cols = slice(2, 4) if name == "gantry_xyz_ac" else slice(0, 4)
            return (Tq[:3, cols] - T[:3, cols]).ravel()

        found = 0
        for _ in range(30):
            x0 = np.where(rev, rng.uniform(-PI, PI, arm.n), rng.uniform(-1.0, 4.0, arm.n))
            sol = least_squares(residual, x0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
            if np.max(np.abs(residual(sol.x))) > 1e-10:
                continue
            found += 1
            assert _same(arm, qa[va], sol.x, tol=1e-5).any(), (name, sol.x, qa)
        assert found >= 8


def test_numeric_ik_lands_on_a_closed_form_branch(gantry):
    """deltagen's own numeric solver (damped Newton from random in-limit starts) on poses
    of in-limit configurations: each converged solution is a valid closed-form branch."""
    name, arm = gantry
    q = _in_limits(arm, 12, seed=31)
    T = arm.fk(q)
    q0 = _in_limits(arm, 12, seed=37)
    qn, ok = arm.ik(T, method="numeric", q0=q0, errors="nan", singular="allow")
    qa, va = arm.ik_all(T)
    assert ok.mean() > 0.8
    for i in np.flatnonzero(ok):
        assert (_same(arm, qa[i], qn[i], tol=1e-7) & va[i]).any(), (name, qn[i], qa[i])


def test_c_kernel_equals_the_numpy_solver(gantry):
    name, reference = gantry
    compiled = SerialRobot.load(name)
    assert compiled._core.has_ik_all
    q = _in_limits(compiled, 1000, seed=17)
    T = compiled.fk(q)
    qc, vc = compiled.ik_all(T)
    qn, vn = reference.ik_all(T)
    np.testing.assert_array_equal(vc, vn)
    both = np.isfinite(qc) & np.isfinite(qn)
    np.testing.assert_array_equal(np.isfinite(qc), np.isfinite(qn))
    # q4, q6 of the 3R wrist are ill-conditioned near q5 = 0 (their sum is not): 1e-9
    assert np.max(np.abs(_angle_diff(qc, qn)[both])) < 1e-9
    worst = max(_pose_error(name, qc[i, k], T[i]) for i, k in zip(*np.nonzero(vc)))
    assert worst < 1e-12


# ------------------------------------------------------- what each layout solves


def test_head_leaves_the_rotation_about_the_tool_axis_free():
    """5 axes: a target turned about its own tool z axis is reached (tool point and tool
    axis to 1e-12); the tool's x axis then is the head's, not the target's."""
    name = "gantry_xyz_ac"
    arm = SerialRobot.load(name, backend="reference")
    rng = np.random.default_rng(19)
    q = _in_limits(arm, 100, seed=23)
    T = arm.fk(q) @ np.stack([_rot("z", a) for a in rng.uniform(0.3, 2.8, q.shape[0])])
    qa, va = arm.ik_all(T)
    assert va.all(axis=1).mean() > 0.9
    x_moved = 0.0
    for i, k in zip(*np.nonzero(va)):
        assert _pose_error(name, qa[i, k], T[i]) < 1e-12
        x_moved = max(x_moved, float(np.max(np.abs(_chain(name, qa[i, k])[:3, 0] - T[i, :3, 0]))))
    assert x_moved > 0.1  # the x axis is not the target's: it was not asked for
    # a tool axis the A axis cannot tilt to (beyond 110 deg from the vertical) is out of
    # its range: solved with the limits off, not valid with them
    T_up = _chain(name, [1.0, 0.8, 0.2, 0.4, math.radians(150.0)])
    _, within = arm.ik_all(T_up)
    _, free = analytic_solver(arm.description).solve(T_up, limits=False)
    assert not within.any() and free.any()


def test_head_branches_are_the_two_tilts_and_meet_at_the_vertical():
    arm = SerialRobot.load("gantry_xyz_ac", backend="reference")
    T = arm.fk(np.array([1.0, 0.5, 0.3, 0.7, 0.6]))
    qa, va = arm.ik_all(T)
    assert va.all()
    assert np.sign(qa[0, 4]) == -np.sign(qa[1, 4])  # A and -A
    assert abs(abs(_angle_diff(qa[0, 3], qa[1, 3])) - PI) < 1e-12  # C and C + pi
    # tool axis straight down (along the C axis): C is free, 0 is returned
    qv, vv = arm.ik_all(arm.fk(np.array([1.0, 0.5, 0.3, 1.1, 0.0])))
    assert vv.all() and np.all(np.abs(qv[:, 3]) < 1e-12)
    assert max(_pose_error("gantry_xyz_ac", x, arm.fk(np.array([1.0, 0.5, 0.3, 1.1, 0.0])))
               for x in qv) < 1e-12  # fmt: skip


@pytest.mark.parametrize("backend", ["reference", "compiled"])
def test_head_refuses_a_target_that_is_not_a_rotation(backend):
    """The head compares the tool axis only; a target whose x and y columns are not those of
    a rotation (scaled, sheared, left-handed) is not valid all the same (solver and C)."""
    arm = SerialRobot.load("gantry_xyz_ac", backend=backend)
    T = arm.fk(np.array([1.0, 0.5, 0.3, 0.7, 0.6]))
    bad = np.stack([T, T, T, T])
    bad[1, :3, 0] *= 1.1  # x column scaled
    bad[2, :3, 1] += 0.05 * bad[2, :3, 2]  # y column sheared towards z
    bad[3, :3, 0] *= -1.0  # left-handed
    solver = analytic_solver(arm.description)
    _, valid = solver.solve(bad)
    assert valid[0].all() and not valid[1:].any()
    if backend == "compiled":
        q, valid, status = arm._core.ik_all(np.ascontiguousarray(bad), 2)
        assert valid[0].all() and not valid[1:].any() and np.isnan(q[1:]).all()


def test_palletiser_solves_point_and_yaw_and_refuses_a_tilt():
    name = "palletiser_xyzc"
    arm = SerialRobot.load(name, backend="reference")
    q = np.array([2.0, 1.0, 0.6, 2.5])
    T = arm.fk(q)
    qa, va = arm.ik_all(T)
    assert va.all() and np.allclose(qa[0], q, atol=1e-12)
    tilted = T @ _rot("x", 0.05)
    qt, vt = arm.ik_all(tilted)
    assert not vt.any() and np.isnan(qt).all()
    # the position alone: reached, the yaw as near as the arm goes
    qp, vp = analytic_solver(arm.description).solve(tilted, position_only=True)
    assert vp.all() and np.max(np.abs(_chain(name, qp[0])[:3, 3] - tilted[:3, 3])) < 1e-12
    with pytest.raises(Exception, match="orientation not reachable"):
        arm.ik(tilted)


def test_travel_ranges_are_respected():
    arm = SerialRobot.load("gantry_xyz_wrist", backend="reference")
    T = arm.fk(np.array([2.9, 1.0, 0.3, 0.2, 0.5, -0.3]))
    T[0, 3] += 0.2  # X beyond its 3.0 m of travel
    qa, va = arm.ik_all(T)
    assert not va.any()
    assert np.all(qa[:, 0] > 3.0)  # solved, outside the range: kept, not valid
    with pytest.raises(Exception, match="outside the joint limits"):
        arm.ik(T)


def test_wrist_singularity_is_solved():
    """q5 = 0: axes 4 and 6 in line; q4 = 0 and q6 takes the whole turn."""
    arm = SerialRobot.load("gantry_xyz_wrist", backend="reference")
    T = arm.fk(np.array([1.0, 1.0, 0.4, 0.7, 0.0, -0.4]))
    qa, va = arm.ik_all(T)
    assert va.any()
    for k in np.flatnonzero(va):
        assert _pose_error("gantry_xyz_wrist", qa[k], T) < 1e-12
        assert abs(qa[k, 3]) < 1e-12


# ---------------------------------------------------------------- more detection


URDF_GANTRY = """<?xml version="1.0"?>
<robot name="urdf_gantry">
  <link name="base"/><link name="x"/><link name="y"/><link name="z"/>
  <link name="w1"/><link name="w2"/><link name="w3"/><link name="tool"/>
  <joint name="jx" type="prismatic"><parent link="base"/><child link="x"/>
    <origin xyz="0.3 0.1 1.8" rpy="0 0 0.4"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="2" effort="1" velocity="1"/></joint>
  <joint name="jy" type="prismatic"><parent link="x"/><child link="y"/>
    <origin xyz="0 0 -0.1"/><axis xyz="0 -1 0"/>
    <limit lower="-1.5" upper="0" effort="1" velocity="1"/></joint>
  <joint name="jz" type="prismatic"><parent link="y"/><child link="z"/>
    <origin xyz="0.05 0 -0.3" rpy="3.141592653589793 0 0"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.9" effort="1" velocity="1"/></joint>
  <joint name="j4" type="revolute"><parent link="z"/><child link="w1"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j5" type="revolute"><parent link="w1"/><child link="w2"/>
    <origin xyz="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j6" type="revolute"><parent link="w2"/><child link="w3"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="w3"/><child link="tool"/>
    <origin xyz="0 0 0.1" rpy="0 0.2 0"/></joint>
</robot>
"""


def _round_trip(arm, count=200, seed=29):
    q = _in_limits(arm, count, seed)
    T = arm.fk(q)
    qa, va = arm.ik_all(T)
    assert np.all((_same(arm, qa, q[:, None]) & va).any(axis=1))
    Tb = arm.fk(np.where(np.isfinite(qa), qa, 0.0).reshape(-1, arm.n)).reshape(count, -1, 4, 4)
    return float(np.max(np.abs(Tb - T[:, None])[va]))


def test_urdf_gantry_is_detected_and_solved(tmp_path):
    path = tmp_path / "urdf_gantry.urdf"
    path.write_text(URDF_GANTRY)
    arm = SerialRobot.from_urdf(path, backend="reference")
    found = st.detect(arm.description)
    assert type(found) is st.GantryArm and found.kind == "gantry_wrist_3r"
    assert _round_trip(arm) < 1e-12


def test_standard_dh_gantry_is_detected_and_solved():
    """A Cartesian arm in standard DH rows (slides along z0, then x, then y; a wrist whose
    axes 4 and 6 are parallel, Z-X-Z like): the same structure, found in that convention."""
    rows = [
        dict(type="prismatic", theta=-PI / 2, alpha=-PI / 2, a=0.1),
        dict(type="prismatic", theta=-PI / 2, alpha=PI / 2, a=0.05),
        dict(type="prismatic", theta=0.0, alpha=0.0),
        dict(type="revolute", alpha=-PI / 2, d=0.2),
        dict(type="revolute", alpha=PI / 2),
        dict(type="revolute", d=0.1),
    ]
    desc = SerialDescription.from_rows(rows, "standard", name="dh_gantry")
    found = st.detect(desc)
    assert type(found) is st.GantryArm and found.kind == "gantry_wrist_3r"
    assert _round_trip(SerialRobot(desc, backend="reference")) < 1e-12


def _universal(slide_tilt=0.0, wrist_offset=0.0, first="prismatic", w5="y", tool=("x", PI), n=6):
    rows = [
        dict(type=first, axis="x", tz=2.0),
        dict(type="prismatic", axis="y", tz=-0.15, rx=slide_tilt),
        dict(type="prismatic", axis="z", sign=-1.0, tz=-0.6),
        dict(type="revolute", axis="z", tz=-0.25),
        dict(type="revolute", axis=w5, ty=wrist_offset),
        dict(type="revolute", axis="z", tz=-0.12),
    ][:n]
    return SerialDescription.from_rows(rows, "universal", name="variant", tool=_rot(*tool))


def test_squareness_error_and_wrist_offset_keep_the_closed_form_exact():
    """The closed form needs independent slides, not orthogonal ones, and no common wrist
    point: a 1 mrad squareness error of Z against Y and a 2 mm offset of axis 5 are still
    gantries, solved exactly (the axes are not those of a central wrist any more)."""
    desc = _universal(slide_tilt=1e-3, wrist_offset=0.002)
    ax = st.joint_axes(desc)
    assert abs(ax.directions[1] @ ax.directions[2]) > 1e-4  # not orthogonal
    assert st.central_wrist(ax) is None  # axes 4, 5, 6 do not meet
    assert type(st.detect(desc)) is st.GantryArm
    assert _round_trip(SerialRobot(desc, backend="reference")) < 1e-12


def test_bc_head_with_an_offset_tool_is_solved():
    """A B/C head (C about z, B about y) whose tool point sits 3 cm off the B axis and whose
    Z slide is 1 mrad out of square: the tool point and the tool axis of every valid
    branch, through the description's own transforms, to 1e-12; both tilts found."""
    desc = _universal(slide_tilt=1e-3, wrist_offset=0.03, w5="y", n=5)
    found = st.detect(desc)
    assert type(found) is st.GantryArm and found.kind == "gantry_head_2r"
    arm = SerialRobot(desc, backend="reference")
    rng = np.random.default_rng(43)
    q = np.column_stack([rng.uniform(-1, 1, (200, 3)), rng.uniform(-PI, PI, 200),
                         rng.uniform(-1.4, 1.4, 200)])  # fmt: skip
    T = arm.fk(q)
    qa, va = arm.ik_all(T)
    assert va.all(axis=1).mean() > 0.95
    Tb = arm.fk(np.where(np.isfinite(qa), qa, 0.0).reshape(-1, 5)).reshape(200, 2, 4, 4)
    assert np.max(np.abs(Tb - T[:, None])[..., :3, 2:][va]) < 1e-12
    assert np.all((_same(arm, qa, q[:, None]) & va).any(axis=1))


@pytest.mark.parametrize(
    "variant",
    [
        dict(first="revolute"),  # R P P R R R: not three slides
        dict(w5="z"),  # axis 5 parallel to 4 and 6: the wrist turns about one direction
        dict(slide_tilt=PI / 2),  # the Y slide turned onto Z: the slides are coplanar
        dict(w5="x", tool=("y", PI / 2), n=5),  # a head whose tool axis lies along its A axis
    ],
)
def test_not_gantries_fall_back_to_the_numeric_solver(variant):
    desc = _universal(**variant)
    assert not isinstance(st.detect(desc), st.GantryArm)
    assert analytic_solver(desc) is None
    arm = SerialRobot(desc, backend="reference")
    assert arm.analytic_configs() == ()


# ------------------------------------------------------- the C alone, sanitized

HEAD_DRIVER = r"""
#include <stdio.h>
#include <math.h>
#include "serial_gantry_xyz_ac.h"

#define N %(n)d
static const double T_IN[N * 16] = {%(poses)s};

int main(void) {
    static double q[N * 10];
    static uint8_t valid[N * 2];
    static int8_t status[N];
    if (deltagen_gantry_xyz_ac_ik_all(N, T_IN, q, valid, status) != 0) return 1;
    for (size_t i = 0; i < N; ++i) {
        printf("%%d %%d %%d", (int)status[i], valid[2 * i] == 1, valid[2 * i + 1] == 1);
        for (size_t c = 0; c < 10; ++c) printf(" %%a", q[i * 10 + c]);
        printf("\n");
    }
    return 0;
}
"""


@pytest.mark.slow
def test_head_ik_all_alone_under_sanitizers(tmp_path, sanitizers):
    """The generated ik_all of the 5-axis head built alone with ASan/UBSan on poses with
    NaN, infinite, huge, non-rigid, out-of-travel and singular (tool axis along C) rows: no
    report, the status codes as documented, the flags and angles of the numpy solver."""
    arm = SerialRobot.load("gantry_xyz_ac", backend="reference")
    T = arm.fk(_in_limits(arm, 60, seed=41))
    T[5] = arm.fk(np.array([1.0, 0.5, 0.3, 1.1, 0.0]))  # tool axis along C
    T[10, :3, 3] += 40.0  # beyond the travel of every slide
    T[20, 2, 2] = np.nan
    T[30, 0, 3] = -np.inf
    T[40, :3, 0] *= 0.9  # not a rotation (the tool axis column untouched)
    T[50, :3, 3] = 1e300
    poses = ", ".join(
        float(x).hex()
        if np.isfinite(x)
        else ("NAN" if np.isnan(x) else ("INFINITY" if x > 0 else "-INFINITY"))
        for x in T.reshape(-1)
    )
    for name in ("serial_gantry_xyz_ac.c", "serial_gantry_xyz_ac.h"):
        shutil.copy(paths.generated_dir() / name, tmp_path)
    runtime = sorted(paths.runtime_dir().glob("deltagen_*.[ch]"))
    for path in runtime:
        shutil.copy(path, tmp_path)
    (tmp_path / "driver.c").write_text(HEAD_DRIVER % dict(n=len(T), poses=poses))
    sources = ["driver.c", "serial_gantry_xyz_ac.c", *(p.name for p in runtime if p.suffix == ".c")]
    flags = ["-std=c99", "-O0", "-Wall", "-Wextra", "-Werror", *sanitizers]
    compile_c(sources, tmp_path / "driver", flags=flags, cwd=tmp_path)
    env = dict(os.environ, UBSAN_OPTIONS="halt_on_error=1")
    run = subprocess.run(
        [str(tmp_path / "driver")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert run.returncode == 0 and run.stderr == "", run.stderr[-3000:]
    rows = [line.split() for line in run.stdout.splitlines()]
    status = np.array([int(r[0]) for r in rows])
    valid = np.array([[v == "1" for v in r[1:3]] for r in rows])
    q_c = np.array(
        [[float.fromhex(v) if "nan" not in v else math.nan for v in r[3:]] for r in rows]
    )
    q_c = q_c.reshape(len(T), 2, 5)
    assert status[20] == INVALID and status[30] == INVALID
    assert status[10] == UNREACHABLE and status[40] == UNREACHABLE and status[50] == UNREACHABLE
    assert status[5] == OK and np.all(np.abs(q_c[5, :, 3]) < 1e-12)
    safe = np.where(np.isfinite(T), T, 0.0)
    safe[:, 3] = [0, 0, 0, 1]
    q_n, v_n = analytic_solver(arm.description).solve(safe)
    rows_ok = np.isin(status, (OK, UNREACHABLE))
    np.testing.assert_array_equal(valid[rows_ok], v_n[rows_ok])
    both = np.isfinite(q_c) & np.isfinite(q_n)
    assert np.max(np.abs(_angle_diff(q_c, q_n)[both])) < 1e-9
