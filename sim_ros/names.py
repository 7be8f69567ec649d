"""The ROS names and QoS profiles the project's nodes share, each defined once.

Every name is relative: a bring-up started under a namespace (``bringup --namespace r1``, or
``--ros-args -r __ns:=/r1``) has all of them under it (``/r1/joint_states``, ``/r1/sim/skill_command``),
its own ``clock`` and its own ``tf`` too; in the root namespace they are the usual ``/joint_states``,
``/clock``, ``/tf``. The docstrings below write them as they are in the root namespace.

``/sim`` publishes the streams every other node reads; the ``/sim/...`` topics below are the
simulator's side of a device node or an action server (only the project's own nodes use them). Both
ends of a topic take its name and its QoS from here, so they cannot drift apart. A node's own
interfaces (its services, actions and private ``~/`` topics) are named where the node is.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, QoSProfile

SIM_NODE = "sim"  # the simulator's node name (/sim); the servers ask it for its robot parameter

# ----- streams of /sim --------------------------------------------------------------------------
CLOCK_TOPIC = "clock"
JOINT_STATES_TOPIC = "joint_states"
ODOM_TOPIC = "odom"
TF_TOPIC = "tf"
TF_STATIC_TOPIC = "tf_static"
OBJECTS_TOPIC = "objects"
MAP_TOPIC = "map"
PLAN_TOPIC = "plan"  # the running navigation's path (Nav2's name), latched
GOAL_MARKERS_TOPIC = "goal_markers"  # the running goals drawn for a viewer, latched
ROBOT_DESCRIPTION_TOPIC = "robot_description"  # the robot as simulated, URDF (latched, as robot_state_publisher's)
IMU_TOPIC = "imu"
CMD_VEL_TOPIC = "cmd_vel"
CMD_VEL_STAMPED_TOPIC = "cmd_vel_stamped"


def wrench_topic(sensor: str) -> str:
    """A force/torque sensor's wrench, from ``/sim``: a foot's, or a wrist's less the offset ``/hand_sensors`` calibrated."""
    return f"{sensor}/wrench"


def image_topic(camera: str) -> str:
    return f"{camera}/image_raw"


def camera_info_topic(camera: str) -> str:
    return f"{camera}/camera_info"


# ----- /sim's side of the servers and device nodes ----------------------------------------------
SKILL_COMMAND_TOPIC = "sim/skill_command"  # action servers -> /sim: START, CANCEL, UPDATE of a goal
SKILL_STATE_TOPIC = "sim/skill_state"  # /sim -> action servers: each goal's status, feedback and result
HAND_SENSORS_TOPIC = "sim/hand_sensors"  # /sim -> /hand_sensors: raw wrist force/torque, hand speed and contact
HAND_OFFSETS_TOPIC = "sim/hand_sensors/offsets"  # /hand_sensors -> /sim: the calibrated offsets (latched; wrenches only)
HAND_OFFSETS_APPLIED_TOPIC = "sim/hand_sensors/offsets_applied"  # /sim -> /hand_sensors: the offsets /sim now subtracts (latched)
BATTERY_TOPIC = "sim/battery"  # /sim -> /power: the battery drained in the control step
BATTERY_CONFIG_TOPIC = "sim/battery_config"  # /power -> /sim: the battery model's settings (latched)
WORLD_TOPIC = "sim/world"  # /sim -> the action servers: the scene loaded (latched simulation_interfaces WorldResource)


def camera_settings_topic(camera: str) -> str:
    """/camera -> /sim: the camera's settings (latched)."""
    return f"sim/{camera}/settings"


def camera_tilt_topic(camera: str) -> str:
    """/head -> /sim: the tilt of a camera's mount [rad] (latched)."""
    return f"sim/{camera}/tilt"


# ----- QoS profiles -----------------------------------------------------------------------------
# The latest value, kept for a reader that comes later (a restarted /sim takes its devices' settings).
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
MAX_STREAM_RATE_HZ = 500.0  # the fastest /clock and /joint_states rate /sim allows [Hz of sim time]
STREAM_HISTORY_S = 10.0  # /clock and /joint_states a reliable writer keeps for a stalled reader [s of sim time]
STREAM_HISTORY_DEPTH = int(STREAM_HISTORY_S * MAX_STREAM_RATE_HZ)  # 5000 samples: Fast DDS's default max_samples
STREAMS = QoSProfile(depth=STREAM_HISTORY_DEPTH)  # /clock and /joint_states
SKILL_QOS = QoSProfile(depth=100)  # the goal protocol's topics, both ways
# An action's feedback, on the servers' publishers and the project's clients. rclpy's default keeps 10 messages:
# a client held up for a moment lost some (a free-running sim sends feedback many times faster than real time).
# Transient local: a goal's first feedback published before the server's side of discovery had matched a new
# client's reader reaches it once matched (a lock-stepped run waits for that first message, and /sim, paused,
# sends no other: a fresh run once waited 30 s for it). Volatile readers (ros2cli's) are served as before.
FEEDBACK_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
