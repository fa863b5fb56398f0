"""What a task puts on the table, declared as data: objects, fixtures and their colours.

A task's scene is the robot, the table, the lights and the cameras (``assets/``) plus
a :class:`Scene`: free objects (:class:`SceneObject`, a body with a free joint and one
collision shape) and fixtures (:class:`Fixture`, bodies fixed to the table or moving on
one joint, such as a goal pad, a bin or a drawer). :mod:`gym_soarm.sim.scene` turns the
declaration into a compiled MuJoCo model; :class:`gym_soarm.sim.physics.SoArmPhysics`
answers questions about each object and fixture by its name.

Sizes follow MuJoCo's convention: half extents for a box, (radius, half height) for a
cylinder, (radius,) for a sphere. Every figure carries its unit in its name.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterable, Sequence

COLOURS: dict[str, tuple[float, float, float, float]] = {
    "blue": (0.1, 0.25, 0.85, 1.0),
    "red": (0.85, 0.12, 0.1, 1.0),
    "green": (0.15, 0.75, 0.2, 1.0),
    "yellow": (0.95, 0.8, 0.1, 1.0),
    "orange": (0.95, 0.45, 0.05, 1.0),
    "purple": (0.55, 0.2, 0.75, 1.0),
    "white": (0.92, 0.92, 0.92, 1.0),
    "grey": (0.5, 0.5, 0.52, 1.0),
    "brown": (0.45, 0.3, 0.18, 1.0),
    "black": (0.08, 0.08, 0.08, 1.0),
}
"""The named colours objects and fixtures may have (RGBA, 0 to 1)."""

SHAPES: tuple[str, ...] = ("box", "cylinder", "sphere")
SIZE_COUNTS: dict[str, int] = {"box": 3, "cylinder": 2, "sphere": 1}
JOINT_KINDS: tuple[str, ...] = ("slide", "hinge")
DEFAULT_FRICTION: tuple[float, float, float] = (1.0, 0.02, 0.001)
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


def _check_name(kind: str, name: object) -> None:
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(
            f"{kind} name must be lower-case letters, digits and underscores, starting with a "
            f"letter (it names MuJoCo bodies and geoms); got {name!r}. Pass e.g. 'red_cube'."
        )


def _check_shape(kind: str, shape: str, size: Sequence[float]) -> tuple[float, ...]:
    if shape not in SHAPES:
        raise ValueError(f"{kind} shape must be one of {', '.join(SHAPES)}; got {shape!r}.")
    size = tuple(float(v) for v in size)
    if len(size) != SIZE_COUNTS[shape] or not all(math.isfinite(v) and v > 0 for v in size):
        raise ValueError(
            f"a {shape}'s size_m must be {SIZE_COUNTS[shape]} positive numbers of metres "
            f"(box: half extents; cylinder: radius, half height; sphere: radius); got {size!r}."
        )
    return size


def _check_colour(kind: str, colour: str) -> None:
    if colour not in COLOURS:
        raise ValueError(f"{kind} colour must be one of {', '.join(COLOURS)}; got {colour!r}.")


def _vector(name: str, value: Sequence[float], n: int = 3) -> tuple[float, ...]:
    vector = tuple(float(v) for v in value)
    if len(vector) != n or not all(math.isfinite(v) for v in vector):
        raise ValueError(f"{name} must be {n} finite numbers; got {value!r}.")
    return vector


def half_height(shape: str, size: Sequence[float]) -> float:
    """Height (m) of a shape's centre above its base when it stands upright."""
    return size[0] if shape == "sphere" else size[1] if shape == "cylinder" else size[2]


def not_in_scene(kind: str, name: str, known: Iterable[str]) -> ValueError:
    """The error for a scene that has no ``kind`` (``"object"``, ``"fixture"``) called
    ``name``, listing the ``known`` names."""
    return ValueError(f"this scene has no {kind} {name!r}; its {kind}s are {list(known)}.")


@dataclasses.dataclass(frozen=True)
class SceneObject:
    """A free object: one body with a free joint and one collision shape.

    Attributes:
        name: names the body, its free joint and its geom (``"cube"``, ``"red_cube"``).
        shape: ``"box"``, ``"cylinder"`` (upright) or ``"sphere"``.
        size_m: half extents (box), (radius, half height) (cylinder) or (radius,).
        colour: one of :data:`COLOURS`.
        mass_kg: its mass.
        position_m: (x, y) where it rests in the compiled model, before any reset.
        friction: MuJoCo's sliding, torsional and rolling friction.
    """

    name: str
    shape: str
    size_m: tuple[float, ...]
    colour: str
    mass_kg: float
    position_m: tuple[float, float] = (0.0, 0.35)
    friction: tuple[float, float, float] = DEFAULT_FRICTION

    def __post_init__(self) -> None:
        _check_name("object", self.name)
        object.__setattr__(self, "size_m", _check_shape("object", self.shape, self.size_m))
        _check_colour("object", self.colour)
        if not (isinstance(self.mass_kg, (int, float)) and 0 < self.mass_kg < 10):
            raise ValueError(f"mass_kg must be a number in (0, 10) kg; got {self.mass_kg!r}.")
        object.__setattr__(self, "position_m", _vector("position_m", self.position_m, 2))
        object.__setattr__(self, "friction", _vector("friction", self.friction, 3))

    @property
    def rest_height_m(self) -> float:
        """Height (m) of the centre above the table when the object stands on it."""
        return half_height(self.shape, self.size_m)

    @property
    def footprint_radius_m(self) -> float:
        """Radius (m) of the smallest vertical cylinder around the object, any yaw."""
        if self.shape == "box":
            return math.hypot(self.size_m[0], self.size_m[1])
        return self.size_m[0]


@dataclasses.dataclass(frozen=True)
class FixtureGeom:
    """One shape of a fixture, placed in the fixture's frame.

    Attributes:
        shape: ``"box"``, ``"cylinder"`` or ``"sphere"``.
        size_m: as for :class:`SceneObject`.
        colour: one of :data:`COLOURS`.
        position_m: centre in the fixture's frame.
        collides: False for purely visual parts (a pad painted on the table).
        emission: glow of the material (0 to 1), to stand out in every camera.
        mass_kg: mass of the part, for fixtures that move on a joint.
    """

    shape: str
    size_m: tuple[float, ...]
    colour: str
    position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    collides: bool = True
    emission: float = 0.0
    mass_kg: float = 0.05

    def __post_init__(self) -> None:
        object.__setattr__(self, "size_m", _check_shape("fixture geom", self.shape, self.size_m))
        _check_colour("fixture geom", self.colour)
        object.__setattr__(self, "position_m", _vector("position_m", self.position_m))


def open_box_geoms(
    inner_half_m: float, wall_m: float, floor_m: float, rim_z_m: float, colour: str
) -> tuple[FixtureGeom, ...]:
    """An open box standing on the table, in its own frame (origin: the floor plate's
    underside): a floor plate of ``floor_m`` and four walls of ``wall_m`` round a square
    inside of ``2 * inner_half_m``, their tops ``rim_z_m`` above the table."""
    outer = inner_half_m + wall_m
    half_height = (rim_z_m - floor_m) / 2
    z = floor_m + half_height
    offset = inner_half_m + wall_m / 2
    floor = FixtureGeom("box", (outer, outer, floor_m / 2), colour, (0.0, 0.0, floor_m / 2))
    # The walls along y span the full outer width; those along x fit between them.
    along_x = (wall_m / 2, outer, half_height)
    along_y = (inner_half_m, wall_m / 2, half_height)
    walls = tuple(
        FixtureGeom("box", size, colour, position, emission=0.1)
        for size, position in (
            (along_x, (offset, 0.0, z)),
            (along_x, (-offset, 0.0, z)),
            (along_y, (0.0, offset, z)),
            (along_y, (0.0, -offset, z)),
        )
    )
    return (floor, *walls)


@dataclasses.dataclass(frozen=True)
class FixtureJoint:
    """The one joint of a moving fixture (a drawer slides, a lid hinges).

    Attributes:
        kind: ``"slide"`` or ``"hinge"``.
        axis: direction in the fixture's frame.
        range: (low, high) in metres (slide) or radians (hinge); starts at 0.
        damping: joint damping (N·s/m or N·m·s/rad).
        frictionloss: dry friction (N or N·m), so the fixture stays where it is left.
    """

    kind: str
    axis: tuple[float, float, float]
    range: tuple[float, float]
    damping: float = 1.0
    frictionloss: float = 0.05

    def __post_init__(self) -> None:
        if self.kind not in JOINT_KINDS:
            raise ValueError(
                f"joint kind must be one of {', '.join(JOINT_KINDS)}; got {self.kind!r}."
            )
        object.__setattr__(self, "axis", _vector("axis", self.axis))
        low, high = _vector("range", self.range, 2)
        if not low <= 0.0 <= high or low == high:
            raise ValueError(
                f"range must be (low, high) with low <= 0 <= high; got {self.range!r}."
            )
        object.__setattr__(self, "range", (low, high))


@dataclasses.dataclass(frozen=True)
class Fixture:
    """A body fixed to the world (or moving on one joint), made of several shapes.

    Attributes:
        name: names the body, its site (``fixture_position``) and its joint.
        position_m: where the body's frame sits, in the world (or in ``parent``'s frame).
        geoms: its shapes.
        site_m: where its named site sits in its frame (the point tasks aim at).
        joint: the joint it moves on, or None for a fixed fixture.
        parent: name of the fixture it is attached to, or None for the world.
    """

    name: str
    position_m: tuple[float, float, float]
    geoms: tuple[FixtureGeom, ...]
    site_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint: FixtureJoint | None = None
    parent: str | None = None

    def __post_init__(self) -> None:
        _check_name("fixture", self.name)
        object.__setattr__(self, "position_m", _vector("position_m", self.position_m))
        object.__setattr__(self, "site_m", _vector("site_m", self.site_m))
        object.__setattr__(self, "geoms", tuple(self.geoms))
        if not self.geoms or not all(isinstance(g, FixtureGeom) for g in self.geoms):
            raise ValueError(
                f"fixture {self.name!r} needs at least one FixtureGeom; got {self.geoms!r}."
            )


@dataclasses.dataclass(frozen=True)
class Scene:
    """The objects and fixtures of one task's scene (the robot and table are always there)."""

    objects: tuple[SceneObject, ...] = ()
    fixtures: tuple[Fixture, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "objects", tuple(self.objects))
        object.__setattr__(self, "fixtures", tuple(self.fixtures))
        names = [o.name for o in self.objects] + [f.name for f in self.fixtures]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"object and fixture names must be unique; {duplicates} repeat.")
        known: set[str] = set()
        for fixture in self.fixtures:
            if fixture.parent is not None and fixture.parent not in known:
                raise ValueError(
                    f"fixture {fixture.name!r} is attached to {fixture.parent!r}, which must be "
                    f"declared before it; declared so far: {sorted(known)}."
                )
            known.add(fixture.name)

    def object(self, name: str) -> SceneObject:
        """The declared object called ``name`` (ValueError listing the names if unknown)."""
        for item in self.objects:
            if item.name == name:
                return item
        raise not_in_scene("object", name, (o.name for o in self.objects))


EMPTY_SCENE = Scene()
"""The arena and the robot alone."""
