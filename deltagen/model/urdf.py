"""URDF import: the chain from a base link to a tip link as universal coordinates.

Parsing: the standard library's ``xml.etree.ElementTree``. A URDF never needs a document type
declaration, so any ``<!DOCTYPE`` or ``<!ENTITY`` is refused before the tree is built (the
protection defusedxml gives against entity expansion, "billion laughs", and external
entities): by a look at the bytes, then by a first expat pass whose DOCTYPE and entity
handlers raise (which also sees declarations in encodings the byte look cannot read).

The chain. URDF gives each joint J an ``origin`` O_J = Trans(xyz) Rot_z(y) Rot_y(p) Rot_x(r)
(fixed-axis roll-pitch-yaw, the ``rpy`` of geometry/rotations.py) from the parent link frame
to the joint frame, and a motion M_J(q) about / along its unit ``axis`` a_J in the joint
frame; the child link frame is the joint frame moved: parent -> child = O_J M_J(q_J).
Going from ``base`` to ``tip`` through movable joints 1..n with fixed joints in between,

    T(q) = P_0 O_1 M_1(q_1) P_1 O_2 M_2(q_2) ... O_n M_n(q_n) P_n,

where P_0 is the product of the fixed joints' origins from the base link to the parent of
joint 1, P_i (0 < i < n) of those from the child of joint i to the parent of joint i+1, and
P_n of those from the child of joint n to the tip (identity where there are none).

Axes of any direction. Let R_i be a constant rotation that takes z to the unit axis,
R_i e_z = a_i (identity for +z, Rot_x(pi) for -z, else the shortest turn, Rodrigues about
e_z x a_i), and hat R_i its 4x4 homogeneous form. A turn about a_i is a turn about z seen in
the turned frame, M_i(q) = hat R_i Z(q) hat R_i^T, with Z(q) = Rot_z(q) (revolute) or
Trans_z(q) (prismatic). Substituting and regrouping the constant factors:

    T(q) = [P_0 O_1 hat R_1] Z(q_1) [hat R_1^T P_1 O_2 hat R_2] Z(q_2) ... Z(q_n) [hat R_n^T P_n]
         = base  D_1(q_1) ... D_n(q_n)  tool,

the universal-coordinate form of model/serial.py, D_i = Rot_z(q_i) C_i with axis "z" and the
constant C_i = hat R_i^T P_i O_{i+1} hat R_{i+1} (i < n), C_n = identity, base = P_0 O_1
hat R_1, tool = hat R_n^T P_n. Each C_i is written as Trans(tx, ty, tz) Rot_x(rx) Rot_y(ry)
Rot_z(rz) (the X-Y-Z angles of its rotation; at cos ry = 0 the angle rz is set to 0). The
joint variable is the URDF one: q_i = 0 where URDF's is 0, same sign, offset 0.

Inertials. Universal link frame i, U_i = base D_1 ... D_i (serial.py's frame for com and
inertia), relates to the URDF child link frame W_i of joint i by U_i = W_i G_i with
G_i = P_i O_{i+1} hat R_{i+1} (i < n) and G_n = hat R_n. The link's ``<inertial>`` gives the
mass m, the COM c and the frame of the inertia tensor, E = Trans(c) Rot(rpy), in W_i, and
I = [[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]] about the COM in E's axes. In U_i:
com = G_i^-1 c (a point), inertia = G_R^T R_E I R_E^T G_R (G_R, R_E the rotation parts).
Links attached to link i by fixed joints on the chain (the P_i part) are rigid with it: their
inertials are first carried into W_i and lumped with it (total mass, mass-weighted COM,
parallel-axis theorem about the common COM). So are the links hanging off the chain below a
moving link: the links beyond the tip and the branches (a hand, a gripper's fingers, a
sensor mount). Each is carried into W_i along its joints, a fixed joint by its origin O_J, a
movable one locked at O_J M_J(q_lock): q_lock = the caller's ``locked[name]``, else
multiplier q_lock(leader) + offset for a ``<mimic>`` (its leader must be off the chain too),
else 0 (the joint's zero; the URDFWarning names every joint so locked). This is pinocchio's
buildReducedModel with those joints locked at that configuration. The base link and the links
fixed to it (before joint 1), with whatever hangs off them, carry no joint and are ignored.
When no link of the chain has an ``<inertial>``, the description has no dynamics; when some
have one, the others get mass 0. An ``<inertial>`` is checked where its mass is used: a
defect (a negative mass, a number that is not one, an inertia that is not positive
semidefinite) in a link that does not reach the chain (above the base, on another branch,
fixed to the base) never blocks it. An inertia indefinite by the rounding of its printed
digits -- smallest principal moment negative by at most 1e-6 of the trace or 1e-9 kg m^2
(TIAGo's 1 mg antenna: -3.5e-8 kg m^2) -- is clamped (negative principal moments set to 0)
with a URDFWarning naming the link; a larger defect is an error naming it.

Gravity. The URDF's root link is the world: ``gravity`` (default (0, 0, -9.81) m/s^2) is
given in its frame, as pinocchio and the simulators read a URDF. The chain's base link may
be turned in that world (iCub's ``chest`` has its z axis horizontal), so the description
holds g_base = R^T g, R the rotation root -> base through the joints above the base: fixed
ones by their origin, movable ones locked like those off the chain (``locked``, a
``<mimic>``, else 0 with a URDFWarning naming them when the chain has inertials). The
dynamics then equal those of the whole tree with the joints outside the chain locked
(pinocchio's buildReducedModel) under the world's gravity.

Limits. ``<limit lower upper>`` becomes qlim for revolute and prismatic joints (it is
required there by the URDF specification); ``continuous`` joints are revolute without
limits. ``velocity`` and ``effort`` are read and checked as numbers but not kept: the serial
description has no place for them yet. ``<dynamics damping friction>`` maps to viscous and
Coulomb friction ([friction, -friction]). ``<mimic joint multiplier offset>`` joints are
couplings, q_j = multiplier q_i + offset (model/coupling.py): :func:`chain_from_urdf` returns
the description of every movable joint and the :class:`Coupling` to the independent ones
(the mimicked joint must be a movable joint of the chain; a mimic of a mimic is resolved;
cycles are refused). ``floating`` and ``planar`` joints are refused (a serial arm has one
variable per joint).

Range. Every number must be finite, and lengths (an origin's xyz, a prismatic joint's
limits) at most MAX_LENGTH = 1e6 m in size, masses at most MAX_MASS = 1e9 kg, inertia
entries at most MAX_INERTIA = 1e21 kg m^2: the message names the element. An axis may have
any finite length (it is scaled before it is normalised, so 1e300 is the direction x).
Trees are walked with loops, not recursion: a branch may be thousands of links long.
"""

from __future__ import annotations

import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from xml.parsers import expat

import numpy as np
import numpy.typing as npt

from deltagen.errors import GeometryError
from deltagen.geometry.rotations import matrix_from_rpy, skew, xyz_angles
from deltagen.inputs import InputError, read_regular_file
from deltagen.model.coupling import Coupling
from deltagen.model.robot_file import number_text
from deltagen.model.serial import DEFAULT_GRAVITY, Inertial, Joint, SerialDescription

Matrix = npt.NDArray[np.float64]
_MOVABLE = ("revolute", "continuous", "prismatic")
_REFUSED = ("floating", "planar")
_NOISE = 1e-15  # constant translations below this [m] are rounding noise of the regrouping
_INERTIA_NOISE = 1e-14  # inertia entries below this fraction of the largest one: noise
# an inertia whose smallest principal moment is negative by at most this fraction of its
# trace, or by this much [kg m^2], is rounding of the file's digits (module docstring)
_INDEFINITE_REL = 1e-6
_INDEFINITE_ABS = 1e-9
_DECLARATION = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
# The range of a URDF's numbers deltagen accepts (module docstring, "Range"): far beyond any
# robot, and far inside float64, so that products of lengths, masses and inertias in the
# kinematics and dynamics stay finite.
MAX_LENGTH = 1e6  # [m]: an origin's offset, a prismatic joint's limit
MAX_MASS = 1e9  # [kg]
MAX_INERTIA = MAX_MASS * MAX_LENGTH**2  # [kg m^2]


class URDFWarning(UserWarning):
    """A URDF that deltagen accepts after a correction (an axis that is not unit length)."""


@dataclass(frozen=True)
class _UJoint:
    name: str
    type: str
    parent: str
    child: str
    origin: Matrix
    axis: npt.NDArray[np.float64]
    limit: tuple[float, float] | None
    damping: float
    friction: float
    mimic: tuple[str, float, float] | None = None  # (mimicked joint, multiplier, offset)


@dataclass(frozen=True)
class _ULink:
    name: str
    inertial: tuple[float, Matrix, Matrix] | None  # mass, E (4x4), inertia (3x3) in E
    # a defect of the <inertial> block, raised only when the link's mass is used (a link
    # that does not reach the chain never blocks it), and a correction, warned then
    problem: str | None = None
    correction: str | None = None


def _numbers(text: str | None, count: int, where: str, default: str | None = None) -> list[float]:
    if text is None:
        if default is None:
            raise GeometryError(f"{where}: missing")
        text = default
    parts = text.split()
    if len(parts) != count:
        raise GeometryError(f"{where}: expected {count} numbers, got {text!r}")
    return [number_text(part, where, f" (in {text!r})") for part in parts]


def _within(values: Sequence[float], bound: float, unit: str, where: str) -> None:
    """GeometryError naming ``where`` when a value exceeds ``bound`` in size (Range)."""
    for v in values:
        if abs(v) > bound:
            raise GeometryError(
                f"{where}: {v!r} {unit} is beyond the {bound:g} {unit} deltagen accepts "
                "(module docstring of deltagen.model.urdf, Range)"
            )


def _number(element: ET.Element, attr: str, where: str, default: float | None = None) -> float:
    raw = element.get(attr)
    if raw is None and default is not None:
        return default
    return _numbers(raw, 1, f"{where} attribute {attr!r}")[0]


def _origin(parent: ET.Element, where: str) -> Matrix:
    T = np.eye(4)
    origin = parent.find("origin")
    if origin is None:
        return T
    xyz = _numbers(origin.get("xyz"), 3, f"{where} <origin xyz>", "0 0 0")
    _within(xyz, MAX_LENGTH, "m", f"{where} <origin xyz>")
    rpy = _numbers(origin.get("rpy"), 3, f"{where} <origin rpy>", "0 0 0")
    T[:3, :3] = matrix_from_rpy(rpy)
    T[:3, 3] = xyz
    return T


def _parse_link(element: ET.Element) -> _ULink:
    name = element.get("name")
    if not name:
        raise GeometryError("<link> without a name attribute")
    inertial = element.find("inertial")
    if inertial is None:
        return _ULink(name, None)
    try:
        return _parse_inertial(name, inertial)
    except GeometryError as exc:  # raised where the link's mass is used (module docstring)
        return _ULink(name, None, problem=str(exc))


def _parse_inertial(name: str, inertial: ET.Element) -> _ULink:
    where = f"link {name!r}"
    mass_el = inertial.find("mass")
    if mass_el is None:
        raise GeometryError(f"{where}: <inertial> without <mass>")
    mass = _number(mass_el, "value", f"{where} <mass>")
    if mass < 0:
        raise GeometryError(f"{where} <mass>: must be >= 0 kg, got {mass!r}")
    _within([mass], MAX_MASS, "kg", f"{where} <mass>")
    E = _origin(inertial, f"{where} <inertial>")
    Ic = np.zeros((3, 3))
    correction = None
    ine = inertial.find("inertia")
    if ine is not None:
        w = f"{where} <inertia>"
        xx, yy, zz = (_number(ine, k, w, 0.0) for k in ("ixx", "iyy", "izz"))
        xy, xz, yz = (_number(ine, k, w, 0.0) for k in ("ixy", "ixz", "iyz"))
        _within([xx, yy, zz, xy, xz, yz], MAX_INERTIA, "kg m^2", w)
        Ic = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        lam, V = np.linalg.eigh(Ic)
        smallest = float(lam[0])
        if smallest < -1e-12 * max(1.0, float(np.abs(Ic).max())):
            trace = float(np.trace(Ic))
            if -smallest > max(_INDEFINITE_REL * trace, _INDEFINITE_ABS):
                raise GeometryError(
                    f"{w}: not positive semidefinite (smallest principal moment "
                    f"{smallest:.6g} kg m^2, trace {trace:.6g} kg m^2: more than rounding)"
                )
            # indefinite by the rounding of the printed digits: clamped
            Ic = (V * np.maximum(lam, 0.0)) @ V.T
            correction = (
                f"URDF {w}: smallest principal moment {smallest:.6g} kg m^2 (trace "
                f"{trace:.6g}) is rounding of the printed digits; clamped to 0"
            )
    return _ULink(name, (mass, E, Ic), correction=correction)


def _parse_joint(element: ET.Element, links: dict[str, _ULink]) -> _UJoint:
    name = element.get("name")
    if not name:
        raise GeometryError("<joint> without a name attribute")
    where = f"joint {name!r}"
    kind = element.get("type")
    if kind in _REFUSED:
        raise GeometryError(
            f"{where}: {kind} joints are not supported (a serial arm has one variable per joint)"
        )
    if kind not in _MOVABLE + ("fixed",):
        raise GeometryError(
            f"{where}: unknown joint type {kind!r}; use revolute, continuous, prismatic or fixed"
        )
    mimic = None
    mim = element.find("mimic")
    if mim is not None and kind not in _MOVABLE:
        # a fixed joint has no variable to couple (robot vendors leave <mimic> in when they
        # fix a gripper joint: TALOS' arm); ignored as urdfdom and pinocchio ignore it
        warnings.warn(
            f"URDF {where}: <mimic> on a {kind} joint is ignored", URDFWarning, stacklevel=4
        )
        mim = None
    if mim is not None:
        target = mim.get("joint")
        if not target:
            raise GeometryError(f"{where} <mimic>: missing joint attribute")
        if target == name:
            raise GeometryError(f"{where} <mimic>: a joint cannot mimic itself")
        mimic = (
            target,
            _number(mim, "multiplier", f"{where} <mimic>", 1.0),
            _number(mim, "offset", f"{where} <mimic>", 0.0),
        )
    ends = {}
    for tag in ("parent", "child"):
        el = element.find(tag)
        link = None if el is None else el.get("link")
        if not link:
            raise GeometryError(f"{where}: missing <{tag} link=...>")
        if link not in links:
            raise GeometryError(f"{where}: <{tag}> names link {link!r}, which is not defined")
        ends[tag] = link
    origin = _origin(element, where)
    axis = np.array([1.0, 0.0, 0.0])
    if kind in _MOVABLE:
        ax = element.find("axis")
        if ax is not None:
            axis = np.array(_numbers(ax.get("xyz"), 3, f"{where} <axis xyz>", "1 0 0"))
        # scaled by its largest entry first: the length of (1e300, 0, 0) overflows, its
        # direction does not
        scale = float(np.max(np.abs(axis)))
        direction = axis / scale if scale > 0.0 else axis
        norm = scale * float(np.linalg.norm(direction))
        if norm < 1e-9:
            raise GeometryError(f"{where} <axis>: zero vector {axis.tolist()}")
        if abs(norm - 1.0) > 1e-9:
            warnings.warn(
                f"URDF {where}: axis {axis.tolist()} has length {norm:.6g}; normalised",
                URDFWarning,
                stacklevel=4,
            )
        axis = direction / float(np.linalg.norm(direction))
    limit = None
    lim = element.find("limit")
    if kind in ("revolute", "prismatic"):
        if lim is None:
            raise GeometryError(
                f"{where}: a {kind} joint needs <limit lower upper> (URDF specification; "
                "use type continuous for a revolute joint without limits)"
            )
        lo = _number(lim, "lower", f"{where} <limit>", 0.0)
        hi = _number(lim, "upper", f"{where} <limit>", 0.0)
        if lo > hi:
            raise GeometryError(f"{where} <limit>: lower {lo!r} must be below upper {hi!r}")
        if kind == "prismatic":
            _within([lo, hi], MAX_LENGTH, "m", f"{where} <limit>")
        if lo == hi:
            # lower and upper default to 0 in the specification: files that give a <limit>
            # only for effort and velocity carry 0 = 0 (the double pendulum of
            # example-robot-data). A joint that cannot move would be a fixed joint.
            warnings.warn(
                f"URDF {where}: <limit> lower = upper = {lo!r}, read as no position limits",
                URDFWarning,
                stacklevel=4,
            )
        else:
            limit = (lo, hi)
    if lim is not None:  # checked as numbers, not kept (module docstring)
        for attr in ("velocity", "effort"):
            if lim.get(attr) is not None:
                _number(lim, attr, f"{where} <limit>")
    damping = friction = 0.0
    dyn = element.find("dynamics")
    if dyn is not None and kind in _MOVABLE:
        damping = _number(dyn, "damping", f"{where} <dynamics>", 0.0)
        friction = _number(dyn, "friction", f"{where} <dynamics>", 0.0)
        if damping < 0 or friction < 0:
            raise GeometryError(f"{where} <dynamics>: damping and friction must be >= 0")
    return _UJoint(
        name, kind, ends["parent"], ends["child"], origin, axis, limit, damping, friction, mimic
    )


_REFUSAL = (
    "DOCTYPE/ENTITY declarations are refused (a URDF needs none; they allow entity-expansion "
    "attacks)"
)


class _Declaration(Exception):
    """Raised from expat's handlers when the document declares a DTD or an entity."""


def _refuse(*_args: object) -> None:
    raise _Declaration


def _parse(text: bytes, source: str) -> tuple[str, dict[str, _ULink], list[_UJoint]]:
    # twice: a look at the bytes before expat sees them, and expat's own declaration
    # handlers (which also catch what the byte look cannot read, e.g. a UTF-16 file)
    # the messages do not name ``source``: chain_from_urdf prefixes every one with it
    if _DECLARATION.search(text):
        raise GeometryError(_REFUSAL)
    check = expat.ParserCreate()  # a first pass that builds nothing, with the handlers set
    for handler in (
        "StartDoctypeDeclHandler",
        "EntityDeclHandler",
        "UnparsedEntityDeclHandler",
        "ExternalEntityRefHandler",
    ):
        setattr(check, handler, _refuse)
    try:
        check.Parse(text, True)
        root = ET.fromstring(text)
    except _Declaration:
        raise GeometryError(_REFUSAL) from None
    except (expat.ExpatError, ET.ParseError) as exc:
        raise GeometryError(f"not well-formed XML: {exc}") from None
    if root.tag != "robot":
        raise GeometryError(f"the root element is <{root.tag}>, not <robot>")
    links: dict[str, _ULink] = {}
    for el in root.findall("link"):
        link = _parse_link(el)
        if link.name in links:
            raise GeometryError(f"link {link.name!r} is defined twice")
        links[link.name] = link
    joints = [_parse_joint(el, links) for el in root.findall("joint")]
    names = [j.name for j in joints]
    for n in names:
        if names.count(n) > 1:
            raise GeometryError(f"joint {n!r} is defined twice")
    return root.get("name", "arm"), links, joints


def _tree(links: dict[str, _ULink], joints: list[_UJoint]) -> tuple[str, dict[str, _UJoint]]:
    """(root link, child link -> the joint that moves it), checking it is one tree."""
    by_child: dict[str, _UJoint] = {}
    for j in joints:
        if j.child in by_child:
            raise GeometryError(
                f"joint {j.name!r}: link {j.child!r} is already the child of joint "
                f"{by_child[j.child].name!r} (a link has one parent)"
            )
        by_child[j.child] = j
    for j in joints:  # walk up from each joint; coming back means a cycle
        seen = {j.child}
        link = j.parent
        while link in by_child:
            if link in seen:
                raise GeometryError(f"joint {j.name!r} lies on a cycle through link {link!r}")
            seen.add(link)
            link = by_child[link].parent
    roots = [name for name in links if name not in by_child]
    if len(roots) != 1:
        raise GeometryError(
            f"the links form {len(roots)} trees (roots {sorted(roots)}); a URDF has one root"
        )
    return roots[0], by_child


def _z_to(axis: npt.NDArray[np.float64]) -> Matrix:
    """4x4 rotation taking e_z to the unit vector ``axis`` (module docstring, R_i)."""
    H = np.eye(4)
    c = float(axis[2])
    if c > 1.0 - 1e-15:
        return H
    if c < -1.0 + 1e-15:
        H[:3, :3] = np.diag([1.0, -1.0, -1.0])  # Rot_x(pi)
        return H
    k = np.cross([0.0, 0.0, 1.0], axis)
    s = float(np.linalg.norm(k))
    k = k / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    H[:3, :3] = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    return H


def _inverse(T: Matrix) -> Matrix:
    inv = np.eye(4)
    inv[:3, :3] = T[:3, :3].T
    inv[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return inv


def _lump(
    parts: list[tuple[float, npt.NDArray[np.float64], Matrix]],
) -> tuple[float, npt.NDArray[np.float64], Matrix]:
    """Total mass, COM and inertia about it of rigidly joined bodies (mass, com, Ic) given in
    one frame (parallel-axis theorem)."""
    mass = float(sum(m for m, _, _ in parts))
    inertia = np.zeros((3, 3))
    if mass == 0.0:
        for _, _, Ic in parts:
            inertia += Ic
        return 0.0, np.zeros(3), inertia
    com = np.zeros(3)
    for m, c, _ in parts:
        com += m * c
    com /= mass
    for m, c, Ic in parts:
        d = c - com
        inertia += Ic + m * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return mass, com, inertia


def _motion(j: _UJoint, q: float) -> Matrix:
    """M_J(q): the joint's motion about / along its unit axis (module docstring)."""
    M = np.eye(4)
    a = j.axis
    if j.type == "prismatic":
        M[:3, 3] = q * a
        return M
    K = skew(a)
    M[:3, :3] = np.eye(3) + math.sin(q) * K + (1.0 - math.cos(q)) * (K @ K)  # Rodrigues
    return M


class _OffChain:
    """The links hanging off the base-tip chain (branches and the links beyond the tip), each
    with its pose relative to the chain link it hangs from: fixed joints by their origin,
    movable ones locked (module docstring, "Inertials")."""

    def __init__(
        self, joints: list[_UJoint], on_chain: set[str], locked: Mapping[str, float] | None
    ):
        self.below: dict[str, list[_UJoint]] = {}
        self.by_name = {j.name: j for j in joints}
        for j in joints:
            if j.name not in on_chain:
                self.below.setdefault(j.parent, []).append(j)
        self.on_chain = on_chain
        self.locked: dict[str, float] = {}
        for key, value in (locked or {}).items():
            found = self.by_name.get(key)
            if found is None or found.name in on_chain or found.type not in _MOVABLE:
                raise GeometryError(
                    f"locked: {key!r} is not a movable joint off the chain (those are locked "
                    "where their links' mass is folded in)"
                )
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise GeometryError(f"locked[{key!r}]: {value!r} is not a number")
            if not math.isfinite(float(value)):
                raise GeometryError(f"locked[{key!r}]: {value!r} is not finite")
            self.locked[key] = float(value)
        self.used: dict[str, float] = {}  # every locked joint's value
        self.defaulted: set[str] = set()  # those the caller's ``locked`` does not determine

    def value(self, j: _UJoint) -> float:
        """The locked value of an off-chain movable joint: ``locked`` if given, else
        multiplier q + offset of the joint it mimics, else 0 (the joint's zero). A mimic
        of a mimic is followed in a loop (no recursion: such chains may be long)."""
        followers: list[_UJoint] = []  # j, the joint it mimics, ... up to the last leader
        seen: set[str] = set()
        while j.name not in self.locked and j.mimic is not None:
            target = j.mimic[0]
            leader = self.by_name.get(target)
            if leader is None or leader.type not in _MOVABLE or j.name in seen:
                raise GeometryError(
                    f"joint {j.name!r}: <mimic joint={target!r}> names no movable joint"
                )
            if leader.name in self.on_chain:
                raise GeometryError(
                    f"joint {j.name!r} off the chain mimics joint {target!r} of the chain: its "
                    "links would move with the chain, which a folded inertial cannot follow"
                )
            seen.add(j.name)
            followers.append(j)
            j = leader
        if j.name in self.locked:
            value = float(self.locked[j.name])
        else:
            self.defaulted.add(j.name)
            value = 0.0
        for follower in reversed(followers):  # the leader's value carried down
            _, mult, offset = follower.mimic  # type: ignore[misc]
            value = mult * value + offset
            if j.name in self.defaulted:
                self.defaulted.add(follower.name)
        return value

    def subtree(self, link: str, at: Matrix) -> Iterator[tuple[str, Matrix]]:
        """(link, its pose in the frame where ``link`` is at ``at``) for every link below
        ``link`` off the chain, depth first (with a stack, not recursion: a branch may be
        thousands of links long)."""
        stack = [(j, at) for j in reversed(self.below.get(link, []))]
        while stack:
            j, parent_at = stack.pop()
            T = parent_at @ j.origin
            if j.type in _MOVABLE:
                self.used[j.name] = self.value(j)
                T = T @ _motion(j, self.used[j.name])
            yield j.child, T
            stack.extend((k, T) for k in reversed(self.below.get(j.child, [])))

    def finish(self, tip: str) -> None:
        defaulted = {k: v for k, v in self.used.items() if k in self.defaulted}
        if defaulted:
            names = ", ".join(f"{k} = {v:g}" for k, v in sorted(defaulted.items()))
            warnings.warn(
                f"movable joints off the chain (beyond {tip!r} or on a branch) are locked at "
                f"{names} (their zero, or their <mimic> of it; pass locked={{name: value}} "
                "for another configuration); their links' inertials are folded into the chain "
                "link they hang from",
                URDFWarning,
                stacklevel=5,
            )


def _base_gravity(
    base: str,
    root: str,
    by_child: dict[str, _UJoint],
    off_chain: _OffChain,
    gravity: Sequence[float],
    warn: bool,
) -> tuple[float, float, float]:
    """Gravity [m/s^2] given in the root link's (world) frame, turned into the base link's
    frame: g_base = R^T g with R the rotation of root -> base through the joints above the
    base, fixed ones by their origin, movable ones locked (module docstring, "Gravity")."""
    try:
        g = np.array([float(v) for v in gravity], dtype=float)
    except (TypeError, ValueError):
        raise GeometryError(f"gravity must be 3 finite numbers [m/s^2], got {gravity!r}") from None
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise GeometryError(f"gravity must be 3 finite numbers [m/s^2], got {gravity!r}")
    above: list[_UJoint] = []
    link = base
    while link != root:
        above.append(by_child[link])
        link = by_child[link].parent
    R = np.eye(3)
    held: dict[str, float] = {}
    defaulted = []
    for j in reversed(above):  # root first
        R = R @ j.origin[:3, :3]
        if j.type in _MOVABLE:
            held[j.name] = off_chain.value(j)
            if j.name in off_chain.defaulted:
                defaulted.append(j.name)
            R = R @ _motion(j, held[j.name])[:3, :3]
    out = R.T @ g
    # rounding of the turns (cos(pi/2) = 6e-17 in floats) is zeroed
    out = np.where(np.abs(out) < _NOISE * float(np.linalg.norm(g)), 0.0, out)
    if warn and defaulted:
        names = ", ".join(f"{k} = {held[k]:g}" for k in defaulted)
        warnings.warn(
            f"gravity is turned from the URDF's root link {root!r} into the chain's base "
            f"{base!r} with the movable joints above the base at {names} (their zero, or "
            "their <mimic> of it; pass locked={name: value} for another posture)",
            URDFWarning,
            stacklevel=5,
        )
    return float(out[0]), float(out[1]), float(out[2])


def _identifier(name: str) -> str:
    ident = re.sub(r"[^A-Za-z0-9_]", "_", name)[:64] or "arm"
    return ident if not ident[0].isdigit() else f"urdf_{ident}"[:64]


class TipChoiceError(GeometryError):
    """No tip given and the tree below the base link has no single leaf: ``leaves`` lists
    the candidates (for a caller that names its own way of choosing one)."""

    def __init__(self, message: str, base: str, leaves: list[str]):
        super().__init__(message)
        self.base = base
        self.leaves = leaves


def description_from_urdf(
    path: str | os.PathLike[str],
    base: str | None = None,
    tip: str | None = None,
    name: str | None = None,
    locked: Mapping[str, float] | None = None,
    gravity: Sequence[float] | None = None,
) -> SerialDescription:
    """The chain of the URDF file ``path`` from link ``base`` (default: the root link) to
    link ``tip`` (default: the single leaf below ``base``) as universal coordinates (module
    docstring). Joint names are kept; the robot's name defaults to the URDF's (made a C
    identifier). A chain with ``<mimic>`` joints is refused here (its description alone
    would treat them as free): use :func:`chain_from_urdf`. ``locked``: values [rad or m] of
    movable joints off the chain, where their links' mass is folded in, and of those above
    ``base`` (module docstring). ``gravity``: [m/s^2] in the URDF's root (world) frame,
    default (0, 0, -9.81); the description holds it turned into the base link's frame."""
    desc, coupling = chain_from_urdf(path, base, tip, name, locked, gravity)
    if coupling is not None:
        coupled = [desc.joints[i].name for i in range(desc.n) if i not in coupling.independent]
        raise GeometryError(
            f"URDF {path}: joints {', '.join(coupled)} mimic others; read the chain with "
            "chain_from_urdf (description and coupling) or SerialRobot.from_urdf"
        )
    return desc


def chain_from_urdf(
    path: str | os.PathLike[str],
    base: str | None = None,
    tip: str | None = None,
    name: str | None = None,
    locked: Mapping[str, float] | None = None,
    gravity: Sequence[float] | None = None,
) -> tuple[SerialDescription, Coupling | None]:
    """(description of every movable joint of the chain, its :class:`Coupling` or None when
    no joint of the chain has a ``<mimic>``): q_j = multiplier q_i + offset for a joint j
    that mimics joint i (module docstring of model/coupling.py)."""
    source = str(path)
    try:
        text = read_regular_file(path, "URDF")
    except InputError as exc:
        raise GeometryError(str(exc)) from None
    try:
        return _description(text, source, base, tip, name, locked, gravity)
    except TipChoiceError as exc:
        raise TipChoiceError(f"URDF {source}: {exc}", exc.base, exc.leaves) from None
    except GeometryError as exc:
        raise GeometryError(f"URDF {source}: {exc}") from None


def _description(
    text: bytes,
    source: str,
    base: str | None,
    tip: str | None,
    name: str | None,
    locked: Mapping[str, float] | None = None,
    gravity: Sequence[float] | None = None,
) -> tuple[SerialDescription, Coupling | None]:
    robot_name, links, joints = _parse(text, source)
    if not links:
        raise GeometryError("no <link>: a robot needs links joined by joints")
    if not joints:
        raise GeometryError(
            f"no joints: link{'s' if len(links) > 1 else ''} {', '.join(sorted(links))} and "
            "nothing that moves (a serial arm needs at least one revolute, continuous or "
            "prismatic joint)"
        )
    root, by_child = _tree(links, joints)
    available = ", ".join(sorted(links))
    if base is None:
        base = root
    if base not in links:
        raise GeometryError(f"base link {base!r} is not defined; links: {available}")
    if tip is None:
        parents = {j.parent for j in joints}
        leaves = []
        for link in links:  # leaves below base
            if link in parents:
                continue
            up = link
            while up != base and up in by_child:
                up = by_child[up].parent
            if up == base and link != base:
                leaves.append(link)
        if len(leaves) != 1:
            raise TipChoiceError(
                f"the tree below {base!r} has {len(leaves)} leaves ({', '.join(sorted(leaves))});"
                " choose one with tip=",
                base,
                sorted(leaves),
            )
        tip = leaves[0]
    if tip not in links:
        raise GeometryError(f"tip link {tip!r} is not defined; links: {available}")
    chain: list[_UJoint] = []
    link = tip
    while link != base:
        if link not in by_child:
            raise GeometryError(f"tip link {tip!r} does not lie below base link {base!r}")
        chain.append(by_child[link])
        link = by_child[link].parent
    chain.reverse()

    # P_0 .. P_n and the movable joints (module docstring)
    movable: list[_UJoint] = []
    P: list[Matrix] = [np.eye(4)]
    # inertial parts of each moving body, in its W_i frame: the child link of joint i and the
    # links fixed to it along the chain (at transform P_partial from W_i)
    parts: list[list[tuple[float, npt.NDArray[np.float64], Matrix]]] = []
    any_inertial = False

    def add_inertial(link_name: str, at: Matrix) -> None:
        nonlocal any_inertial
        link = links[link_name]
        if not parts:
            return
        if link.problem is not None:
            raise GeometryError(link.problem)
        if link.correction is not None:
            warnings.warn(link.correction, URDFWarning, stacklevel=6)
        inertial = link.inertial
        if inertial is None:
            return
        any_inertial = True
        mass, E, Ic = inertial
        F = at @ E
        parts[-1].append((mass, F[:3, 3].copy(), F[:3, :3] @ Ic @ F[:3, :3].T))

    on_chain = {j.name for j in chain}
    off_chain = _OffChain(joints, on_chain, locked)

    def add_subtree(link_name: str, at: Matrix) -> None:
        """The link's inertial and those of every link hanging off the chain below it."""
        add_inertial(link_name, at)
        if not parts:  # fixed to the base: carries no joint
            return
        for child, T in off_chain.subtree(link_name, at):
            add_inertial(child, T)

    for j in chain:
        if j.type == "fixed":
            P[-1] = P[-1] @ j.origin
            add_subtree(j.child, P[-1])
        else:
            movable.append(j)
            P.append(np.eye(4))
            parts.append([])
            add_subtree(j.child, P[-1])
    off_chain.finish(tip)
    g_base = _base_gravity(
        base,
        root,
        by_child,
        off_chain,
        DEFAULT_GRAVITY if gravity is None else gravity,
        any_inertial,
    )
    if not movable:
        raise GeometryError(f"the chain from {base!r} to {tip!r} has no movable joint")

    n = len(movable)
    Rh = [_z_to(j.axis) for j in movable]
    Og = [j.origin for j in movable]
    base_T = P[0] @ Og[0] @ Rh[0]
    tool_T = Rh[-1].T @ P[n]
    C = [Rh[i].T @ P[i + 1] @ Og[i + 1] @ Rh[i + 1] for i in range(n - 1)] + [np.eye(4)]
    G = [P[i + 1] @ Og[i + 1] @ Rh[i + 1] for i in range(n - 1)] + [Rh[-1]]

    out: list[Joint] = []
    for i, j in enumerate(movable):
        t = [0.0 if abs(v) < _NOISE else float(v) for v in C[i][:3, 3]]
        rx, ry, rz = xyz_angles(C[i][:3, :3])
        inertial = None
        if any_inertial:
            mass, com_w, I_w = _lump(parts[i])
            Ginv = _inverse(G[i])
            com = Ginv[:3, :3] @ com_w + Ginv[:3, 3]
            GR = G[i][:3, :3]
            I_u = GR.T @ I_w @ GR
            I_u = (I_u + I_u.T) / 2
            # rounding noise of the regrouping (cos(pi/2) = 6e-17 in floats) is zeroed, so
            # that the derivation sees exact zeros: com below _NOISE, inertia entries below
            # _INERTIA_NOISE of the largest one
            com = np.where(np.abs(com) < _NOISE, 0.0, com)
            I_u = np.where(np.abs(I_u) < _INERTIA_NOISE * np.abs(I_u).max(), 0.0, I_u)
            inertial = Inertial(
                mass=mass,
                com=(float(com[0]), float(com[1]), float(com[2])),
                inertia=(
                    float(I_u[0, 0]),
                    float(I_u[1, 1]),
                    float(I_u[2, 2]),
                    float(I_u[0, 1]),
                    float(I_u[0, 2]),
                    float(I_u[1, 2]),
                ),
                viscous=j.damping,
                coulomb=(j.friction, -j.friction),
            )
        out.append(
            Joint(
                type="prismatic" if j.type == "prismatic" else "revolute",
                tx=t[0],
                ty=t[1],
                tz=t[2],
                rx=rx,
                ry=ry,
                rz=rz,
                axis="z",
                qlim=j.limit,
                name=j.name,
                inertial=inertial,
            )
        )
    desc = SerialDescription(
        name=name if name is not None else _identifier(robot_name),
        convention="universal",
        joints=tuple(out),
        base=base_T,
        tool=tool_T,
        doc=f"from URDF {source}, chain {base} -> {tip}",
        gravity=g_base,
    )
    mimics = {j.name: j.mimic for j in movable if j.mimic is not None}
    if not mimics:
        return desc, None
    return desc, Coupling.from_mimics([j.name for j in movable], mimics)
