"""Checks that do not depend on the path a call takes, and errors that name their cause.

The same checks on every path: SerialRobot.ik / ik_all and DeltaRobot.fk / ik have
single-pose fast paths next to the batched one, and some of them only exist after a first
call. Every bad call below is
made as a single pose, a batch of one and a batch (the bad row first), on a fresh robot
(first call) and on one whose fast paths are warm (later call), on both backends; the
error class and message (rows text aside) must be the same everywhere.

The cause named: each error names the actual cause (out of reach, an orientation the
structure cannot reach, the joint limits, invalid q0, max_iter, the arm's own shape) and the rows;
the evidence for "the cause is X" is a second call that differs in X only and succeeds.
"""

from __future__ import annotations

import re
from decimal import Decimal

import numpy as np
import pytest

from deltagen import DeltaRobot, SerialRobot, SingularityError, UnreachableError
from deltagen.errors import DeltagenError, GeometryError, KinematicsError
from deltagen.geometry.rotations import rot_axis
from deltagen.inputs import InputError

Q_PUMA = np.array([0.1, -0.5, 0.3, 0.2, 0.6, -0.4])
ROWS = re.compile(r"rows \[[^\]]*\] \(\d+ of the batch\)")


def _norm(message: str) -> str:
    return ROWS.sub("rows <R>", message)


def _puma(backend, warm):
    arm = SerialRobot.load("puma560", backend=backend)
    if warm:  # every fast path built and used once
        T = arm.fk(Q_PUMA)
        arm.ik(T)
        arm.ik_all(T)
        arm.ik(T, method="numeric", q0=Q_PUMA)
        arm.ik(T, method="numeric")
    return arm


def _target():
    return SerialRobot.load("puma560", backend="reference").fk(Q_PUMA)


def _non_rigid():
    T = _target()
    T[:3, :3] *= 1.1
    return T


def _bottom_row():
    T = _target()
    T[3, 0] = 0.25
    return T


def _nan_pose():
    T = _target()
    T[1, 2] = np.nan
    return T


def _far():
    T = _target()
    T[:3, 3] = [4.0, -3.0, 2.0]
    return T


# name: (target T, keyword arguments, error class, message pattern)
IK_CASES = {
    "numeric non-rigid T": (_non_rigid, dict(method="numeric"), InputError, "not a rigid"),
    "auto non-rigid T": (_non_rigid, {}, InputError, "not a rigid"),
    "numeric bottom row": (_bottom_row, dict(method="numeric", q0=Q_PUMA), InputError, "rigid"),
    "analytic bottom row": (_bottom_row, dict(method="analytic"), InputError, "rigid"),
    "NaN in T": (_nan_pose, {}, InputError, "T contains NaN"),
    "numeric NaN in T": (_nan_pose, dict(method="numeric"), InputError, "T contains NaN"),
    "misspelt method": (_target, dict(method="analytik"), InputError, "method must be"),
    "unknown config": (_target, dict(config="sideways"), InputError, "unknown configuration"),
    "config with numeric": (
        _target,
        dict(config="front_up_noflip", method="numeric"),
        InputError,
        "does not apply to the numeric",
    ),
    "misspelt errors": (_target, dict(errors="Raise"), InputError, "errors must be"),
    "misspelt singular": (_target, dict(singular="ignore"), InputError, "singular must be"),
    "bad seed": (_target, dict(method="numeric", seed="x"), InputError, "seed must be"),
    "negative restarts": (_target, dict(method="numeric", restarts=-1), InputError, "restarts"),
    "max_iter 0": (
        _target,
        dict(method="numeric", max_iter=0),
        InputError,
        r"max_iter must be an integer >= 1",
    ),
    "negative tol": (_target, dict(method="numeric", tol=-1.0), InputError, "tol must be"),
    "unknown option": (
        _target,
        dict(method="numeric", tolerance=1e-9),
        InputError,
        "unknown option",
    ),
    "numeric option on the closed form": (
        _target,
        dict(restarts=3),
        InputError,
        "apply to method='numeric' only",
    ),
    "NaN q0 numeric": (
        _target,
        dict(method="numeric", q0=np.full(6, np.nan)),
        InputError,
        "q0 contains NaN",
    ),
    "NaN q0 analytic": (_target, dict(q0=np.full(6, np.nan)), InputError, "q0 contains NaN"),
    "q0 of 3 values": (
        _target,
        dict(method="numeric", q0=np.zeros(3)),
        InputError,
        r"q0 must have shape \(\.\.\., 6\)",
    ),
    "out of reach": (_far, {}, UnreachableError, "out of reach"),
    "numeric out of reach": (_far, dict(method="numeric"), UnreachableError, "out of reach"),
}


def _shapes(T):
    good = _target()
    return {"single": T, "batch of one": T[None], "batch": np.stack([T, good])}


@pytest.mark.parametrize("case", list(IK_CASES))
def test_ik_refuses_the_same_way_on_every_path(case):
    make, kwargs, error, pattern = IK_CASES[case]
    seen = {}
    for backend in ("compiled", "reference"):
        for warm in (False, True):
            for shape, T in _shapes(make()).items():
                arm = _puma(backend, warm)
                with pytest.raises(error) as info:
                    arm.ik(T, **kwargs)
                assert type(info.value) is error
                assert re.search(pattern, str(info.value)), str(info.value)
                rows = info.value.rows
                assert rows.dtype == np.intp
                if ROWS.search(str(info.value)):
                    assert 0 in rows and 1 not in rows or "q0" in case
                seen[(backend, warm, shape)] = _norm(str(info.value))
    assert len(set(seen.values())) == 1, seen


@pytest.mark.parametrize("make", [_non_rigid, _bottom_row, _nan_pose])
def test_ik_all_marks_bad_poses_invalid_on_every_path(make):
    results = []
    for backend in ("compiled", "reference"):
        for warm in (False, True):
            arm = _puma(backend, warm)
            for T in _shapes(make()).values():
                q, valid = arm.ik_all(T)
                first = valid.reshape(-1, valid.shape[-1])[0]
                assert not first.any()
                assert np.isnan(q.reshape(-1, *q.shape[-2:])[0]).all()
                results.append(first.tolist())
    assert len({tuple(r) for r in results}) == 1


def test_ik_accepts_the_same_way_on_every_path():
    """A good call gives one answer on every path (and fk of it is the target)."""
    T = _target()
    for backend in ("compiled", "reference"):
        for warm in (False, True):
            arm = _puma(backend, warm)
            for kwargs in ({}, dict(method="numeric", q0=Q_PUMA + 0.05), dict(config=None)):
                single = arm.ik(T, **kwargs)
                batch = arm.ik(np.stack([T, T]), **kwargs)
                np.testing.assert_allclose(batch[0], single, atol=1e-9)
                np.testing.assert_allclose(arm.fk(single), T, atol=1e-9)


# -- the delta robot and the serial fk: list inputs take the same checks as arrays -------


@pytest.mark.parametrize(
    "values",
    [[True, False, True], [Decimal("0.1"), 0.0, 0.0], [0.1, True, 0.2], ["0.1", 0.0, 0.0]],
    ids=["bools", "decimal", "one bool", "string"],
)
@pytest.mark.parametrize("backend", ["compiled", "reference"])
@pytest.mark.parametrize("method", ["fk", "ik"])
def test_delta_list_inputs_refused_as_single_and_batch(values, backend, method):
    robot = DeltaRobot.default(backend=backend)
    call = getattr(robot, method)
    messages = set()
    for arg in (values, [values], tuple(values)):
        with pytest.raises(InputError) as info:
            call(arg)
        messages.add(str(info.value))
    assert len(messages) == 1, messages


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_serial_fk_list_of_bools_refused_as_single_and_batch(backend):
    arm = SerialRobot.load("puma560", backend=backend)
    for arg in ([True] * 6, [[True] * 6], [0.1, 0.2, 0.3, 0.4, 0.5, False]):
        with pytest.raises(InputError, match="numeric"):
            arm.fk(arg)
        with pytest.raises(InputError, match="numeric"):
            arm.jacobian(arg)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_misspelt_errors_mode_is_refused_by_every_method(backend):
    arm = SerialRobot.load("puma560", backend=backend)
    robot = DeltaRobot.default(backend=backend)
    calls = [
        lambda e: arm.fk(Q_PUMA, errors=e),
        lambda e: arm.jacobian(Q_PUMA, errors=e),
        lambda e: arm.euler(Q_PUMA, errors=e),
        lambda e: arm.rpy(Q_PUMA, errors=e),
        lambda e: arm.pose(Q_PUMA, errors=e),
        lambda e: arm.manipulability(Q_PUMA, errors=e),
        lambda e: arm.condition_number(Q_PUMA, errors=e),
        lambda e: arm.analytic_jacobian(Q_PUMA, errors=e),
        lambda e: arm.singularities(Q_PUMA, errors=e),
        lambda e: robot.fk([0.1, 0.2, 0.3], errors=e),
        lambda e: robot.ik([0.0, 0.0, -0.9], errors=e),
    ]
    for call in calls:
        for bad in ("Raise", "nans", np.array(["raise", "nan"]), None):
            with pytest.raises(InputError, match="errors must be"):
                call(bad)


# -- the cause named ------------------------------------------------------------------------


def _planar(backend="compiled", qlim2=None):
    rows = [{"a": 0.3}, {"a": 0.2}]
    if qlim2 is not None:
        rows[1]["qlim"] = list(qlim2)
    return SerialRobot.from_dh(rows, "standard", name="planar2", backend=backend)


def _planar_pose(x, y, yaw):
    T = np.eye(4)
    T[:3, :3] = rot_axis("z", yaw)
    T[:2, 3] = x, y
    return T


@pytest.mark.parametrize("backend", ["compiled", "reference"])
@pytest.mark.parametrize("method", ["auto", "numeric"])
def test_out_of_reach_is_named_with_the_reach(backend, method):
    arm = _planar(backend)
    near = arm.fk(np.array([0.2, -0.7]))  # a pose the arm reaches
    # links 0.3 m and 0.2 m: the tool point reaches at most 0.5 m from the base
    far = near.copy()
    far[:3, 3] *= 0.6 / np.linalg.norm(near[:3, 3])
    with pytest.raises(UnreachableError, match="out of reach") as info:
        arm.ik(far, method=method)
    assert "0.6 m" in str(info.value) and re.search(r"at most 0\.5\d* m", str(info.value))
    assert info.value.rows.tolist() == [0]
    assert "joint limits" not in str(info.value)
    q = arm.ik(near, method=method)  # the distance was the cause
    np.testing.assert_allclose(arm.fk(q), near, atol=1e-9)


def test_yaw_a_planar_arm_cannot_take_at_that_position_is_named():
    arm = _planar()
    T = arm.fk(np.array([0.2, -0.7]))
    turned = T.copy()
    turned[:3, :3] = rot_axis("z", 0.3) @ T[:3, :3]  # same point, another yaw
    with pytest.raises(UnreachableError, match="orientation not reachable") as info:
        arm.ik(turned)
    assert "position alone is reachable" in str(info.value)
    assert "tilted" not in str(info.value)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_joint_limits_named_when_the_solutions_lie_outside_them(backend):
    free = _planar(backend)
    limited = _planar(backend, qlim2=(0.0, 0.5))
    q_out = np.array([0.2, 1.2])  # both elbow branches have |q2| = 1.2 > 0.5
    T = free.fk(q_out)
    np.testing.assert_allclose(free.fk(free.ik(T)), T, atol=1e-12)  # reachable
    # the same arm with other limits is another compiled core (its ik_all checks them in C)
    _, valid = limited.ik_all(T)
    _, valid_reference = limited.with_backend("reference").ik_all(T)
    assert valid.tolist() == valid_reference.tolist() == [False, False]
    with pytest.raises(UnreachableError, match="outside the joint limits") as info:
        limited.ik(T)
    assert "out of reach" not in str(info.value)
    assert info.value.rows.tolist() == [0]


@pytest.mark.parametrize("backend", ["compiled", "reference"])
@pytest.mark.parametrize("method", ["auto", "numeric"])
@pytest.mark.parametrize("name", ["lecture_scara", "manutec_h5"])
def test_tilted_scara_target_names_the_orientation(backend, method, name):
    arm = SerialRobot.load(name, backend=backend)
    q_true = np.clip(np.full(arm.n, 0.3), arm.qlim[:, 0], arm.qlim[:, 1])
    T = arm.fk(q_true)
    start = dict(q0=q_true + 0.05) if method == "numeric" else {}
    np.testing.assert_allclose(arm.fk(arm.ik(T, method=method, **start)), T, atol=1e-9)
    tilted = T.copy()
    tilted[:3, :3] = rot_axis("x", 0.2) @ T[:3, :3]
    for shape in (tilted, tilted[None]):  # one pose and a batch of one: the same refusal
        with pytest.raises(UnreachableError, match="orientation not reachable by this") as e:
            arm.ik(shape, method=method, **start)
        assert "tilted" in str(e.value)
        assert "joint limits" not in str(e.value) and "out of reach" not in str(e.value)
    batch = np.stack([T, tilted, T])
    with pytest.raises(UnreachableError) as info:
        arm.ik(batch, method=method, **start)
    assert info.value.rows.tolist() == [1]
    q, ok = arm.ik(batch, method=method, errors="nan", **start)
    assert ok.tolist() == [True, False, True]
    if method == "numeric":  # the fit of the components the arm moves, when asked for
        fitted = arm.ik(tilted, method=method, mask=[1, 1, 1, 0, 0, 1], **start)
        np.testing.assert_allclose(arm.fk(fitted)[:3, 3], T[:3, 3], atol=1e-9)


@pytest.mark.parametrize("method", ["auto", "numeric"])
def test_nan_q0_is_named_not_called_unreachable(method):
    arm = SerialRobot.load("puma560")
    T = arm.fk(Q_PUMA)
    q0 = np.array([Q_PUMA, np.full(6, np.nan)])
    with pytest.raises(InputError, match=r"q0 contains NaN or infinite values in rows \[1\]") as e:
        arm.ik(np.stack([T, T]), q0=q0, method=method)
    assert e.value.rows.tolist() == [1]
    q, ok = arm.ik(np.stack([T, T]), q0=q0, method=method, errors="nan")
    assert ok.tolist() == [True, False]
    np.testing.assert_allclose(arm.fk(q[0]), T, atol=1e-9)


def test_q0_that_does_not_broadcast_is_named():
    arm = SerialRobot.load("puma560")
    T = np.stack([arm.fk(Q_PUMA)] * 3)
    with pytest.raises(InputError, match="does not broadcast"):
        arm.ik(T, q0=np.zeros((2, 6)), method="numeric")


def test_max_iter_below_one_is_named():
    arm = SerialRobot.load("puma560")
    for bad in (0, -3, 2.5, True):
        with pytest.raises(InputError, match="max_iter must be an integer >= 1"):
            arm.ik(arm.fk(Q_PUMA), method="numeric", max_iter=bad)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_shape_errors_name_the_arms_own_width(backend):
    arm = SerialRobot.load("puma560", backend=backend)
    for call in (arm.fk, arm.jacobian, arm.frames, arm.singularities, arm.within_limits):
        for bad in (0.5, np.zeros(3), np.zeros((2, 4))):
            with pytest.raises(InputError) as info:
                call(bad)
            text = str(info.value)
            assert "(..., 6)" in text and "3 or 4" not in text, text
    with pytest.raises(InputError, match=r"\(\.\.\., 4, 4\)"):
        arm.ik(0.5)


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_singularities_of_nan_q_raise_or_report_nan(backend):
    arm = SerialRobot.load("puma560", backend=backend)
    q = np.array([Q_PUMA, [0.1, 0.2, np.nan, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    with pytest.raises(InputError, match=r"q contains NaN or infinite values in rows \[1\]") as e:
        arm.singularities(q)
    assert e.value.rows.tolist() == [1]
    with pytest.raises(InputError):
        arm.singularities(q[1])
    rep = arm.singularities(q, errors="nan")
    assert rep["valid"].tolist() == [True, False, True]
    assert not rep["singular"][1] and np.isnan(rep["condition"][1])
    alone = arm.singularities(q[[0, 2]])  # the finite rows' report is unchanged
    np.testing.assert_array_equal(rep["singular"][[0, 2]], alone["singular"])
    np.testing.assert_allclose(rep["sigma_min"][[0, 2]], alone["sigma_min"])
    # q5 = 0 puts the Puma's wrist axes 4 and 6 in line: singular, not a NaN artefact
    assert alone["wrist"][1]


def _all_error_classes():
    from deltagen.apps.plotting import PlottingUnavailable
    from deltagen.native.build import BuildError
    from deltagen.plan.following import TrajectoryError

    return [
        DeltagenError,
        GeometryError,
        KinematicsError,
        UnreachableError,
        SingularityError,
        InputError,
        BuildError,
        TrajectoryError,
        PlottingUnavailable,
    ]


@pytest.mark.parametrize("cls", _all_error_classes(), ids=lambda c: c.__name__)
def test_every_error_class_carries_rows(cls):
    plain = cls("a message")
    assert plain.rows.dtype == np.intp and plain.rows.tolist() == []
    assert str(plain) == "a message"
    with_rows = cls("a message", [3, 5])
    assert with_rows.rows.tolist() == [3, 5]


def test_errors_from_single_pose_paths_carry_rows():
    robot = DeltaRobot.default()
    with pytest.raises(UnreachableError) as info:
        robot.ik([0.0, 0.0, -5.0])
    assert info.value.rows.tolist() == [0]
    with pytest.raises(InputError) as info:
        robot.fk([0.1, np.nan, 0.0])
    assert info.value.rows.tolist() == [0]
    arm = SerialRobot.load("puma560")
    arm.ik(arm.fk(Q_PUMA))
    with pytest.raises(InputError) as info:
        arm.fk([0.1, np.nan, 0.0, 0.0, 0.0, 0.0])
    assert info.value.rows.tolist() == [0]
    with pytest.raises(UnreachableError) as info:
        arm.ik(_far())
    assert info.value.rows.tolist() == [0]


@pytest.mark.parametrize("backend", ["compiled", "reference"])
@pytest.mark.parametrize(
    "call",
    [
        lambda r: r.ik([1e155, 0.0, -1.0]),
        lambda r: r.ik([0.0, 0.0, -1e155]),
        lambda r: r.ik_vel([0.0, 0.0, -0.9], [1e308, 1e308, 0.0]),
    ],
    ids=["ik far x", "ik far z", "ik_vel huge rate"],
)
def test_delta_non_finite_result_is_never_valid_on_any_path(backend, call):
    """Huge finite inputs overflow inside the kernels: whatever status the kernel gives,
    the API never returns a non-finite value as valid, single pose or batch."""
    robot = DeltaRobot.default(backend=backend)
    kinds = set()
    for wrap in (lambda v: v, lambda v: [v], lambda v: np.array([v, [0.0, 0.0, -0.9]])):

        class Wrapped:
            def __getattr__(self, name, _wrap=wrap):
                method = getattr(robot, name)
                return lambda *args, **kw: method(*(_wrap(a) for a in args), **kw)

        with pytest.raises(DeltagenError) as info:
            call(Wrapped())
        assert 0 in info.value.rows and 1 not in info.value.rows
        kinds.add(type(info.value))
        result = call(_NanMode(Wrapped()))
        ok = result[-1]
        assert not np.asarray(ok).reshape(-1)[0]
        for out in result[:-1]:
            assert np.isnan(np.asarray(out).reshape(-1, 3)[0]).all()
    assert len(kinds) == 1


class _NanMode:
    def __init__(self, robot):
        self._robot = robot

    def __getattr__(self, name):
        method = getattr(self._robot, name)
        return lambda *args, **kw: method(*args, errors="nan", **kw)
