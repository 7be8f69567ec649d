"""The G1's ``tables`` scene: two tables a few metres apart, and objects to carry on the first one.

World frame: the robot stands at the origin facing +x. The first table stands in front of it, its near
edge 0.9 m ahead; the second stands 2.8 m to the robot's right. Both tops are 0.75 m above the floor,
where a standing G1 reaches with its hands.

Each table is a top and four legs, static geoms of the world body that collide with the robot's soles,
its body shell (:data:`robot_models.g1_constants.SHELL_CONTYPE`) and the objects, as the course
obstacles do. A table is one :class:`~robot_models.spec.Obstacle` named after its top geom (the
entity's canonical frame: the top's centre), made of its top and legs (the entity's bounds) and with
the top's footprint on the navigation map.

The objects on the first table are free bodies with contacts fit for friction grasps (condim 4,
friction 1, a stiff ``solref``, as the Panda's boxes): a box to carry with both hands (0.25 m along
the grasp axis, world y at rest), a 5.5 cm cube and a can for one hand. At the ``stand`` keyframe
they rest on the table top (their free joints' initial positions are their resting poses).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Final

import mujoco

import robot_models.g1_constants as names
from robot_models.g1_palms import add_palm_pads
from robot_models.spec import Obstacle
from robot_models.validation import check_range

Vec3 = tuple[float, float, float]
Rgba = tuple[float, float, float, float]

TABLE_TOP_Z_M: Final = 0.75  # height of both table tops above the floor [m]
TABLE_TOP_THICKNESS_M: Final = 0.04
TABLE_LEG_HALF_WIDTH_M: Final = 0.025  # square legs, 5 cm
TABLE_LEG_INSET_M: Final = 0.05  # from the top's edges to the legs' centres
TABLE_RGBA: Final = (0.62, 0.45, 0.28, 1.0)

OBJECT_CONDIM: Final = 4  # sliding and torsional friction
OBJECT_FRICTION: Final = (1.0, 0.02, 0.001)  # sliding, torsional [m], rolling [m]
OBJECT_SOLREF: Final = (0.004, 1.0)  # time constant [s] (2 physics steps), damping ratio: stiff contacts


class Shape(enum.Enum):
    BOX = "box"
    CYLINDER = "cylinder"  # its axis along the object's z


@dataclass(frozen=True)
class TableLayout:
    """A table standing on the floor, its sides along the world axes.

    Attributes:
        name: the table's name, also its top geom's (the entity and the map obstacle).
        center_xy: centre of its top, world frame [m].
        half_size_xy: half lengths of its top along world x and y [m].
        top_z: height of its top surface above the floor [m].
    """

    name: str
    center_xy: tuple[float, float]
    half_size_xy: tuple[float, float]
    top_z: float = TABLE_TOP_Z_M

    def __post_init__(self) -> None:
        for axis, half in zip("xy", self.half_size_xy, strict=True):
            check_range(f"table {self.name} half size {axis}", half, 2 * TABLE_LEG_INSET_M, low_open=True, unit="m")
        check_range(f"table {self.name} top_z", self.top_z, TABLE_TOP_THICKNESS_M, low_open=True, unit="m")

    @property
    def leg_names(self) -> tuple[str, ...]:
        return tuple(f"{self.name}_leg_{i}" for i in range(4))

    @property
    def xy_bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the top, world frame [m]."""
        (x, y), (hx, hy) = self.center_xy, self.half_size_xy
        return x - hx, x + hx, y - hy, y + hy


@dataclass(frozen=True)
class ObjectLayout:
    """A free object resting upright on a table at the keyframe.

    Attributes:
        name: its body, free joint and geom name (an object of the scene: /objects, /tf, entities).
        shape: box or upright cylinder.
        half_size: half lengths along its own x, y, z [m]; a cylinder's are (radius, radius, half height).
        mass_kg: [kg].
        xy: centre at rest, world frame [m]; the object is not rotated.
        rgba: colour.
        touches_shell: whether it collides with the robot's body shell and palm pads (contype
            :data:`~robot_models.g1_constants.SHELL_CONTYPE`) besides the hands' grasp geoms. The small
            objects do not: the palm pads stand 4.5 cm proud of the palm, where a hand closing on a
            5 cm object holds it, and the hand's shell sphere fills the palm's hollow.
    """

    name: str
    shape: Shape
    half_size: Vec3
    mass_kg: float
    xy: tuple[float, float]
    rgba: Rgba
    touches_shell: bool = True

    def __post_init__(self) -> None:
        for axis, half in zip("xyz", self.half_size, strict=True):
            check_range(f"object {self.name} half size {axis}", half, 0.0, 0.5, low_open=True, unit="m")
        if self.shape is Shape.CYLINDER and self.half_size[0] != self.half_size[1]:
            raise ValueError(f"object {self.name}: a cylinder's half sizes x and y are its radius, got {self.half_size}")
        check_range(f"object {self.name} mass", self.mass_kg, 0.0, 20.0, low_open=True, unit="kg")


PICK_TABLE: Final = TableLayout("table_0", center_xy=(1.2, 0.0), half_size_xy=(0.3, 0.6))
PLACE_TABLE: Final = TableLayout("table_1", center_xy=(1.2, -2.8), half_size_xy=(0.3, 0.6))
TABLES: Final = (PICK_TABLE, PLACE_TABLE)

# On the first table, near its edge facing the robot. The box is 0.25 m wide along y (between the
# palms of a robot facing the table), 0.20 m deep and 0.15 m high.
BOX: Final = ObjectLayout("box", Shape.BOX, (0.10, 0.125, 0.075), 0.7, (1.02, 0.0), (0.85, 0.55, 0.25, 1.0))
CUBE: Final = ObjectLayout("cube", Shape.BOX, (0.0275, 0.0275, 0.0275), 0.1, (1.0, -0.35), (0.2, 0.45, 0.85, 1.0),
                           touches_shell=False)
CAN: Final = ObjectLayout("can", Shape.CYLINDER, (0.033, 0.033, 0.06), 0.3, (1.0, 0.35), (0.8, 0.15, 0.15, 1.0),
                          touches_shell=False)
OBJECTS: Final = (BOX, CUBE, CAN)
OBJECTS_TABLE: Final = PICK_TABLE  # the table the objects rest on at the keyframe


def object_rest_position(item: ObjectLayout, table: TableLayout = OBJECTS_TABLE) -> Vec3:
    """Centre of an upright object resting on a table top, world frame [m]."""
    return item.xy[0], item.xy[1], table.top_z + item.half_size[2]


def _add_table(world: mujoco.MjsBody, table: TableLayout) -> Obstacle:
    (x, y), (hx, hy) = table.center_xy, table.half_size_xy
    static = {"contype": 1, "conaffinity": 1 | names.SHELL_CONTYPE, "rgba": list(TABLE_RGBA)}
    half_thickness = TABLE_TOP_THICKNESS_M / 2
    world.add_geom(name=table.name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx, hy, half_thickness],
                   pos=[x, y, table.top_z - half_thickness], **static)
    leg_half_height = (table.top_z - TABLE_TOP_THICKNESS_M) / 2
    corners = [(sx, sy) for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)]
    for leg, (sx, sy) in zip(table.leg_names, corners, strict=True):
        world.add_geom(name=leg, type=mujoco.mjtGeom.mjGEOM_BOX,
                       size=[TABLE_LEG_HALF_WIDTH_M, TABLE_LEG_HALF_WIDTH_M, leg_half_height],
                       pos=[x + sx * (hx - TABLE_LEG_INSET_M), y + sy * (hy - TABLE_LEG_INSET_M), leg_half_height],
                       **static)
    return Obstacle(name=table.name, center_xy=(x, y), half_size_xy=(hx, hy), height=table.top_z,
                    geoms=(table.name, *table.leg_names))


def _add_object(world: mujoco.MjsBody, item: ObjectLayout) -> None:
    body = world.add_body(name=item.name, pos=list(object_rest_position(item)))
    body.add_freejoint(name=item.name)
    if item.shape is Shape.BOX:
        kind, size = mujoco.mjtGeom.mjGEOM_BOX, list(item.half_size)
    else:
        kind, size = mujoco.mjtGeom.mjGEOM_CYLINDER, [item.half_size[0], item.half_size[2], 0.0]
    body.add_geom(name=item.name, type=kind, size=size, mass=item.mass_kg, condim=OBJECT_CONDIM,
                  friction=list(OBJECT_FRICTION), solref=list(OBJECT_SOLREF), contype=1,
                  conaffinity=1 | names.SHELL_CONTYPE if item.touches_shell else 1, rgba=list(item.rgba))


def add_tables_and_objects(spec: mujoco.MjSpec) -> tuple[tuple[Obstacle, ...], tuple[str, ...]]:
    """Put the tables and the objects in the G1's spec (before compiling).

    Returns:
        The tables as obstacles (for the navigation map and the entities) and the objects' names.
    """
    obstacles = tuple(_add_table(spec.worldbody, table) for table in TABLES)
    for item in OBJECTS:
        _add_object(spec.worldbody, item)
    add_palm_pads(spec)  # flat pads to squeeze the box between, past the tucked thumbs (robot_models.g1_palms)
    return obstacles, tuple(item.name for item in OBJECTS)
