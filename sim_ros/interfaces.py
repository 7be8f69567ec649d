"""ROS interface types by name: their Python classes and their ``ros2msg`` definitions (nested types appended,
as rosbag2 stores them and Foxglove reads them), for code that handles messages raw (recordings, bridges)."""

from __future__ import annotations

import importlib
import pathlib
import re
import sys
from typing import Any

PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32",
              "int64", "uint64", "string", "wstring"}
# Interfaces installed without their .msg text (only .idl/.json): the definitions, verbatim.
_KNOWN_DEFINITIONS = {"unique_identifier_msgs/msg/UUID": "uint8[16] uuid\n"}
_SEPARATOR = "=" * 80


def _share_dirs() -> list[pathlib.Path]:
    return [pathlib.Path(sys.prefix) / "share"]


def _read_interface(full_name: str) -> str:
    """Text of ``pkg/msg/Type`` or of a part of an action (``pkg/action/Walk_Feedback``)."""
    if full_name in _KNOWN_DEFINITIONS:
        return _KNOWN_DEFINITIONS[full_name]
    package, kind, name = full_name.split("/")
    for share in _share_dirs():
        if kind == "action":
            base, _, part = name.rpartition("_")
            action_file = share / package / "action" / f"{base}.action"
            if action_file.exists():
                goal, result, feedback = [*re.split(r"^---\s*$", action_file.read_text(), flags=re.MULTILINE), "", ""][:3]
                if part == "Goal":
                    return goal
                if part == "Result":
                    return result
                if part == "Feedback":
                    return feedback
                if part == "FeedbackMessage":
                    return f"unique_identifier_msgs/UUID goal_id\n{package}/action/{base}_Feedback feedback\n"
        path = share / package / kind / f"{name}.msg"
        if path.exists():
            return path.read_text()
    raise KeyError(f"no definition found for {full_name}")


def _dependencies(package: str, text: str) -> list[str]:
    found = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        field_type = line.split()[0]
        base = re.sub(r"\[.*\]$", "", field_type)
        base = re.sub(r"<=\d+$", "", base)
        if base in PRIMITIVES:
            continue
        if base == "Header":
            found.append("std_msgs/msg/Header")
        elif "/" in base:
            parts = base.split("/")
            found.append(base if len(parts) == 3 else f"{parts[0]}/msg/{parts[1]}")
        else:
            found.append(f"{package}/msg/{base}")
    return found


def message_definition(full_name: str) -> str:
    """The ``ros2msg`` definition of a type with every nested type appended, as rosbag2 stores it."""
    main = _read_interface(full_name)
    seen: list[str] = []
    queue = _dependencies(full_name.split("/")[0], main)
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.append(dep)
        queue.extend(_dependencies(dep.split("/")[0], _read_interface(dep)))
    parts = [main.rstrip("\n")]
    for dep in seen:
        parts.append(f"{_SEPARATOR}\nMSG: {dep}\n{_read_interface(dep).rstrip()}")
    return "\n".join(parts) + "\n"


def import_type(full_name: str) -> Any:
    """Python class of ``pkg/msg/Type`` or ``pkg/action/Walk_FeedbackMessage``."""
    package, kind, name = full_name.split("/")
    module = importlib.import_module(f"{package}.{kind}")
    if kind == "action" and not hasattr(module, name):
        base, _, part = name.rpartition("_")
        return getattr(getattr(module, base).Impl, part)
    return getattr(module, name)



def matching_qos(publishers: list[Any], depth: int = 1000) -> Any:
    """A subscription QoS that hears every publisher of a topic: transient local when all of them are (a latched
    topic's last message comes at once), best effort when any of them is; reliable and volatile otherwise."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    qos = QoSProfile(depth=depth)
    if publishers and all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers):
        qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
    if any(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers):
        qos.reliability = ReliabilityPolicy.BEST_EFFORT
    return qos
