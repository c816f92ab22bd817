"""Input handling of every batched method: bad types, shapes and values get a clear
InputError (a ValueError) that names the problem; any real dtype and memory layout is
accepted and gives the same numbers as C-contiguous float64."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import BACKENDS, DELTA_METHODS, args_for, as_tuple, call

from deltagen import DeltaRobot, InputError


@pytest.fixture(scope="module", params=BACKENDS)
def any_robot(request):
    return DeltaRobot.default(backend=request.param)


def _replace(args, index, value):
    args = list(args)
    args[index] = value
    return args


ALL = list(DELTA_METHODS)


# ------------------------------------------------------------------------ non-numeric


NON_NUMERIC = {
    "strings": ["a", "b", "c"],
    "numeric strings": np.array(["0.1", "0.2", "0.3"]),
    "bytes": np.array([b"1", b"2", b"3"]),
    "objects": [object(), object(), object()],
    "mixed objects": np.array([0.1, "x", 0.3], dtype=object),
    "None": None,
    "dict": {"q1": 0.1},
    "complex": np.array([0.1 + 0j, 0.2, 0.3]),
    "complex list": [0.1, 0.2j, 0.3],
    "complex objects": np.array([0.1, 1j, 0.3], dtype=object),
    "ragged": [[0.1, 0.2, 0.3], [0.1, 0.2]],
    "datetime": np.array(["2024-01-01"] * 3, dtype="datetime64[D]"),
    "string": "0.1 0.2 0.3",
}


@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("kind", list(NON_NUMERIC))
def test_non_numeric_input_is_rejected(any_robot, method, kind):
    args = args_for(method, (), 3)
    for position in range(len(args)):
        if kind == "None" and method == "ik_acc" and position == 2:
            continue  # see test_ik_acc_with_none_acceleration_is_rejected
        bad = _replace(args, position, NON_NUMERIC[kind])
        with pytest.raises(InputError) as info:
            call(any_robot, method, bad)
        assert isinstance(info.value, ValueError)
        message = str(info.value)
        assert any(w in message for w in ("numeric", "number", "dtype", "shape")), message
        with pytest.raises(InputError):
            call(any_robot, method, bad, errors="nan")


def test_strings_in_object_arrays_are_rejected(default_robot):
    with pytest.raises(InputError):
        default_robot.fk(np.array(["0.1", "0.2", "0.3"], dtype=object))


def test_ik_acc_with_none_acceleration_is_rejected(default_robot):
    with pytest.raises(InputError):
        default_robot.ik_acc([0.0, 0.0, -0.7], [0.0, 0.0, 0.1], None)


def test_non_numeric_message_names_argument_and_dtype(default_robot):
    with pytest.raises(InputError, match=r"qd.*complex"):
        default_robot.fk_vel([0.0, 0.0, 0.0], [1j, 0, 0])
    with pytest.raises(InputError, match=r"\bp\b.*numeric"):
        default_robot.ik(["x", "y", "z"])
    with pytest.raises(InputError, match=r"q .*non-numeric"):
        default_robot.fk(np.array([object(), 1.0, 2.0], dtype=object))


# ------------------------------------------------------------------------ wrong shapes


BAD_SHAPES = [(2,), (5,), (5, 2), (3, 5), (4, 1), (5, 0), (0,), (2, 3, 6), (3, 3, 2)]


@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("shape", BAD_SHAPES, ids=str)
def test_wrong_shape_is_rejected_with_the_shape(any_robot, method, shape):
    args = args_for(method, (), 3)
    for position in range(len(args)):
        bad = _replace(args, position, np.full(shape, 0.1))
        with pytest.raises(InputError) as info:
            call(any_robot, method, bad)
        message = str(info.value)
        assert str(shape) in message and "(..., 3 or 4)" in message, message


@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("scalar", [0.5, np.float64(0.5), np.array(0.5), 3])
def test_scalar_is_rejected(any_robot, method, scalar):
    args = args_for(method, (), 3)
    for position in range(len(args)):
        with pytest.raises(InputError, match=r"shape \(\.\.\., 3 or 4\)"):
            call(any_robot, method, _replace(args, position, scalar))


def test_scalar_error_message_names_its_shape(default_robot):
    with pytest.raises(InputError, match=r"got \(\)"):
        default_robot.fk(0.5)


@pytest.mark.parametrize("method", [m for m in ALL if DELTA_METHODS[m][0] > 1])
def test_arguments_must_agree_in_width_and_broadcast(any_robot, method):
    args = args_for(method, (5,), 3)
    wide = args_for(method, (5,), 4)
    with pytest.raises(InputError, match="same number of columns"):
        call(any_robot, method, [args[0], wide[1]] + args[2:])
    with pytest.raises(InputError, match="do not broadcast") as info:
        call(any_robot, method, [args[0], args[1][:4]] + args[2:])
    assert "(5, 3)" in str(info.value) and "(4, 3)" in str(info.value)


# -------------------------------------------------------------------------- NaN / inf


@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
def test_non_finite_rows_are_named_or_masked(any_robot, method, bad):
    n_args = DELTA_METHODS[method][0]
    for position in range(n_args):
        args = args_for(method, (6,), 3)
        args[position][1, 0] = bad
        args[position][4, 2] = bad
        with pytest.raises(InputError) as info:
            call(any_robot, method, args)
        message = str(info.value)
        assert "[1, 4]" in message and ("NaN" in message or "infinite" in message), message
        out = call(any_robot, method, args, errors="nan")
        valid = out[-1]
        np.testing.assert_array_equal(valid, [True, False, True, True, False, True])
        clean = as_tuple(call(any_robot, method, [a[valid] for a in args]))
        for o, c in zip(out[:-1], clean):
            assert np.all(np.isnan(o[~valid]))
            np.testing.assert_allclose(o[valid], c, rtol=0, atol=1e-14)


def test_nan_in_the_fourth_axis_column_through_the_api_reference(default_reference_robot):
    robot = default_reference_robot
    with pytest.raises(InputError, match=r"\[1\]"):
        robot.fk([[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, np.nan]])
    p, valid = robot.ik([[0.0, 0.0, -0.7, np.inf], [0.0, 0.0, -0.7, 1.0]], errors="nan")
    np.testing.assert_array_equal(valid, [False, True])


@pytest.mark.parametrize("method", ["fk", "fk_vel", "fk_acc", "ik", "ik_vel", "ik_acc"])
def test_nan_in_the_fourth_axis_column_through_the_api_compiled(default_robot, method):
    """A non-finite phi makes the row invalid like any other non-finite input."""
    args = args_for(method, (3,), 4)
    args[-1][2, 3] = np.nan
    with pytest.raises(InputError, match=r"\[2\]"):
        call(default_robot, method, args)


# ------------------------------------------------------------ dtypes and memory layouts


def _layouts(base, integers):
    """(name, value, float64 equivalent): the values of ``base`` (N, 3) in many memory
    layouts and float dtypes, and ``integers`` (N, 3, non-negative) in integer dtypes."""
    n = len(base)
    yield "list", base.tolist(), base
    yield "tuple", tuple(map(tuple, base)), base
    yield "float32", base.astype(np.float32), base.astype(np.float32).astype(float)
    yield "float16", base.astype(np.float16), base.astype(np.float16).astype(float)
    yield "longdouble", base.astype(np.longdouble), base
    yield "big-endian", base.astype(">f8"), base
    yield "object floats", base.astype(object), base
    for dtype in (np.int64, np.int32, np.int16, np.int8, np.uint8, np.uint64, ">i4"):
        yield f"integer {np.dtype(dtype).str}", integers.astype(dtype), integers.astype(float)
    yield "fortran", np.asfortranarray(base), base
    wide = np.zeros((2 * n, 7))
    wide[::2, 1:4] = base
    yield "strided slice", wide[::2, 1:4], base
    yield "negative strides", np.ascontiguousarray(base[::-1])[::-1], base
    yield "transposed view", np.ascontiguousarray(base.T).T, base
    readonly = base.copy()
    readonly.flags.writeable = False
    yield "read-only", readonly, base


def _integer_values(method, position, n):
    """Integer arguments that make a valid call: crank angles 0 / 1 rad, the reachable
    position (0, 0, -1) m, any rates."""
    kind = DELTA_METHODS[method][1]
    if position > 0:
        return (np.arange(3 * n).reshape(n, 3) % 4).astype(np.int64)
    if kind == "q":
        return (np.arange(3 * n).reshape(n, 3) % 2).astype(np.int64)
    return np.tile(np.array([0, 0, -1]), (n, 1))


@pytest.mark.parametrize("method", ALL)
def test_any_real_dtype_and_layout_is_accepted(any_robot, method):
    rng = np.random.default_rng(21)
    args = args_for(method, (6,), 3, rng)
    for position in range(len(args)):
        for name, value, exact in _layouts(args[position], _integer_values(method, position, 6)):
            unsigned = isinstance(value, np.ndarray) and value.dtype.kind == "u"
            if DELTA_METHODS[method][1] == "p" and position == 0 and unsigned:
                continue  # unsigned types cannot hold z = -1
            expected = as_tuple(call(any_robot, method, _replace(args, position, exact)))
            got = as_tuple(call(any_robot, method, _replace(args, position, value)))
            for g, e in zip(got, expected):
                assert g.dtype == np.float64 and g.flags.c_contiguous, name
                np.testing.assert_array_equal(g, e, err_msg=f"{method}: {name}")


def test_integer_angles_equal_float_angles(default_robot):
    np.testing.assert_array_equal(default_robot.fk([0, 0, 0]), default_robot.fk([0.0, 0.0, 0.0]))
    np.testing.assert_array_equal(
        default_robot.fk(np.zeros((4, 3), dtype=np.int16)), default_robot.fk(np.zeros((4, 3)))
    )


@pytest.mark.parametrize("method", ALL)
def test_leading_dimensions_broadcast(any_robot, method):
    rng = np.random.default_rng(5)
    args = args_for(method, (2, 5), 3, rng)
    out = as_tuple(call(any_robot, method, args))
    flat = as_tuple(call(any_robot, method, [a.reshape(10, 3) for a in args]))
    for o, f in zip(out, flat):
        assert o.shape[:2] == (2, 5)
        np.testing.assert_array_equal(o.reshape(f.shape), f)
    if len(args) > 1:
        # a single rate vector for a (2, 5) batch of poses, and a (5, 1, 3) against (2, 3)
        shared = [args[0]] + [a[0, 0] for a in args[1:]]
        out = as_tuple(call(any_robot, method, shared))
        expanded = [args[0]] + [np.broadcast_to(a[0, 0], (2, 5, 3)) for a in args[1:]]
        ref = as_tuple(call(any_robot, method, [np.array(e) for e in expanded]))
        for o, r in zip(out, ref):
            assert o.shape[:2] == (2, 5)
            np.testing.assert_array_equal(o, r)
        column = args[0][0, :2][:, None, :]  # (2, 1, 3)
        rows = [a[1, :3][None, :, :] for a in args[1:]]  # (1, 3, 3)
        out = as_tuple(call(any_robot, method, [column] + rows))
        for o in out:
            assert o.shape[:2] == (2, 3)


def test_broadcast_views_with_zero_strides(default_robot):
    q = np.broadcast_to(np.array([0.1, 0.2, 0.3]), (100, 3))
    p = default_robot.fk(q)
    assert p.shape == (100, 3) and p.flags.writeable
    # (vectorised and scalar cos/sin may differ in the last bit: compare to an ulp or two)
    np.testing.assert_allclose(p, np.tile(default_robot.fk(q[0]), (100, 1)), rtol=0, atol=1e-15)


# ----------------------------------------------------------------- keyword validation


@pytest.mark.parametrize("method", ALL)
@pytest.mark.parametrize("errors", ["ignore", "NaN", "Raise", "", None, True, 0, "coerce"])
def test_errors_keyword_is_validated(any_robot, method, errors):
    args = args_for(method, (2,), 3)
    with pytest.raises(InputError) as info:
        call(any_robot, method, args, errors=errors)
    assert "errors" in str(info.value) and '"raise"' in str(info.value)


@pytest.mark.parametrize("backend", ["fortran", "Compiled", "", None, 1, "c"])
def test_backend_keyword_is_validated(backend, tmp_path):
    robot_file = tmp_path / "r.toml"
    robot_file.write_text(
        "[delta]\nr_a = 0.2\nr_b = 0.045\nl_a = 0.35\nl_b = 0.8\ntheta_deg = [0, 120, 240]\n"
    )
    for make in (
        lambda: DeltaRobot(0.2, 0.045, 0.35, 0.8, backend=backend),
        lambda: DeltaRobot.default(backend=backend),
        lambda: DeltaRobot.from_toml(robot_file, backend=backend),
        lambda: DeltaRobot.default().with_backend(backend),
    ):
        with pytest.raises(InputError) as info:
            make()
        assert isinstance(info.value, ValueError)
        assert "backend" in str(info.value) and "compiled" in str(info.value)


def test_empty_batches(any_robot):
    for method in ALL:
        for width in (3, 4):
            args = args_for(method, (0,), width)
            out = as_tuple(call(any_robot, method, args))
            for o in out:
                assert o.shape[0] == 0
            *_, valid = call(any_robot, method, args, errors="nan")
            assert valid.shape == (0,)
        args = args_for(method, (0, 4), 3)
        for o in as_tuple(call(any_robot, method, args)):
            assert o.shape[:2] == (0, 4)
