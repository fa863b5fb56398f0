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
TABLE_GEOM = "tabletop"
TABLE_BODY = "table"
ROBOT_BASE_BODY = "base"
JAW_PAD_GEOMS: tuple[str, str] = ("fixed_jaw_pad", "moving_jaw_pad")
JAW_TOUCH_SENSORS: tuple[str, str] = ("fixed_jaw_touch", "moving_jaw_touch")
HOME_KEYFRAME = "home"
ROBOT_BASE_BODY = "base"

# Timing: physics at 500 Hz, control at 50 Hz.
PHYSICS_TIMESTEP_S = 0.002
N_SUBSTEPS = 10
CONTROL_TIMESTEP_S = PHYSICS_TIMESTEP_S * N_SUBSTEPS
RENDER_FPS = 50

# Scene figures.
ROBOT_BASE_POS_M: tuple[float, float, float] = (0.0, 0.15, 0.0)
ROBOT_BASE_YAW_DEG = 90.0
SHOULDER_PAN_OFFSET_M = 0.0388353
"""The shoulder pan axis's offset from the robot base's centre along the base's x axis
(the ``shoulder`` body's position in ``so101.xml``)."""
PAN_AXIS_XY_M: tuple[float, float] = (
    ROBOT_BASE_POS_M[0],
    ROBOT_BASE_POS_M[1] + SHOULDER_PAN_OFFSET_M,
)
"""Where the shoulder pan axis meets the table (m): the base faces +y, so the offset is along y."""
TABLE_SIZE_M: tuple[float, float] = (0.64, 0.45)
TABLE_TOP_Z_M = 0.0

# Physics safety: an object farther than this from the origin was thrown by a diverging
# simulation (the floor is 0.75 m below the table).
POSITION_BOUND_M = 5.0
DEG = math.pi / 180.0
