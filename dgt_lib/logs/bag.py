"""A robot's drive log, read: ROS 2 bags (an MCAP or sqlite3 file, or a bag directory with
its ``metadata.yaml``) and ROS 1 ``.bag`` files, through ``rosbags`` — pure Python, one
library for every format, writing as well as reading, and the standard message types built
in, so no ROS installation is needed (``pip install 'dgt-kit[logs]'``).

Every problem with a log is a :class:`BadLogError` whose message is one line naming it and,
where a topic is the problem, the topics the log has.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dgt_lib.core.faults import SetupError


class BadLogError(ValueError):
    """A log the kit cannot use; the message says why in one line."""


@functools.cache
def typestore() -> Any:
    """rosbags' ROS 2 Humble message types (the standard ones every log here uses)."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise SetupError("reading and writing drive logs needs the 'rosbags' package: "
                         "pip install 'dgt-kit[logs]' (or pip install rosbags)") from None
    return get_typestore(Stores.ROS2_HUMBLE)


@contextlib.contextmanager
def open_log(path: str | Path) -> Iterator[Any]:
    """The log at ``path`` open for reading (rosbags' ``AnyReader``); :class:`BadLogError`
    when it is missing, not a bag, truncated beyond reading, or empty."""
    path = Path(path)
    typestore()
    from rosbags.highlevel import AnyReader

    if not path.exists():
        raise BadLogError(f"{path}: no such file or directory")
    try:
        reader = AnyReader([path], default_typestore=typestore())
        reader.open()
    except Exception as exc:  # rosbags raises its own errors, and OSError/KeyError below
        raise BadLogError(f"{path}: not a readable ROS bag ({type(exc).__name__}: "
                          f"{str(exc)[:120]})") from None
    try:
        if reader.message_count == 0:
            raise BadLogError(f"{path}: the log holds no messages")
        yield reader
    finally:
        reader.close()


@dataclass(frozen=True)
class Topic:
    """One topic of a log: its name, message type, message count and mean rate [Hz]."""

    name: str
    msgtype: str
    count: int
    rate_hz: float


def log_topics(reader: Any) -> list[Topic]:
    """Every topic of an open log, by name, with its mean rate from the bag's timestamps."""
    stamps: dict[str, list[int]] = {}
    for con, t_ns, _ in reader.messages():
        stamps.setdefault(con.topic, []).append(t_ns)
    out = []
    for name, info in sorted(reader.topics.items()):
        t = stamps.get(name, [])
        span = (max(t) - min(t)) * 1e-9 if len(t) > 1 else 0.0
        out.append(Topic(name, info.msgtype, len(t), (len(t) - 1) / span if span > 0 else 0.0))
    return out


def topic_list(reader: Any) -> str:
    """The log's topics and their types, for an error message."""
    return ", ".join(f"{name} ({info.msgtype})" for name, info in sorted(reader.topics.items()))


def messages(reader: Any, topic: str, types: tuple[str, ...]) -> Iterator[tuple[float, Any]]:
    """(time [s], message) of ``topic``, whose type must be one of ``types``; the time is
    the message's header stamp when it has one (the sensor's clock), else the bag's."""
    info = reader.topics.get(topic)
    if info is None:
        raise BadLogError(f"no topic {topic} in the log; it has: {topic_list(reader)}")
    if info.msgtype not in types:
        raise BadLogError(f"{topic} is a {info.msgtype}; expected {' or '.join(types)}")
    for con, t_ns, raw in reader.messages(connections=info.connections):
        try:
            msg = reader.deserialize(raw, con.msgtype)
        except Exception as exc:  # a truncated or corrupt message
            raise BadLogError(f"{topic}: a message cannot be decoded ({exc})") from None
        header = getattr(msg, "header", None)
        yield (stamp_s(header.stamp) if header is not None else t_ns * 1e-9), msg


def stamp_s(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` in seconds."""
    return stamp.sec + 1e-9 * stamp.nanosec


IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")


def image_array(msg: Any) -> np.ndarray:
    """A ``sensor_msgs/Image`` or ``CompressedImage`` as an array: colour (h, w, 3) uint8
    RGB (rgb8, bgr8, mono8, or any format OpenCV decodes), depth (h, w) float32 metres
    with NaN where there is none (16UC1 in millimetres, 0 = none; 32FC1 in metres)."""
    import cv2

    if not hasattr(msg, "encoding"):  # CompressedImage: png (16-bit depth too), jpeg, …
        img = cv2.imdecode(np.asarray(msg.data, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise BadLogError(f"a compressed image ({msg.format}) cannot be decoded")
        if img.dtype == np.uint16:
            return _depth(img.astype(np.float32) * 1e-3)
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB if img.ndim == 3 else cv2.COLOR_GRAY2RGB)
    kinds = {"rgb8": (np.uint8, 3), "bgr8": (np.uint8, 3), "mono8": (np.uint8, 1),
             "16UC1": (np.uint16, 1), "mono16": (np.uint16, 1), "32FC1": (np.float32, 1)}
    if msg.encoding not in kinds:
        raise BadLogError(f"image encoding {msg.encoding!r} is not one of {', '.join(kinds)}")
    dtype, channels = kinds[msg.encoding]
    dtype = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    row = np.frombuffer(np.asarray(msg.data, np.uint8).tobytes(), np.uint8)
    rows = row.reshape(msg.height, msg.step)[:, :msg.width * channels * dtype.itemsize]
    img = rows.copy().view(dtype).reshape(msg.height, msg.width, channels)
    if msg.encoding == "32FC1":
        return _depth(img[..., 0].astype(np.float32))
    if channels == 1 and dtype.itemsize == 2:
        return _depth(img[..., 0].astype(np.float32) * 1e-3)
    return np.repeat(img, 3, axis=2) if channels == 1 else (
        img[..., ::-1].copy() if msg.encoding == "bgr8" else img)


def _depth(metres: np.ndarray) -> np.ndarray:
    """Depth [m] with NaN where a sensor gives none (0, negative or not finite)."""
    return np.where(np.isfinite(metres) & (metres > 0), metres, np.nan).astype(np.float32)


def pose_matrix(position: Any, orientation: Any) -> np.ndarray:
    """The 4 × 4 transform of a ROS position / translation and quaternion."""
    from scipy.spatial.transform import Rotation

    out = np.eye(4)
    q = [orientation.x, orientation.y, orientation.z, orientation.w]
    if not np.isfinite(q).all() or np.linalg.norm(q) < 1e-6:
        raise BadLogError(f"a pose has an invalid quaternion {q}")
    out[:3, :3] = Rotation.from_quat(q).as_matrix()
    out[:3, 3] = position.x, position.y, position.z
    return out
