"""Names and figures shared by the model, the tasks and the environment.

Every joint, actuator, camera and site name lives here once; units are in the names
(``_M`` metres, ``_RAD`` radians, ``_DEG`` degrees, ``_S`` seconds).
"""

from __future__ import annotations

import math

# Joints and their position servos, in this order everywhere (actions, agent_pos).
JOINT_NAMES: tuple[str, ...] = (
    "shoulder_pan",
    "shoulder_lift",
    "elbow_flex",
    "wrist_flex",
    "wrist_roll",
    "gripper",
)
ARM_JOINT_NAMES: tuple[str, ...] = JOINT_NAMES[:5]
GRIPPER_JOINT_NAME = "gripper"

# Cameras, in the fixed order in which observations list them.
CAMERA_NAMES: tuple[str, ...] = ("overview_camera", "front_camera", "wrist_camera")
CAMERA_CONFIGS: dict[str, tuple[str, ...]] = {
    "front_only": ("front_camera",),
    "front_wrist": ("front_camera", "wrist_camera"),
    "all": CAMERA_NAMES,
}
DEFAULT_CAMERA_CONFIG = "front_wrist"
DEFAULT_RENDER_CAMERA = "front_camera"

# Sites, geoms and bodies the tasks read.
GRIPPER_SITE = "gripperframe"
GRASP_SITE = "grasp_center"
CUBE_JOINT = "cube"
CUBE_GEOM = "cube"
CUBE_SITE = "cube"
GOAL_SITE = "goal"
JAW_PAD_GEOMS: tuple[str, str] = ("fixed_jaw_pad", "moving_jaw_pad")
JAW_TOUCH_SENSORS: tuple[str, str] = ("fixed_jaw_touch", "moving_jaw_touch")
HOME_KEYFRAME = "home"

# Timing: physics at 500 Hz, control at 50 Hz.
PHYSICS_TIMESTEP_S = 0.002
N_SUBSTEPS = 10
CONTROL_TIMESTEP_S = PHYSICS_TIMESTEP_S * N_SUBSTEPS
RENDER_FPS = 50

# Scene figures.
ROBOT_BASE_POS_M: tuple[float, float, float] = (0.0, 0.15, 0.0)
ROBOT_BASE_YAW_DEG = 90.0
TABLE_SIZE_M: tuple[float, float] = (0.64, 0.45)
TABLE_TOP_Z_M = 0.0
CUBE_SIZE_M = 0.03
CUBE_HALF_M = CUBE_SIZE_M / 2
GOAL_RADIUS_M = 0.04

# The 3 x 3 grid of cube start cells. Cell i sits at GRID_CENTER + (dx, dy) with
# dx = GRID_DX_M[i // 3] and dy = GRID_DY_M[i % 3].
GRID_CENTER_M: tuple[float, float] = (0.0, 0.35)
GRID_DX_M: tuple[float, float, float] = (-0.10, 0.0, 0.10)
GRID_DY_M: tuple[float, float, float] = (-0.075, 0.0, 0.075)
NUM_GRID_CELLS = 9
CUBE_YAWS_DEG: tuple[float, ...] = (0.0, 30.0, 45.0, 60.0)


def grid_cell_offset(cell: int) -> tuple[float, float]:
    """Offset (dx, dy) in metres of grid cell ``cell`` from the grid centre."""
    return GRID_DX_M[cell // 3], GRID_DY_M[cell % 3]


def grid_cell_position(cell: int) -> tuple[float, float]:
    """World (x, y) in metres of the centre of grid cell ``cell``."""
    dx, dy = grid_cell_offset(cell)
    return GRID_CENTER_M[0] + dx, GRID_CENTER_M[1] + dy


# Success and reward figures.
LIFT_HEIGHT_M = 0.05  # lift task: cube bottom this far above the table
PLACE_HEIGHT_TOL_M = 0.005  # pick-and-place: cube bottom within this of the pad top
GOAL_TOP_Z_M = 0.001
DEG = math.pi / 180.0
