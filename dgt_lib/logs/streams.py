"""What DGT-Map needs of a drive log, as arrays: the robot's pose over time (from an
odometry topic, or from ``/tf``), its commanded forward speed, and where its camera sat
when each RGB-D frame was taken (the camera's mount from ``/tf_static`` or ``/tf``).

Poses between two samples are interpolated (position linearly, attitude by slerp); a
log whose streams never share a moment is refused.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from dgt_lib.logs.bag import BadLogError, messages, pose_matrix

ODOMETRY = ("nav_msgs/msg/Odometry",)
TRANSFORMS = ("tf2_msgs/msg/TFMessage",)
COMMANDS = ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped")
CAMERA_INFO = ("sensor_msgs/msg/CameraInfo",)


@dataclass(frozen=True)
class LogTopics:
    """Which topics and frames of a log hold what (the defaults are a RealSense camera's
    and Nav2's names). ``odom`` empty: the pose is ``world_frame`` → ``base_frame`` on
    ``/tf``. The depth image must be registered to the colour camera (an aligned-depth
    topic), whose ``CameraInfo`` gives the intrinsics and the camera's frame."""

    rgb: str = "/camera/color/image_raw"
    depth: str = "/camera/aligned_depth_to_color/image_raw"
    camera_info: str = "/camera/color/camera_info"
    odom: str = "/odom"
    cmd: str = "/cmd_vel"
    world_frame: str = "odom"
    base_frame: str = "base_link"


DEFAULT_TOPICS = LogTopics()
"""The topics and frames a log is read with unless told otherwise."""


class Trajectory:
    """Poses ``(N, 4, 4)`` (world from a frame) at increasing times ``(N,)`` [s], with the
    body's angular rate [°/s] where the log gives it (odometry's twist)."""

    def __init__(self, time_s: np.ndarray, poses: np.ndarray, what: str,
                 rate_dps: np.ndarray | None = None):
        order = np.argsort(time_s, kind="stable")
        t, p = np.asarray(time_s, float)[order], np.asarray(poses, float)[order]
        keep = np.concatenate([[True], np.diff(t) > 0])
        self.time_s, self.poses, self.what = t[keep], p[keep], what
        self.rate_dps = None if rate_dps is None else np.asarray(rate_dps)[order][keep]
        if len(self.time_s) == 0:
            raise BadLogError(f"{what}: no poses in the log")

    def at(self, t: np.ndarray | float) -> np.ndarray:
        """The poses at times ``t`` (clipped to the recorded span), ``(…, 4, 4)``."""
        from scipy.spatial.transform import Rotation, Slerp

        t = np.clip(np.asarray(t, float), self.time_s[0], self.time_s[-1])
        out = np.zeros((*t.shape, 4, 4))
        out[..., 3, 3] = 1.0
        for k in range(3):
            out[..., k, 3] = np.interp(t, self.time_s, self.poses[:, k, 3])
        if len(self.time_s) == 1:
            out[..., :3, :3] = self.poses[0, :3, :3]
        else:
            slerp = Slerp(self.time_s, Rotation.from_matrix(self.poses[:, :3, :3]))
            out[..., :3, :3] = slerp(t.ravel()).as_matrix().reshape(*t.shape, 3, 3)
        return out

    def covers(self, t: float, slack_s: float = 0.2) -> bool:
        return self.time_s[0] - slack_s <= t <= self.time_s[-1] + slack_s


class TransformTree:
    """The ``/tf`` and ``/tf_static`` transforms of a log, looked up along the frames'
    parent chain at a time (a static edge holds at every time)."""

    def __init__(self) -> None:
        self.parent: dict[str, str] = {}
        self.edges: dict[str, list[tuple[float, np.ndarray]]] = {}
        self.static: set[str] = set()

    def add(self, reader: Any, topic: str, static: bool) -> None:
        if topic not in reader.topics:
            return
        for _, msg in messages(reader, topic, TRANSFORMS):
            for tr in msg.transforms:
                child = tr.child_frame_id.lstrip("/")
                self.parent[child] = tr.header.frame_id.lstrip("/")
                stamp = tr.header.stamp.sec + 1e-9 * tr.header.stamp.nanosec
                self.edges.setdefault(child, []).append(
                    (stamp, pose_matrix(tr.transform.translation, tr.transform.rotation)))
                if static:
                    self.static.add(child)

    def _to_root(self, frame: str) -> list[str]:
        chain = [frame]
        while chain[-1] in self.parent and len(chain) < 64:
            chain.append(self.parent[chain[-1]])
        return chain

    def trajectory(self, parent: str, child: str) -> Trajectory:
        """``parent`` from ``child`` at every time a non-static edge between them was
        recorded; :class:`BadLogError` when the frames are not connected."""
        up, down = self._to_root(child), self._to_root(parent)
        if up[-1] != down[-1]:
            frames = ", ".join(sorted(set(self.parent) | set(self.parent.values()))) or "none"
            raise BadLogError(f"no transform from {parent} to {child} in /tf or /tf_static "
                              f"(frames there: {frames})")
        edges = [f for f in up + down if f in self.edges and f not in self.static]
        times = np.unique(np.concatenate([[0.0]] + [[s for s, _ in self.edges[f]]
                                                    for f in edges]))
        if edges:
            times = times[times > 0]
        root_child = self._chain(up[:-1], times)
        root_parent = self._chain(down[:-1], times)
        return Trajectory(times, np.linalg.inv(root_parent) @ root_child, f"{parent}→{child}")

    def _chain(self, frames: list[str], times: np.ndarray) -> np.ndarray:
        out = np.broadcast_to(np.eye(4), (len(times), 4, 4)).copy()
        for frame in reversed(frames):  # root first: T_root_frame = Π T_parent_child
            samples = self.edges[frame]
            edge = Trajectory(np.array([s for s, _ in samples]),
                              np.stack([m for _, m in samples]), frame)
            out = out @ edge.at(times)
        return out


def robot_trajectory(reader: Any, topics: LogTopics, tree: TransformTree) -> Trajectory:
    """World from the robot's base over time: the odometry topic's poses, or ``/tf``."""
    if not topics.odom:
        return tree.trajectory(topics.world_frame, topics.base_frame)
    stamps, poses, rates = [], [], []
    for t, msg in messages(reader, topics.odom, ODOMETRY):
        stamps.append(t)
        poses.append(pose_matrix(msg.pose.pose.position, msg.pose.pose.orientation))
        w = msg.twist.twist.angular
        rates.append(np.degrees(np.hypot(np.hypot(w.x, w.y), w.z)))
    if not poses:
        raise BadLogError(f"{topics.odom}: no messages")
    return Trajectory(np.array(stamps), np.stack(poses), topics.odom, np.array(rates))


def commanded_speed(reader: Any, topic: str) -> tuple[np.ndarray, np.ndarray]:
    """(times [s], forward speed commanded [m/s]) of the velocity command topic."""
    out = [(t, (msg.twist if hasattr(msg, "twist") else msg).linear.x)
           for t, msg in messages(reader, topic, COMMANDS)]
    if not out:
        raise BadLogError(f"{topic}: no velocity commands in the log")
    arr = np.array(out)
    order = np.argsort(arr[:, 0], kind="stable")
    return arr[order, 0], arr[order, 1]


def camera_model(reader: Any, topic: str) -> tuple[np.ndarray, str]:
    """(fx, fy, cx, cy) [px] and the camera's frame, from the first ``CameraInfo``."""
    for _, msg in messages(reader, topic, CAMERA_INFO):
        k = np.asarray(msg.k, float)
        if not (k[0] > 0 and k[4] > 0):
            raise BadLogError(f"{topic}: the camera matrix K has no focal length ({k})")
        return np.array([k[0], k[4], k[2], k[5]]), msg.header.frame_id.lstrip("/")
    raise BadLogError(f"{topic}: no CameraInfo message, so the depth cannot be back-projected")


PAIR_S = 0.05
"""A depth image and the colour image nearest it in time pair up within this [s]."""


def image_stamps(reader: Any, topic: str) -> np.ndarray:
    """The header stamps [s] of an image topic, in increasing order."""
    from dgt_lib.logs.bag import IMAGE_TYPES

    return np.array(sorted(t for t, _ in messages(reader, topic, IMAGE_TYPES)))


def frame_pairs(reader: Any, topics: LogTopics) -> dict[float, float]:
    """{depth stamp: the colour stamp nearest it} for the depth images with a colour image
    within :data:`PAIR_S` (a dropped image leaves its partner out)."""
    rgb, depth = image_stamps(reader, topics.rgb), image_stamps(reader, topics.depth)
    if len(rgb) == 0 or len(depth) == 0:
        raise BadLogError(f"no images on {topics.rgb if len(rgb) == 0 else topics.depth}")
    nearest = rgb[np.clip(np.searchsorted(rgb, depth), 1, len(rgb) - 1) - 1]
    after = rgb[np.clip(np.searchsorted(rgb, depth), 0, len(rgb) - 1)]
    nearest = np.where(np.abs(after - depth) < np.abs(nearest - depth), after, nearest)
    return {float(d): float(r) for d, r in zip(depth, nearest, strict=True)
            if abs(d - r) <= PAIR_S}


def paired_frames(reader: Any, topics: LogTopics, pairs: dict[float, float]
                  ) -> Iterator[tuple[float, np.ndarray, np.ndarray]]:
    """(depth stamp, RGB (h, w, 3) uint8, depth (h, w) [m]) for each pair of stamps of
    :func:`frame_pairs` given; read in one pass, holding only the images still waiting
    for their partner."""
    from dgt_lib.logs.bag import IMAGE_TYPES, image_array, stamp_s

    want_rgb = {r: d for d, r in pairs.items()}
    infos = [reader.topics[topics.rgb], reader.topics[topics.depth]]
    rgbs: dict[float, np.ndarray] = {}
    depths: dict[float, np.ndarray] = {}
    for con, _, raw in reader.messages(connections=[c for i in infos for c in i.connections]):
        if con.msgtype not in IMAGE_TYPES:
            raise BadLogError(f"{con.topic} is a {con.msgtype}; expected an image")
        msg = reader.deserialize(raw, con.msgtype)
        t = stamp_s(msg.header.stamp)
        if con.topic == topics.depth and t in pairs:
            depths[t] = image_array(msg)
        elif con.topic == topics.rgb and t in want_rgb:
            rgbs[want_rgb[t]] = image_array(msg)
        for ready in [s for s in depths if s in rgbs]:
            yield ready, rgbs.pop(ready), depths.pop(ready)
