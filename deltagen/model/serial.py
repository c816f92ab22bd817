"""Serial-arm descriptions: standard DH, modified DH (Craig) and universal coordinates.

Conventions (lecture slides 80-89, EASY-ROB paper eqs. (1)-(3)):

* ``standard``  A_i = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i); joint i moves
  theta_i (revolute) or d_i (prismatic) about / along z_{i-1}.
* ``modified``  A_i = Rot_x(alpha_{i-1}) Trans_x(a_{i-1}) Rot_z(theta_i) Trans_z(d_i) (Craig);
  a row's ``a`` and ``alpha`` are those of the link before the joint.
* ``universal`` D_i = Rot_i(q_i) Trans_x(tx) Trans_y(ty) Trans_z(tz) Rot_x(rx) Rot_y(ry) Rot_z(rz)
  with Rot_i the joint's own motion about (or along) its ``axis`` x, y or z (paper eq. (3)).

T(q) = base . A_1(q_1) ... A_n(q_n) . tool. The joint variable enters as q_i + offset_i, or
as -q_i + offset_i for a reversed joint (``flip = true`` / ``sign = -1``, in every convention:
the joint turns or slides the other way, as roboticstoolbox's Jaco/Mico models need).
Lengths in metres, angles in radians; robot files may use ``*_deg`` keys instead.

Robot files (TOML) state the convention explicitly; there is no default::

    name = "my_arm"
    convention = "standard"          # "standard" | "modified" | "universal"
    [base]                           # optional: xyz [m], rpy or rpy_deg = [roll, pitch, yaw]
    xyz = [0, 0, 0.1]
    [tool]                           # optional, same keys
    xyz = [0, 0, 0.05]
    [[joint]]                        # one table per joint, base to tool
    type = "revolute"                # or "prismatic"
    a = 0.0                          # DH keys: a, alpha|alpha_deg, d, theta|theta_deg, offset|offset_deg
    alpha_deg = 90
    d = 0.67183
    qlim_deg = [-160, 160]           # optional; qlim = [...] in rad (m for prismatic)
    flip = false                     # optional; true (or sign = -1): the joint turns / slides
                                     # the other way, its variable enters as -q + offset
    [configurations]                 # optional named joint vectors (rad / m)
    qz = [0, 0, 0, 0, 0, 0]

Universal-coordinate joints use tx, ty, tz [m], rx|rx_deg, ry|ry_deg, rz|rz_deg, axis
("x" | "y" | "z") and offset.

Inertial parameters (for the dynamics; optional, but all or nothing: once one ``[[joint]]``
table has a ``mass``, every table must have one). Each ``[[joint]]`` table describes joint i
and the link i it drives::

    mass = 17.4                      # [kg], >= 0
    com = [-0.3638, 0.006, 0.2275]   # centre of mass in link frame i [m] (default 0)
    inertia = [0.13, 0.524, 0.539, 0, 0, 0]
                                     # about the COM, axes of link frame i [kg m^2]:
                                     # Ixx Iyy Izz Ixy Ixz Iyz (default 0; positive
                                     # semidefinite. The triangle inequalities are not
                                     # enforced: published sets such as the Puma's link 1,
                                     # a massless link with inertia, violate them)
    armature = 1.2                   # motor inertia reflected to the joint, Jm G^2
                                     # [kg m^2 or kg] (default 0)
    viscous = 2.3                    # viscous friction B at the joint [N m s/rad | N s/m]
    coulomb = [3.0, -4.0]            # Coulomb friction at the joint [N m | N]: [Tc+, Tc-]
                                     # (Tc+ >= 0 acts for qd > 0, Tc- <= 0 for qd < 0;
                                     # one number c means [c, -c]); none at qd = 0

and the top level may give ``gravity = [0, 0, -9.81]`` [m/s^2] in the base frame (the
default). Joint torque tau_i = (rigid-body torque) + armature_i qdd_i + viscous_i qd_i +
(Tc+_i if qd_i > 0, Tc-_i if qd_i < 0, else 0).

Link frame i, in which com and inertia are expressed, is the frame after A_i (D_i) in every
convention: standard DH frame i (its origin at the far end of link i, z_i the axis of joint
i+1; the joint's own axis z_{i-1} is not in it), modified DH frame i (origin and z_i on joint
i's own axis), universal coordinates frame base D_1 ... D_i. The inertials of a URDF link
are in its link frame, which is the modified-DH kind of frame.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from deltagen.errors import GeometryError
from deltagen.geometry.rotations import matrix_from_rpy, rot_axis
from deltagen.model.naming import check_identifier
from deltagen.model.robot_file import RobotFile, real

CONVENTIONS = ("standard", "modified", "universal")
JOINT_TYPES = ("revolute", "prismatic")
_DH_LENGTHS: tuple[str, ...] = ("a", "d")
_DH_ANGLES: tuple[str, ...] = ("alpha", "theta", "offset")
_UC_LENGTHS: tuple[str, ...] = ("tx", "ty", "tz")
_UC_ANGLES: tuple[str, ...] = ("rx", "ry", "rz", "offset")


@dataclass(frozen=True)
class Joint:
    """One joint and the link it drives. Unused fields of the other conventions stay 0."""

    type: str = "revolute"
    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    offset: float = 0.0
    tx: float = 0.0
    ty: float = 0.0
    tz: float = 0.0
    rx: float = 0.0
    ry: float = 0.0
    rz: float = 0.0
    axis: str = "z"
    sign: float = 1.0  # +1, or -1 for a reversed joint: the variable enters as sign q + offset
    qlim: tuple[float, float] | None = None
    name: str = ""
    inertial: Inertial | None = None

    @property
    def revolute(self) -> bool:
        return self.type == "revolute"


@dataclass(frozen=True)
class Inertial:
    """Inertial parameters of link i and the drive of joint i (module docstring): mass [kg],
    com (3,) in link frame i [m], inertia (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) about the COM in the
    axes of link frame i [kg m^2], armature (reflected motor inertia Jm G^2), viscous
    friction, Coulomb friction (Tc+, Tc-) at the joint."""

    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, float, float, float, float, float] = (0.0,) * 6
    armature: float = 0.0
    viscous: float = 0.0
    coulomb: tuple[float, float] = (0.0, 0.0)

    @property
    def inertia_matrix(self) -> npt.NDArray[np.float64]:
        """3x3 inertia tensor about the COM in link frame i."""
        xx, yy, zz, xy, xz, yz = self.inertia
        return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])

    def key(self) -> tuple:
        return (self.mass, self.com, self.inertia, self.armature, self.viscous, self.coulomb)


INERTIAL_KEYS = ("mass", "com", "inertia", "armature", "viscous", "coulomb")
DEFAULT_GRAVITY = (0.0, 0.0, -9.81)


def transform(
    xyz: Sequence[float] = (0.0, 0.0, 0.0), rpy: Sequence[float] = (0.0, 0.0, 0.0)
) -> npt.NDArray[np.float64]:
    """4x4 homogeneous transform: translation xyz, rotation Rz(yaw) Ry(pitch) Rx(roll)."""
    T = np.eye(4)
    T[:3, :3] = matrix_from_rpy(rpy)
    T[:3, 3] = xyz
    return T


@dataclass(frozen=True)
class SerialDescription(RobotFile):
    name: str
    convention: str
    joints: tuple[Joint, ...]
    base: npt.NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    tool: npt.NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    configurations: dict[str, tuple[float, ...]] = field(default_factory=dict)
    doc: str = ""
    gravity: tuple[float, float, float] = DEFAULT_GRAVITY

    def __post_init__(self) -> None:
        check_identifier(self.name)
        given = [j.inertial is not None for j in self.joints]
        if any(given) and not all(given):
            missing = [str(i + 1) for i, g in enumerate(given) if not g]
            raise GeometryError(
                f"inertial parameters are all or nothing: joints {', '.join(missing)} have "
                "no mass (give mass = 0 for a massless link)"
            )
        g = tuple(float(v) for v in self.gravity)
        if len(g) != 3 or not all(math.isfinite(v) for v in g):
            raise GeometryError(f"gravity must be 3 finite numbers [m/s^2], got {self.gravity!r}")
        object.__setattr__(self, "gravity", g)
        if self.convention not in CONVENTIONS:
            raise GeometryError(
                f"convention must be one of {CONVENTIONS} (stated explicitly), got {self.convention!r}"
            )
        if not self.joints:
            raise GeometryError(f"robot {self.name!r} has no joints")
        for which in ("base", "tool"):
            M = np.asarray(getattr(self, which), dtype=float)
            if M.shape != (4, 4) or not np.all(np.isfinite(M)):
                raise GeometryError(f"{which} must be a finite 4x4 homogeneous transform")
            R = M[:3, :3]
            if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or not np.allclose(
                M[3], [0, 0, 0, 1]
            ):
                raise GeometryError(
                    f"{which} is not a rigid transform (rotation part not orthonormal)"
                )
            object.__setattr__(self, which, M.copy())
        n = len(self.joints)
        for key, q in self.configurations.items():
            check_identifier(key, "configuration name")
            if len(q) != n:
                raise GeometryError(
                    f"configuration {key!r} has {len(q)} values, the arm has {n} joints"
                )

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def has_inertia(self) -> bool:
        """True when the description carries inertial parameters (every joint has them)."""
        return self.joints[0].inertial is not None

    def require_inertia(self) -> None:
        """Raise a clear error when the dynamics are asked of an arm without inertials."""
        if not self.has_inertia:
            raise GeometryError(
                f"robot {self.name!r} has no inertial parameters: its robot file gives no "
                "mass/com/inertia in its [[joint]] tables (see deltagen.model.serial), so "
                "it has no dynamics"
            )

    def without_inertia(self) -> SerialDescription:
        """The same arm without inertial parameters: its kinematics alone (what the compiled
        backend builds first, so that an arm's first use waits for no dynamics)."""
        from dataclasses import replace

        if not self.has_inertia:
            return self
        return replace(self, joints=tuple(replace(j, inertial=None) for j in self.joints))

    def without_friction(self) -> SerialDescription:
        """The same arm with viscous and Coulomb friction set to zero."""
        from dataclasses import replace

        if not self.has_inertia:
            return self
        joints = tuple(
            replace(j, inertial=replace(j.inertial, viscous=0.0, coulomb=(0.0, 0.0)))
            for j in self.joints
            if j.inertial is not None
        )
        return replace(self, joints=joints)

    @property
    def qlim(self) -> npt.NDArray[np.float64]:
        """(n, 2) joint limits; +-inf where a joint has none."""
        lim = np.tile([-np.inf, np.inf], (self.n, 1))
        for i, j in enumerate(self.joints):
            if j.qlim is not None:
                lim[i] = j.qlim
        return lim

    def key(self) -> str:
        """A canonical text of everything that determines the generated code."""
        parts = [self.name, self.convention]
        for j in self.joints:
            parts.append(
                repr(
                    (
                        j.type,
                        j.a,
                        j.alpha,
                        j.d,
                        j.theta,
                        j.offset,
                        j.tx,
                        j.ty,
                        j.tz,
                        j.rx,
                        j.ry,
                        j.rz,
                        j.axis,
                        *(() if j.sign == 1.0 else ("flip",)),  # unflipped arms keep their key
                        # the closed-form ik_all checks the limits in C: two arms that
                        # differ only in limits must not share a compiled core
                        None if j.qlim is None else tuple(float(x) for x in j.qlim),
                    )
                )
            )
        parts.append(repr(self.base.tolist()))
        parts.append(repr(self.tool.tolist()))
        if self.has_inertia:  # arms without inertials keep their fingerprint
            parts.append(repr(self.gravity))
            parts.extend(repr(j.inertial.key()) for j in self.joints if j.inertial)
        return "\n".join(parts)

    # -- construction ---------------------------------------------------------------

    @classmethod
    def from_rows(
        cls,
        rows: Iterable[Mapping[str, Any]],
        convention: str,
        name: str = "arm",
        base: npt.ArrayLike | None = None,
        tool: npt.ArrayLike | None = None,
        configurations: Mapping[str, Sequence[float]] | None = None,
        doc: str = "",
        gravity: Sequence[float] = DEFAULT_GRAVITY,
    ) -> SerialDescription:
        if convention not in CONVENTIONS:
            raise GeometryError(
                f"convention must be one of {CONVENTIONS} (stated explicitly), got {convention!r}"
            )
        if isinstance(rows, (str, bytes)) or not hasattr(rows, "__iter__"):
            raise GeometryError("rows must be a list of joint tables")
        joints = tuple(_joint(row, convention, f"joint {i + 1}") for i, row in enumerate(rows))
        return cls(
            name=name,
            convention=convention,
            joints=joints,
            base=np.eye(4) if base is None else np.asarray(base, dtype=float),
            tool=np.eye(4) if tool is None else np.asarray(tool, dtype=float),
            configurations={
                k: tuple(real(v, f"configuration {k}") for v in q)
                for k, q in (configurations or {}).items()
            },
            doc=doc,
            gravity=_vector(gravity, 3, "gravity"),
        )

    @classmethod
    def from_mapping(
        cls, data: dict[str, Any], source: str = "robot description"
    ) -> SerialDescription:
        try:
            return cls._from_mapping(data)
        except GeometryError as exc:
            raise GeometryError(f"{source}: {exc}") from None

    @classmethod
    def _from_mapping(cls, data: dict[str, Any]) -> SerialDescription:
        if not isinstance(data, dict):
            raise GeometryError("expected a table")
        allowed = {
            "name",
            "convention",
            "base",
            "tool",
            "joint",
            "configurations",
            "doc",
            "gravity",
        }
        unknown = set(data) - allowed
        if unknown:
            raise GeometryError(f"unknown top-level keys {sorted(unknown)}")
        if "convention" not in data:
            raise GeometryError(
                'missing key "convention": state "standard", "modified" or "universal" '
                "(deltagen never guesses between standard and modified DH)"
            )
        if "joint" not in data or not isinstance(data["joint"], list):
            raise GeometryError("missing [[joint]] tables")
        configurations = data.get("configurations", {})
        if not isinstance(configurations, dict):
            raise GeometryError("[configurations] must be a table of joint vectors")
        for k, q in configurations.items():
            if not isinstance(q, list):
                raise GeometryError(f"configuration {k!r} must be a list of numbers")
        return cls.from_rows(
            data["joint"],
            data["convention"],
            name=data.get("name", "arm"),
            base=_frame(data.get("base"), "base"),
            tool=_frame(data.get("tool"), "tool"),
            configurations=configurations,
            doc=str(data.get("doc", "")),
            gravity=data.get("gravity", DEFAULT_GRAVITY),
        )


# ------------------------------------------------------------- numeric link transforms
# The description's own forward kinematics, for the structure detection of
# model/structure.py (the joint axes at q = 0 and its product-of-exponentials check). Written
# from the conventions above like the reference (reference/serial.py, which stays
# independent of the model's code): the same elementary matrices, multiplied in the same
# order, batched over N joint vectors.

_AXIS = {"x": 0, "y": 1, "z": 2}


def _rot(axis: int, angle: np.ndarray) -> np.ndarray:
    """(N, 4, 4) rotations about coordinate axis 0/1/2 by ``angle`` (N,) [rad]."""
    M = np.broadcast_to(np.eye(4), (angle.shape[0], 4, 4)).copy()
    M[:, :3, :3] = rot_axis(axis, angle)
    return M


def _trans(axis: int, dist: np.ndarray) -> np.ndarray:
    """(N, 4, 4) translations along coordinate axis 0/1/2 by ``dist`` (N,) [m]."""
    M = np.broadcast_to(np.eye(4), (dist.shape[0], 4, 4)).copy()
    M[:, axis, 3] = dist
    return M


def link_transform(desc: SerialDescription, i: int, qi: Any) -> np.ndarray:
    """A_i(q_i) (N, 4, 4) of joint i (0-based) for joint values qi (N,) per the description's
    convention (module docstring); the joint variable enters as q_i + offset_i."""
    j = desc.joints[i]
    qi = np.asarray(qi, dtype=np.float64)
    var = j.sign * qi + j.offset
    const = np.full(qi.shape[0], 0.0)
    if desc.convention == "universal":
        ax = _AXIS[j.axis]
        mats = [
            _rot(ax, var) if j.revolute else _trans(ax, var),
            _trans(0, const + j.tx),
            _trans(1, const + j.ty),
            _trans(2, const + j.tz),
            _rot(0, const + j.rx),
            _rot(1, const + j.ry),
            _rot(2, const + j.rz),
        ]
    else:
        theta = var if j.revolute else const + j.theta
        d = const + j.d if j.revolute else var
        if desc.convention == "standard":
            mats = [_rot(2, theta), _trans(2, d), _trans(0, const + j.a), _rot(0, const + j.alpha)]
        else:  # modified
            mats = [_rot(0, const + j.alpha), _trans(0, const + j.a), _rot(2, theta), _trans(2, d)]
    out = mats[0]
    for M in mats[1:]:
        out = np.matmul(out, M)
    return out


def frames(desc: SerialDescription, q: Any) -> np.ndarray:
    """F (N, n+2, 4, 4) for finite joint vectors q (N, n): F[:, 0] = base,
    F[:, i] = base A_1 ... A_i, F[:, n+1] = F[:, n] tool (the tool pose)."""
    q = np.asarray(q, dtype=np.float64)
    N, n = q.shape
    F = np.empty((N, n + 2, 4, 4))
    F[:, 0] = desc.base
    for i in range(n):
        F[:, i + 1] = np.matmul(F[:, i], link_transform(desc, i, q[:, i]))
    F[:, n + 1] = np.matmul(F[:, n], desc.tool)
    return F


def axis_frame(desc: SerialDescription, i: int) -> tuple[int, int]:
    """(index into :func:`frames`' F, column) of the frame whose column is joint i's motion
    axis and whose origin lies on it: standard DH z of frame i-1 (F[:, i]); modified DH z of
    frame i (F[:, i+1]: for a revolute joint that origin is fixed in link i-1, since d_i is
    constant); universal the joint's ``axis`` of base D_1 ... D_{i-1} (F[:, i]). A reversed
    joint (``sign`` -1) moves about / along minus that column."""
    if desc.convention == "standard":
        return i, 2
    if desc.convention == "modified":
        return i + 1, 2
    return i, _AXIS[desc.joints[i].axis]


def _angle(row, key, where, required=False):
    """Value of ``key`` (rad) or ``key_deg`` (deg), never both."""
    has_rad, has_deg = key in row, f"{key}_deg" in row
    if has_rad and has_deg:
        raise GeometryError(f"{where}: give {key} (rad) or {key}_deg (deg), not both")
    if has_deg:
        return math.radians(real(row[f"{key}_deg"], f"{where}: {key}_deg"))
    if has_rad:
        return real(row[key], f"{where}: {key}")
    if required:
        raise GeometryError(f"{where}: missing key {key} (or {key}_deg)")
    return 0.0


def _joint(row: object, convention: str, where: str) -> Joint:
    if not isinstance(row, dict):
        raise GeometryError(f"{where}: expected a table of joint parameters")
    kind = row.get("type", row.get("joint", "revolute"))
    if "type" in row and "joint" in row:
        raise GeometryError(f"{where}: give the joint type once (type or joint)")
    if kind not in JOINT_TYPES:
        raise GeometryError(f"{where}: unknown joint type {kind!r}; use 'revolute' or 'prismatic'")
    if convention == "universal":
        lengths, angles = _UC_LENGTHS, _UC_ANGLES
        extra = {"axis"}
    else:
        lengths, angles = _DH_LENGTHS, _DH_ANGLES
        extra = set()
    prismatic = kind == "prismatic"
    allowed = (
        set(lengths)
        | set(angles)
        | {f"{a}_deg" for a in angles}
        | extra
        | {"type", "joint", "qlim", "qlim_deg", "name", "flip", "sign"}
        | set(INERTIAL_KEYS)
    )
    unknown = set(row) - allowed
    if unknown:
        hint = ""
        if unknown & {"tx", "ty", "tz", "rx", "ry", "rz", "axis", "a", "alpha", "d", "theta"}:
            hint = f" (keys of another convention; this file says {convention!r})"
        raise GeometryError(f"{where}: unknown keys {sorted(unknown)}{hint}")
    values: dict[str, Any] = {k: real(row[k], f"{where}: {k}") for k in lengths if k in row}
    for k in angles:
        values[k] = _angle(row, k, where)
    if convention != "universal":
        if not prismatic and ("theta" in row or "theta_deg" in row):
            raise GeometryError(f"{where}: a revolute joint's theta is its variable; use offset")
        if prismatic and "d" in row:
            raise GeometryError(f"{where}: a prismatic joint's d is its variable; use offset")
    else:
        axis = row.get("axis", None)
        if axis not in ("x", "y", "z"):
            raise GeometryError(f"{where}: axis must be 'x', 'y' or 'z', got {axis!r}")
        values["axis"] = axis
    qlim = None
    if "qlim" in row or "qlim_deg" in row:
        if "qlim" in row and "qlim_deg" in row:
            raise GeometryError(f"{where}: give qlim or qlim_deg, not both")
        raw = row.get("qlim", row.get("qlim_deg"))
        if not isinstance(raw, (list, tuple)) or len(raw) != 2:
            raise GeometryError(f"{where}: qlim must be [lower, upper]")
        lo, hi = (real(v, f"{where}: qlim") for v in raw)
        if "qlim_deg" in row:
            if prismatic:
                raise GeometryError(f"{where}: qlim_deg on a prismatic joint (use qlim in m)")
            lo, hi = math.radians(lo), math.radians(hi)
        if not lo < hi:
            raise GeometryError(f"{where}: qlim lower {lo!r} must be below upper {hi!r}")
        qlim = (lo, hi)
    name = row.get("name", "")
    if not isinstance(name, str):
        raise GeometryError(f"{where}: name must be text")
    return Joint(
        type=kind,
        qlim=qlim,
        name=name,
        sign=_sign(row, where),
        inertial=_inertial(row, where),
        **values,
    )


def _sign(row: Mapping[str, Any], where: str) -> float:
    """The joint's direction: ``flip = true`` or ``sign = -1`` reverse it (the joint turns /
    slides the other way: its variable enters as -q + offset); default +1."""
    if "flip" in row and "sign" in row:
        raise GeometryError(f"{where}: give flip or sign, not both")
    if "flip" in row:
        if not isinstance(row["flip"], bool):
            raise GeometryError(f"{where}: flip must be true or false, got {row['flip']!r}")
        return -1.0 if row["flip"] else 1.0
    if "sign" in row:
        raw = row["sign"]
        if isinstance(raw, bool) or raw not in (1, -1):
            raise GeometryError(f"{where}: sign must be 1 or -1, got {raw!r}")
        return float(raw)
    return 1.0


def _vector(raw: Any, size: int, where: str) -> tuple:
    if isinstance(raw, (str, bytes)) or not isinstance(raw, (list, tuple, np.ndarray)):
        raise GeometryError(f"{where} must be a list of {size} numbers, got {raw!r}")
    if len(raw) != size:
        raise GeometryError(f"{where} must be a list of {size} numbers, got {len(raw)}")
    return tuple(real(v, where) for v in raw)


def _inertial(row: Mapping[str, Any], where: str) -> Inertial | None:
    """The joint table's inertial parameters (module docstring), validated; None if it has
    none. A table with any inertial key must give mass."""
    keys = [k for k in INERTIAL_KEYS if k in row]
    if not keys:
        return None
    if "mass" not in row:
        raise GeometryError(f"{where}: {', '.join(keys)} given without mass [kg]")
    mass = real(row["mass"], f"{where}: mass")
    if mass < 0:
        raise GeometryError(f"{where}: mass must be >= 0 kg, got {mass!r}")
    com = _vector(row.get("com", [0.0, 0.0, 0.0]), 3, f"{where}: com [m]")
    inertia = _vector(
        row.get("inertia", [0.0] * 6), 6, f"{where}: inertia [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]"
    )
    inertial = Inertial(mass=mass, com=com, inertia=inertia)
    eig = np.linalg.eigvalsh(inertial.inertia_matrix)
    scale = max(1.0, float(np.max(np.abs(inertia))))
    if eig[0] < -1e-12 * scale:
        raise GeometryError(
            f"{where}: inertia {list(inertia)} is not positive semidefinite "
            f"(smallest principal moment {eig[0]:.6g} kg m^2)"
        )
    values = {}
    for k in ("armature", "viscous"):
        v = real(row.get(k, 0.0), f"{where}: {k}")
        if v < 0:
            raise GeometryError(f"{where}: {k} must be >= 0, got {v!r}")
        values[k] = v
    raw = row.get("coulomb", 0.0)
    if isinstance(raw, (list, tuple)):
        plus, minus = _vector(raw, 2, f"{where}: coulomb [Tc+, Tc-]")
    else:
        c = real(raw, f"{where}: coulomb")
        plus, minus = c, -c
    if plus < 0 or minus > 0:
        raise GeometryError(
            f"{where}: coulomb [Tc+, Tc-] must have Tc+ >= 0 (for qd > 0) and Tc- <= 0 "
            f"(for qd < 0), got [{plus!r}, {minus!r}]"
        )
    return Inertial(
        mass=mass,
        com=com,
        inertia=inertia,
        armature=values["armature"],
        viscous=values["viscous"],
        coulomb=(plus, minus),
    )


def _frame(table, which):
    if table is None:
        return None
    if not isinstance(table, dict):
        raise GeometryError(f"[{which}] must be a table with xyz and rpy/rpy_deg")
    unknown = set(table) - {"xyz", "rpy", "rpy_deg"}
    if unknown:
        raise GeometryError(f"[{which}]: unknown keys {sorted(unknown)}")
    xyz = table.get("xyz", [0.0, 0.0, 0.0])
    if not isinstance(xyz, list) or len(xyz) != 3:
        raise GeometryError(f"[{which}] xyz must be 3 numbers")
    xyz = [real(v, f"[{which}] xyz") for v in xyz]
    if "rpy" in table and "rpy_deg" in table:
        raise GeometryError(f"[{which}]: give rpy or rpy_deg, not both")
    rpy = table.get("rpy", table.get("rpy_deg", [0.0, 0.0, 0.0]))
    if not isinstance(rpy, list) or len(rpy) != 3:
        raise GeometryError(f"[{which}] rpy must be 3 numbers [roll, pitch, yaw]")
    rpy = [real(v, f"[{which}] rpy") for v in rpy]
    if "rpy_deg" in table:
        rpy = [math.radians(v) for v in rpy]
    return transform(xyz, rpy)
