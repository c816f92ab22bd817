"""What the robot families of the API share (DeltaRobot, SerialRobot, LinearDelta, Tripod,
FiveAxisMachine, Hexapod): the backend and ``threads`` checks, the class methods that read
a robot file or take the family's default model, the shaping of a batched kernel's outputs
by the ``errors`` mode (``_finish``) and the adapter that gives a numpy reference module the
compiled core's call signatures (``ReferenceCore``). Each family's methods try their one-pose
lean path first, written out in the method (an attribute test and a call: a shared helper
cost one more Python call per pose, +25-30 % of a delta fk of one pose)."""

from __future__ import annotations

from functools import partial
from typing import Any, ClassVar, Self

import numpy as np

from deltagen import status as st
from deltagen.api.hints import Backend, PathLike
from deltagen.api.threads import ThreadsProperty
from deltagen.api.validity import finite_rows
from deltagen.inputs import InputError
from deltagen.native.parallel import check_threads

BACKENDS = ("compiled", "reference")


class ReferenceCore:
    """A numpy reference module with the compiled core's call signatures: ``core.fk(q)``
    is ``module.fk(*model, q)`` for each name in ``calls`` (the reference functions take the
    robot's model first)."""

    def __init__(self, module: Any, model: tuple, calls: tuple[str, ...]) -> None:
        for name in calls:
            setattr(self, name, partial(getattr(module, name), *model))
        self.threads: int | None = None  # the reference is single-threaded


class RobotFamily(ThreadsProperty):
    """The base of the robot classes: a model (the family's geometry or description, in the
    attribute ``_model_attr``, of class ``_model_class``), a backend and a core."""

    _model_attr: ClassVar[str] = "geometry"
    _model_class: ClassVar[Any]
    backend: Backend

    def _check_backend(self, backend: Any, threads: int | None) -> int | None:
        """Set ``backend`` and ``threads`` after checking them; returns the checked threads."""
        if backend not in BACKENDS:
            raise InputError(f"backend must be one of {BACKENDS}, got {backend!r}")
        self._threads = check_threads(threads)
        self.backend = backend
        return self._threads

    def _init_backend(self, backend: Any, threads: int | None = None) -> None:
        raise NotImplementedError

    @classmethod
    def _from_model(cls, model: Any, backend: Backend, threads: int | None) -> Self:
        robot = cls.__new__(cls)
        setattr(robot, cls._model_attr, model)
        robot._init_backend(backend, threads)
        return robot

    @classmethod
    def from_toml(
        cls, path: PathLike, backend: Backend = "compiled", *, threads: int | None = None
    ) -> Self:
        """The robot of a robot file (the family's model class reads it: its from_toml)."""
        return cls._from_model(cls._model_class.from_toml(path), backend, threads)

    @property
    def name(self) -> str:
        """The robot's name (its model's ``name``)."""
        return getattr(self, self._model_attr).name

    def with_backend(self, backend: Backend) -> Self:
        """The same robot (same model, same threads) on the other backend."""
        return type(self)._from_model(getattr(self, self._model_attr), backend, self._threads)

    def _raise(self, status: Any, ok: Any, names: Any, inputs: Any) -> None:
        """Raise the error of the rows that are not ok (each family words its causes)."""
        raise NotImplementedError

    def _finish(
        self, errors, lead, status, outs, names, inputs, allow_singular=False, trailing=None
    ):
        """Shape the kernel's outputs (N, ...) to ``lead``. The status already applies the
        finite-output rule (deltagen/status.py: a row is OK only where every output is
        finite -- the generated C and the reference alike, tested by the fuzz tests), so the
        outputs are not read again, except the SINGULAR rows that fk and ik may return
        (``allow_singular``: a singular row with a finite value is an answer): a second
        pass over every row cost about as much as the kernel."""
        trailing = trailing or [o.shape[1:] for o in outs]
        # st.OK is 0: "every row OK" is "no status nonzero", one pass over the (N,) int8
        # status without a (N,) bool temporary (the call's serial tail after the threads)
        all_ok = not status.any()
        ok = None
        if not all_ok:
            ok = status == st.OK
            if allow_singular:  # collinear sphere centres are SINGULAR too, with no value
                singular = np.flatnonzero(status == st.SINGULAR)
                ok[singular] = finite_rows(*(o[singular] for o in outs))
            if errors == "raise" and not ok.all():
                self._raise(status, ok, names, inputs)
        shaped = [o.reshape(lead + tuple(t)) for o, t in zip(outs, trailing)]
        if errors == "nan":
            if ok is None:
                return (*shaped, np.ones(lead, dtype=bool))
            for o in outs:
                o[~ok] = np.nan
            return (*shaped, ok.reshape(lead))
        return shaped[0] if len(shaped) == 1 else tuple(shaped)


class RobotFamilyWithDefault(RobotFamily):
    """A family whose model class has a default robot (DeltaRobot, LinearDelta, Tripod)."""

    @classmethod
    def default(cls, backend: Backend = "compiled", *, threads: int | None = None) -> Self:
        """The family's default robot (its model class's default(): the numbers are in
        that method's docstring)."""
        return cls._from_model(cls._model_class.default(), backend, threads)
