"""ROS message types in one place: type-name constants, cached type stores, header builder.

:func:`typestore_for` returns a rosbags :class:`~rosbags.typesys.store.Typestore` for ROS 1 (Noetic) or
ROS 2 (Humble) with the project's custom definitions (``configs/msg/<pkg>/msg/<Name>.msg``:
``scanbrick_msgs/msg/RawFrame``, ``can_msgs/msg/Frame``, ``nmea_msgs/msg/Sentence``) registered.
The stores are cached per ROS version; treat them as read-only.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from autosar_cli.config import MSG_DIR

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

RAW_FRAME = "scanbrick_msgs/msg/RawFrame"
CAN_FRAME = "can_msgs/msg/Frame"
NMEA_SENTENCE = "nmea_msgs/msg/Sentence"
NAV_SAT_FIX = "sensor_msgs/msg/NavSatFix"
NAV_SAT_STATUS = "sensor_msgs/msg/NavSatStatus"
IMU = "sensor_msgs/msg/Imu"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
TWIST_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/TwistWithCovarianceStamped"
HEADER = "std_msgs/msg/Header"
TIME = "builtin_interfaces/msg/Time"

CUSTOM_TYPES: tuple[str, ...] = (RAW_FRAME, CAN_FRAME, NMEA_SENTENCE)

_STORES = {1: Stores.ROS1_NOETIC, 2: Stores.ROS2_HUMBLE}


def custom_msg_definitions(msg_dir: Path = MSG_DIR) -> dict[str, str]:
    """Return ``{"<pkg>/msg/<Name>": definition text}`` for every ``<pkg>/msg/*.msg`` under ``msg_dir``."""
    defs: dict[str, str] = {}
    for path in sorted(msg_dir.glob("*/msg/*.msg")):
        defs[f"{path.parent.parent.name}/msg/{path.stem}"] = path.read_text(encoding="utf-8")
    return defs


@cache
def typestore_for(ros_version: int) -> Typestore:
    """Type store for ROS ``ros_version`` (1: Noetic, 2: Humble) plus the project's custom messages.

    Cached per version: the same object is returned on every call, do not register more types on it.
    """
    try:
        store_id = _STORES[ros_version]
    except KeyError:
        raise ValueError(f"ros_version must be 1 or 2, got {ros_version!r}") from None
    typestore = get_typestore(store_id)
    defs = custom_msg_definitions()
    missing = sorted(set(CUSTOM_TYPES) - set(defs))
    if missing:
        raise FileNotFoundError(f"custom message definitions missing under {MSG_DIR}: {', '.join(missing)}")
    types: dict[str, Any] = {}
    for name, text in defs.items():
        types.update(get_types_from_msg(text, name))
    typestore.register(types)
    return typestore


def ros_version_of(typestore: Typestore) -> int:
    """1 if ``typestore`` has ROS 1 headers (with ``seq``), else 2."""
    return 1 if "seq" in typestore.types[HEADER].__dataclass_fields__ else 2


def stamp(typestore: Typestore, t_ns: int) -> object:
    """``builtin_interfaces/msg/Time`` for integer nanoseconds ``t_ns`` (>= 0)."""
    if t_ns < 0:
        raise ValueError(f"negative time stamp {t_ns} ns")
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return typestore.types[TIME](sec=sec, nanosec=nanosec)


def header(typestore: Typestore, t_ns: int, frame_id: str) -> object:
    """``std_msgs/msg/Header`` for ``typestore``: stamp ``t_ns`` (ns), ``frame_id``; ROS 1 ``seq`` is 0."""
    cls = typestore.types[HEADER]
    if "seq" in cls.__dataclass_fields__:
        return cls(seq=0, stamp=stamp(typestore, t_ns), frame_id=frame_id)
    return cls(stamp=stamp(typestore, t_ns), frame_id=frame_id)
