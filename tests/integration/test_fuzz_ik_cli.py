"""Fuzzing of the inverse-kinematics surfaces and the CLI.

SerialRobot.ik / ik_all with fuzzed targets (valid poses, NaN/inf/huge/subnormal entries,
non-rigid rotations, wrong shapes and dtypes, lists) and fuzzed options (method, config,
q0, restarts, seed, errors, singular); DeltaRobot.ik with fuzzed positions; `deltagen fk|ik`
through deltagen.cli.main with fuzzed argv.

The property everywhere: a correct result -- forward kinematics of every returned valid q
reproduces the target to 1e-9, invalid rows are NaN, nothing non-finite is marked valid -- or a
deltagen error (a DeltagenError naming the problem; ``rows`` within the batch). The whole
pose is reproduced also by the arms with fewer than 6 joints: ik refuses a target they
cannot take (a tilted SCARA tool) rather than fitting it, unless mask= asks for the fit. The CLI
exits 0, 1 (computed but invalid rows) or 2 with one line naming the problem, never a
traceback. Derandomised (tests/conftest.py's "ci" profile and derandomize=True here).
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from delta_oracles import rod_residual
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as hs
from hypothesis.extra import numpy as hnp

from deltagen import DeltaRobot, SerialRobot, cli
from deltagen.errors import DeltagenError
from deltagen.geometry.rotations import matrix_from_euler_zyx

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf|nan")
FUZZ = dict(
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
ODD = [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e155, 5e-324, 1e-310, -0.0, 0.0]
FLOATS = hs.one_of(hs.sampled_from(ODD), hs.floats(-3.0, 3.0), hs.floats(allow_nan=True))
ARMS = ("puma560", "lecture_scara")


@pytest.fixture(scope="module")
def arms(serial_arms):
    return {
        (name, backend): serial_arms(name, backend)
        for name in ARMS
        for backend in ("compiled", "reference")
    }


def _in_limits(arm, u):
    """A joint vector inside the limits from numbers u in [0, 1]."""
    lim = arm.qlim
    lo, hi = np.maximum(lim[:, 0], -math.pi), np.minimum(lim[:, 1], math.pi)
    return lo + (hi - lo) * np.asarray(u)[: arm.n]


@hs.composite
def targets(draw, arm):
    """(T, kind): one pose or a batch; kind names what was done to it."""
    count = draw(hs.sampled_from([None, 1, 3]))
    rows = count or 1
    U = draw(hnp.arrays(np.float64, (rows, 6), elements=hs.floats(0.05, 0.95)))
    T = arm.with_backend("reference").fk(np.array([_in_limits(arm, u) for u in U]))
    kind = draw(
        hs.sampled_from(
            ["valid", "entry", "scaled", "tilted", "far", "shape", "dtype", "list", "empty"]
        )
    )
    row = draw(hs.integers(0, rows - 1))
    if kind == "entry":  # one entry replaced, anywhere (rotation, position or bottom row)
        i, j = draw(hs.integers(0, 3)), draw(hs.integers(0, 3))
        T[row, i, j] = draw(FLOATS)
    elif kind == "scaled":
        T[row, :3, :3] *= draw(hs.sampled_from([1.1, 0.5, -1.0, 1 + 1e-5, 1e155, 0.0]))
    elif kind == "tilted":
        T[row, :3, :3] = matrix_from_euler_zyx([0.0, 0.3, 0.2]) @ T[row, :3, :3]
    elif kind == "far":
        T[row, :3, 3] *= draw(hs.sampled_from([3.0, 10.0, 1e155, 1e300]))
    elif kind == "shape":
        shape = draw(hnp.array_shapes(min_dims=0, max_dims=3, max_side=5))
        return draw(hnp.arrays(np.float64, shape, elements=FLOATS)), kind
    elif kind == "dtype":
        dtype = draw(hs.sampled_from([np.float32, np.int64, np.bool_, np.complex128, "U3"]))
        return T.astype(dtype), kind
    elif kind == "list":
        value = T.tolist()
        if draw(hs.booleans()):
            value[row][0][0] = draw(hs.sampled_from([True, "1", None, 2**1100, 1]))
        return (value if count else value[0]), kind
    elif kind == "empty":
        return np.zeros((0, 4, 4)), kind
    return (T if count else T[0]), kind


OPTIONS = hs.fixed_dictionaries(
    {},
    optional={
        "method": hs.sampled_from(["auto", "analytic", "numeric", "Numeric", None, 3]),
        "config": hs.sampled_from(["elbow_up", "front_up_noflip", "nope", 1]),
        "q0": hs.sampled_from(["mid", "nan", "short", "list", "batch"]),
        "restarts": hs.sampled_from([0, 2, -1, 1.5, True]),
        "seed": hs.sampled_from([0, 7, -1, "s", None]),
        "errors": hs.sampled_from(["raise", "nan", "NaN"]),
        "singular": hs.sampled_from(["raise", "allow", "no"]),
        "max_iter": hs.sampled_from([100, 0, 1, -5]),
    },
)


def _q0(arm, how):
    mid = _in_limits(arm, np.full(6, 0.5))
    return {
        "mid": mid,
        "nan": np.full(arm.n, np.nan),
        "short": mid[:-1],
        "list": [float(x) for x in mid],
        "batch": np.stack([mid, mid]),
    }[how]


def _reproduces(arm, q, T, atol=1e-9):
    """fk(q) reproduces the whole target T to ``atol`` (also for the arms with fewer than 6
    joints: ik refuses what they cannot take instead of fitting it, unless mask= is given)."""
    Tq = arm.with_backend("reference").fk(q)
    return np.allclose(Tq, T, rtol=0, atol=atol)


def _check_error(exc, n_rows):
    """A deltagen error with a message; its rows (if any) inside a batch of n_rows."""
    assert isinstance(exc, DeltagenError), repr(exc)
    assert str(exc).strip()
    rows = exc.rows
    assert rows.dtype == np.intp
    if rows.size:
        assert rows.min() >= 0 and rows.max() < max(n_rows, 1)
        assert "rows [" in str(exc)


def _pose_rows(T):
    shape = np.shape(T)
    return int(np.prod(shape[:-2])) if len(shape) >= 2 else 1


@settings(max_examples=120, **FUZZ)
@given(data=hs.data())
def test_fuzz_serial_ik(arms, data):
    name = data.draw(hs.sampled_from(ARMS))
    backend = data.draw(hs.sampled_from(["compiled", "reference"]))
    arm = arms[(name, backend)]
    T, kind = data.draw(targets(arm))
    options = data.draw(OPTIONS)
    if "q0" in options:
        options["q0"] = _q0(arm, options["q0"])
    if options.get("method") == "numeric" and backend == "reference":
        options.setdefault("max_iter", 100)  # keep the numpy engine's failures short
    try:
        result = arm.ik(T, **options)
    except Exception as exc:  # noqa: BLE001 - the property is about which exceptions
        _check_error(exc, _pose_rows(T))
        event(f"{kind}: {type(exc).__name__}")
        return
    event(f"{kind}: solved")
    Ta = np.asarray(T, dtype=float)
    atol = 1e-6 if np.asarray(T).dtype == np.float32 else 1e-9  # as in test_fuzz_serial_ik_all
    if options.get("errors", "raise") == "nan":
        q, ok = result
        assert q.shape == Ta.shape[:-2] + (arm.n,) and ok.shape == Ta.shape[:-2]
        assert np.all(np.isfinite(q[ok])) and np.all(np.isnan(q[~ok]))
        if np.any(ok):
            assert _reproduces(arm, q[ok], Ta[ok], atol), (kind, options)
    else:
        q = result
        assert q.shape == Ta.shape[:-2] + (arm.n,)
        assert np.all(np.isfinite(q))
        assert _reproduces(arm, q, Ta, atol), (kind, options)
    assert kind not in ("shape", "dtype") or Ta.shape[-2:] == (4, 4)


@settings(max_examples=80, **FUZZ)
@given(data=hs.data())
def test_fuzz_serial_ik_all(arms, data):
    name = data.draw(hs.sampled_from(ARMS))
    backend = data.draw(hs.sampled_from(["compiled", "reference"]))
    arm = arms[(name, backend)]
    T, kind = data.draw(targets(arm))
    try:
        q, valid = arm.ik_all(T)
    except Exception as exc:  # noqa: BLE001
        _check_error(exc, _pose_rows(T))
        assert kind in ("shape", "dtype", "list"), (kind, exc)
        return
    Ta = np.asarray(T, dtype=float)
    k = len(arm.analytic_configs())
    assert q.shape == Ta.shape[:-2] + (k, arm.n) and valid.shape == Ta.shape[:-2] + (k,)
    assert np.all(np.isfinite(q[valid]))
    if np.any(valid):
        Tk = np.broadcast_to(Ta[..., None, :, :], valid.shape + (4, 4))
        # a float32 target is a pose rounded to 6e-8 relative: an arm with fewer than 6
        # joints reaches it only to that (SCARA: 2.6e-8 m on a 4 m pose), within ik_all's
        # tolerance for the components it cannot set
        float32 = np.asarray(T).dtype == np.float32
        assert _reproduces(arm, q[valid], Tk[valid], 1e-6 if float32 else 1e-9), kind
    if kind in ("scaled", "entry"):  # a non-rigid or non-finite row has no valid branch
        flat = Ta.reshape(-1, 4, 4)
        R = flat[:, :3, :3]
        with np.errstate(all="ignore"):
            rigid = np.all(np.isfinite(flat), axis=(1, 2)) & np.all(
                np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)) < 1e-6, axis=(1, 2)
            )
            rigid &= np.all(np.abs(flat[:, 3] - [0, 0, 0, 1]) < 1e-12, axis=1)
        assert not np.any(valid.reshape(-1, k)[~rigid])


@settings(max_examples=120, **FUZZ)
@given(
    p=hs.one_of(
        hnp.arrays(
            hs.sampled_from([np.float64, np.float32, np.int64, np.bool_, np.complex128]),
            hnp.array_shapes(min_dims=0, max_dims=3, max_side=4),
            elements=None,
        ),
        hs.lists(hs.one_of(FLOATS, hs.sampled_from([True, None, "x", 10**400])), max_size=5),
        hnp.arrays(np.float64, hs.sampled_from([(3,), (2, 3), (4,), (2, 4)]), elements=FLOATS),
        hnp.arrays(
            np.float64, hs.sampled_from([(3,), (5, 3), (2, 4)]), elements=hs.floats(-1.2, 1.2)
        ),
    ),
    backend=hs.sampled_from(["compiled", "reference"]),
    errors=hs.sampled_from(["raise", "nan"]),
)
def test_fuzz_delta_ik(p, backend, errors):
    robot = DeltaRobot.default(backend=backend)
    try:
        result = robot.ik(p, errors=errors)
    except Exception as exc:  # noqa: BLE001
        _check_error(exc, int(np.prod(np.shape(p)[:-1])) if np.ndim(p) else 1)
        return
    q, ok = result if errors == "nan" else (result, np.ones(np.shape(result)[:-1], dtype=bool))
    pa = np.asarray(p, dtype=float)
    assert q.shape == pa.shape and ok.shape == pa.shape[:-1]
    assert np.all(np.isfinite(q[ok])) and np.all(np.isnan(q[~ok]))
    if np.any(ok):  # every rod of the returned crank angles has its length l_b at p
        geom = robot.geometry
        residual = rod_residual(geom, q[ok][..., :3], pa[ok][..., :3])
        np.testing.assert_allclose(residual, 0.0, rtol=0, atol=1e-9)


# ------------------------------------------------------------------------------- CLI

VALUE = hs.one_of(
    hs.sampled_from(
        [
            "0",
            "0.1",
            "-0.5",
            "nan",
            "inf",
            "-inf",
            "1e400",
            "1e155",
            "5e-324",
            "-0.0",
            "abc",
            "",
            "1,2",
            "--",
            "-1e-3",
        ]
    ),
    hs.floats(-2.0, 2.0).map(repr),
)
OPTION = hs.one_of(
    hs.just(["--degrees"]),
    hs.tuples(hs.just("--config"), hs.sampled_from(["qz", "qr", "elbow_up", "nope", ""])).map(list),
    hs.tuples(
        hs.just("--q0"), hs.sampled_from(["qz", "0,0,0,0,0,0", "0,0", "nan,0,0,0,0,0", "x"])
    ).map(lambda t: [f"{t[0]}={t[1]}"]),
    hs.tuples(hs.just("--method"), hs.sampled_from(["auto", "analytic", "numeric", "bogus"])).map(
        list
    ),
    hs.tuples(hs.just("--restarts"), hs.sampled_from(["0", "2", "-1", "x"])).map(list),
    hs.tuples(hs.just("--backend"), hs.sampled_from(["compiled", "reference", "gpu"])).map(list),
    hs.just(["--bogus-flag"]),
)


WIDTH = {"default": 3, "puma560": 6, "lecture_scara": 2, "no_such_robot": 3}


@hs.composite
def cli_values(draw, command, robot):
    """The values after the robot: well-formed numbers of the right count (for ik of the
    Puma: a pose it reaches, x y z psi theta phi), or fuzzed tokens."""
    how = draw(hs.sampled_from(["numbers", "pose", "tokens"]))
    if how == "tokens":
        return draw(hs.lists(VALUE, max_size=7))
    if how == "pose" and command == "ik" and robot == "puma560":
        arm = SerialRobot.load("puma560", backend="reference")
        u = draw(hnp.arrays(np.float64, 6, elements=hs.floats(0.1, 0.9)))
        return [repr(float(v)) for v in arm.pose(_in_limits(arm, u))]
    width = WIDTH[robot] if command == "fk" or robot == "default" else 6
    return draw(hs.lists(hs.floats(-1.0, 1.0).map(repr), min_size=width, max_size=width))


@settings(max_examples=100, **FUZZ)
@given(
    command=hs.sampled_from(["fk", "ik"]),
    robot=hs.sampled_from(["default", "puma560", "lecture_scara", "no_such_robot"]),
    data=hs.data(),
    options=hs.one_of(hs.just([]), hs.lists(OPTION, max_size=2)),
)
def test_fuzz_cli_argv(capsys, command, robot, data, options):
    values = data.draw(cli_values(command, robot))
    argv = [command, robot, *values] + [token for option in options for token in option]
    code = cli.main(argv)
    out, err = capsys.readouterr()
    event(f"{command} exit {code}")
    assert "Traceback" not in out + err
    assert code in (0, 1, 2), (argv, code, err)
    if code == 2:
        lines = [line for line in err.strip().splitlines() if line.strip()]
        assert lines, argv  # a message, not a silent exit
        assert lines[-1].startswith(("deltagen ", "usage:")) or "error:" in lines[-1], err
        return
    if code == 1:
        assert "no valid result" in err or "invalid" in err, err
        return
    numbers = [float(v) for v in NUMBER.findall(out)]
    assert numbers and all(math.isfinite(v) for v in numbers), out
    if command == "ik" and robot == "puma560" and "--degrees" not in argv:
        # the printed q (12 significant digits) reaches the pose x y z psi theta phi given
        q = [float(v) for v in NUMBER.findall(out.split("[", 1)[1].split("]", 1)[0])]
        arm = SerialRobot.load("puma560", backend="reference")
        pose = [float(v) for v in values]
        T = arm.fk(np.array(q))
        np.testing.assert_allclose(T[:3, 3], pose[:3], rtol=0, atol=1e-8)
        np.testing.assert_allclose(T[:3, :3], matrix_from_euler_zyx(pose[3:]), atol=1e-8)
