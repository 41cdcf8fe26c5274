"""A drive log to learn and test with: one of the kit's collection drives, written as a
robot would record it — a standard ROS 2 bag with the RGB-D camera at 10 Hz, odometry (or
``/tf``) at 50 Hz and the velocity command at 20 Hz, the camera's mount on ``/tf_static``,
header stamps with a few milliseconds of jitter, a few dropped frames and noisy odometry.

The drive itself is :func:`~dgt_lib.perception.episodes.run_episode`'s, so the log comes
with the episode the pipeline would have made of it (its rows and its BEV statistics),
to compare what ``dgt log ingest`` makes of the log against.
"""

from __future__ import annotations

import math
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dgt_lib.core.config import CollectConfig
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.logs.bag import typestore
from dgt_lib.logs.streams import DEFAULT_TOPICS, LogTopics
from dgt_lib.perception.episodes import Episode, OUSteering, random_steer, run_episode
from dgt_lib.world.rendering import onboard_camera_pose, simulator, terrain_renderer
from dgt_lib.world.simulator import CONTROL_DT_S, VehicleState
from dgt_lib.world.worlds import World

EPOCH_S = 1_700_000_000
"""Wall-clock second the log's stamps start at (a real robot's clock)."""
STOP_S = 3.0
"""How long the robot stands, commanded 0, between two runs of one log [s]."""


@dataclass(frozen=True)
class Realism:
    """How far the log departs from the simulator's truth: sensor rates [Hz], stamp jitter
    [s] (standard deviation), the share of camera images dropped, odometry noise (position
    [m], attitude [rad], standard deviations)."""

    camera_hz: float = 10.0
    odometry_hz: float = 50.0
    command_hz: float = 20.0
    jitter_s: float = 0.002
    dropped: float = 0.02
    position_noise_m: float = 0.01
    attitude_noise_rad: float = 0.002


REALISM = Realism()
"""A log's default departures from the truth."""


def base_pose(st: VehicleState) -> np.ndarray:
    """World from the robot's base (x ahead, y left, z up) [m], the state's pose."""
    cy, sy, cp, sp = math.cos(st.yaw), math.sin(st.yaw), math.cos(st.pitch), math.sin(st.pitch)
    cr, sr = math.cos(st.roll), math.sin(st.roll)
    out = np.eye(4)
    out[:3, :3] = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]) @ np.array(
        [[cp, 0, -sp], [0, 1, 0], [sp, 0, cp]]) @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    out[:3, 3] = st.position
    return out


OPTICAL_FROM_GL = np.diag([1.0, -1.0, -1.0])
"""The kit's camera axes (x right, y up, z behind) to ROS's optical ones (y down, z ahead)."""


class _BagWriter:
    """The messages of one log, written to a rosbag2 (MCAP or sqlite3)."""

    def __init__(self, directory: Path, storage: str, topics: LogTopics, compressed: bool):
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.ts, self.t = typestore(), typestore().types
        plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
        self.writer = Writer(directory, version=9, storage_plugin=plugin)
        self.writer.open()
        image = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
        self.compressed = compressed
        self.rgb_topic = topics.rgb + ("/compressed" if compressed else "")
        self.cons = {name: self.writer.add_connection(name, kind, typestore=self.ts)
                     for name, kind in ((self.rgb_topic, image),
                                        (topics.depth, "sensor_msgs/msg/Image"),
                                        (topics.camera_info, "sensor_msgs/msg/CameraInfo"),
                                        (topics.odom or "/tf", "nav_msgs/msg/Odometry"
                                         if topics.odom else "tf2_msgs/msg/TFMessage"),
                                        (topics.cmd, "geometry_msgs/msg/Twist"),
                                        ("/tf_static", "tf2_msgs/msg/TFMessage"))}

    def header(self, t: float, frame: str) -> Any:
        sec = int(math.floor(EPOCH_S + t))
        return self.t["std_msgs/msg/Header"](stamp=self.t["builtin_interfaces/msg/Time"](
            sec=sec, nanosec=int(round((EPOCH_S + t - sec) * 1e9)) % 1_000_000_000),
            frame_id=frame)

    def write(self, topic: str, t: float, msg: Any) -> None:
        con = self.cons[topic]
        self.writer.write(con, int(round((EPOCH_S + t) * 1e9)),
                          self.ts.serialize_cdr(msg, con.msgtype))

    def pose_parts(self, pose: np.ndarray) -> tuple[Any, Any]:
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_matrix(pose[:3, :3]).as_quat()
        return (self.t["geometry_msgs/msg/Vector3"](x=pose[0, 3], y=pose[1, 3], z=pose[2, 3]),
                self.t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w))

    def transform(self, t: float, parent: str, child: str, pose: np.ndarray) -> Any:
        translation, rotation = self.pose_parts(pose)
        return self.t["geometry_msgs/msg/TransformStamped"](
            header=self.header(t, parent), child_frame_id=child,
            transform=self.t["geometry_msgs/msg/Transform"](translation=translation,
                                                             rotation=rotation))

    def odometry(self, t: float, topics: LogTopics, pose: np.ndarray, speed: float,
                 rate: np.ndarray) -> None:
        T = self.t
        if not topics.odom:
            self.write("/tf", t, T["tf2_msgs/msg/TFMessage"](transforms=[self.transform(
                t, topics.world_frame, topics.base_frame, pose)]))
            return
        v, q = self.pose_parts(pose)
        point = T["geometry_msgs/msg/Point"](x=v.x, y=v.y, z=v.z)
        self.write(topics.odom, t, T["nav_msgs/msg/Odometry"](
            header=self.header(t, topics.world_frame), child_frame_id=topics.base_frame,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=T["geometry_msgs/msg/Pose"](position=point, orientation=q),
                covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=self.twist(speed, rate), covariance=np.zeros(36))))

    def twist(self, v: float, w: Any) -> Any:
        """A twist of forward speed ``v`` [m/s] and angular velocity ``w`` [rad/s]: (3,) or
        the yaw rate alone."""
        vec = self.t["geometry_msgs/msg/Vector3"]
        wx, wy, wz = (0.0, 0.0, w) if np.isscalar(w) else (float(v_) for v_ in w)
        return self.t["geometry_msgs/msg/Twist"](linear=vec(x=v, y=0.0, z=0.0),
                                                 angular=vec(x=wx, y=wy, z=wz))

    def image(self, t: float, topic: str, frame: str, array: np.ndarray, encoding: str) -> None:
        import cv2

        if self.compressed and topic == self.rgb_topic:
            ok, data = cv2.imencode(".jpg", cv2.cvtColor(array, cv2.COLOR_RGB2BGR))
            self.write(topic, t, self.t["sensor_msgs/msg/CompressedImage"](
                header=self.header(t, frame), format="rgb8; jpeg compressed bgr8",
                data=data.ravel()))
            return
        h, w = array.shape[:2]
        self.write(topic, t, self.t["sensor_msgs/msg/Image"](
            header=self.header(t, frame), height=h, width=w, encoding=encoding,
            is_bigendian=0, step=array.itemsize * w * (array.shape[2] if array.ndim == 3 else 1),
            data=np.ascontiguousarray(array).view(np.uint8).ravel()))


def record_log(world: World, vehicle: VehicleSpec, out: str | Path, *, seed: int = 0,
               config: CollectConfig | None = None, topics: LogTopics = DEFAULT_TOPICS,
               realism: Realism = REALISM, compressed: bool = False, runs: int = 1
               ) -> tuple[Path, list[Episode]]:
    """Drive ``vehicle`` on ``world`` as collection does, ``runs`` times (seeds ``seed``,
    ``seed`` + 1, …; ``config``'s duration; the robot stands :data:`STOP_S` between runs,
    commanded 0) and write the log to ``out``: a ``.mcap`` or ``.db3`` file, or else a bag
    directory (MCAP inside). Written whole or not at all. Returns the path and the
    episodes the pipeline makes of the same drives."""
    cfg = config or CollectConfig()
    out = Path(out)
    rng = np.random.default_rng([seed, 7])
    camera_frame = "camera_color_optical_frame"
    tmp = Path(tempfile.mkdtemp(prefix=".dgt-log-", dir=out.parent))
    try:
        bag = _BagWriter(tmp / "bag", "sqlite3" if out.suffix == ".db3" else "mcap", topics,
                         compressed)
        sim = simulator(world, vehicle)
        renderer = terrain_renderer(world, cfg.frame_max_depth_m)
        ou = OUSteering(np.random.default_rng([seed, 8]))
        trees = np.asarray(world.trees, np.float64).reshape(-1, 4)
        clock = {"odom": 0.0, "cmd": 0.0, "cam": 0.0}
        last: dict[str, Any] = {"base": 0.0}

        def noisy(pose: np.ndarray) -> np.ndarray:
            from scipy.spatial.transform import Rotation

            out_pose = pose.copy()
            out_pose[:3, 3] += rng.normal(0.0, realism.position_noise_m, 3)
            turn = Rotation.from_rotvec(rng.normal(0.0, realism.attitude_noise_rad, 3))
            out_pose[:3, :3] = turn.as_matrix() @ pose[:3, :3]
            return out_pose

        def steer(st: VehicleState) -> float:
            pose, now = base_pose(st), last["base"] + st.time_s  # [s] on the log's clock
            if "mount" not in last:  # the first state: the camera's mount, once
                position, rotation = onboard_camera_pose(sim)
                world_cam = np.eye(4)
                world_cam[:3, :3], world_cam[:3, 3] = rotation @ OPTICAL_FROM_GL, position
                last["mount"] = np.linalg.inv(pose) @ world_cam
                bag.write("/tf_static", 0.0, bag.t["tf2_msgs/msg/TFMessage"](transforms=[
                    bag.transform(0.0, topics.base_frame, camera_frame, last["mount"])]))
            while clock["odom"] <= now + 1e-9:  # between two states: interpolated
                frac = 1.0 - (now - clock["odom"]) / CONTROL_DT_S
                use = pose.copy() if frac >= 0.5 or "pose" not in last else last["pose"].copy()
                if "pose" in last:
                    use[:3, 3] = last["pose"][:3, 3] + frac * (pose[:3, 3] - last["pose"][:3, 3])
                bag.odometry(clock["odom"], topics, noisy(use), st.speed_mps, st.angular_rate)
                clock["odom"] += 1.0 / realism.odometry_hz
            s = random_steer(st, ou, world, trees, vehicle)
            if now + 1e-9 >= clock["cmd"]:
                rate = cfg.speed_mps * math.tan(s * vehicle.max_steer_rad) / vehicle.wheelbase_m
                bag.write(topics.cmd, now, bag.twist(cfg.speed_mps, rate))
                clock["cmd"] += 1.0 / realism.command_hz
            if now + 1e-9 >= clock["cam"]:
                clock["cam"] += 1.0 / realism.camera_hz
                _camera(bag, renderer, now + rng.normal(0.0, realism.jitter_s),
                        pose @ last["mount"], topics, camera_frame, rng, realism)
            last["pose"], last["now"] = pose, now
            return s

        episodes = []
        for k in range(runs):
            last.pop("pose", None)  # a new run starts elsewhere: nothing to interpolate from
            episodes.append(run_episode(world, vehicle, seed + k, cfg, steer=steer))
            _stand(bag, topics, clock, last["now"] + STOP_S, lambda: noisy(last["pose"]),
                   realism)
            last["base"] = clock["cam"] = max(clock["odom"], clock["cmd"])
        bag.writer.close()
        stored = tmp / "bag"
        if out.suffix in (".mcap", ".db3"):
            stored = next(stored.glob(f"*{out.suffix}"))
        if out.is_dir():
            shutil.rmtree(out)
        stored.replace(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out, episodes


def _stand(bag: _BagWriter, topics: LogTopics, clock: dict[str, float], until: float,
           pose: Any, realism: Realism) -> None:
    """The robot standing until ``until`` [s]: odometry at ``pose()`` (a fresh noisy copy
    each time), speed 0, and velocity commands of 0, at their rates."""
    while clock["odom"] <= until or clock["cmd"] <= until:
        if clock["odom"] <= clock["cmd"]:
            bag.odometry(clock["odom"], topics, pose(), 0.0, np.zeros(3))
            clock["odom"] += 1.0 / realism.odometry_hz
        else:
            bag.write(topics.cmd, clock["cmd"], bag.twist(0.0, 0.0))
            clock["cmd"] += 1.0 / realism.command_hz


def _camera(bag: _BagWriter, renderer: Any, t: float, world_cam: np.ndarray,
            topics: LogTopics, frame: str, rng: np.random.Generator, realism: Realism) -> None:
    """One RGB-D frame at camera pose ``world_cam`` (optical axes): colour, depth in mm
    (16UC1, 0 = none) and the camera matrix, each image dropped at ``realism.dropped``."""
    from dgt_lib.world.mujoco_model import CAMERA

    img = renderer.render((world_cam[:3, 3], world_cam[:3, :3] @ OPTICAL_FROM_GL))
    if rng.random() >= realism.dropped:
        bag.image(t, bag.rgb_topic, frame, img.rgb, "rgb8")
    if rng.random() >= realism.dropped:
        depth_mm = np.nan_to_num(img.depth * 1000.0, nan=0.0)
        bag.image(t, topics.depth, frame, np.round(depth_mm).astype(np.uint16), "16UC1")
    f, (w, h) = CAMERA.focal_px, (CAMERA.width, CAMERA.height)
    bag.write(topics.camera_info, t, bag.t["sensor_msgs/msg/CameraInfo"](
        header=bag.header(t, frame), height=h, width=w, distortion_model="plumb_bob",
        d=np.zeros(5), k=np.array([f, 0, w / 2 - 0.5, 0, f, h / 2 - 0.5, 0, 0, 1.0]),
        r=np.eye(3).ravel(), p=np.array([f, 0, w / 2 - 0.5, 0, 0, f, h / 2 - 0.5, 0, 0, 0, 1, 0.0]),
        binning_x=0, binning_y=0, roi=bag.t["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)))
