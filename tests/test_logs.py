"""Drive logs in: a ROS bag recorded from the kit's own drive goes through ``dgt log ingest``
to the BEV map and labels the pipeline makes of the same drive; logs the kit cannot use
end with one line and exit status 2, leaving nothing in the data directory."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from dgt_lib.app.cli import main  # noqa: E402
from dgt_lib.core import artifacts  # noqa: E402
from dgt_lib.core.config import get_profile  # noqa: E402
from dgt_lib.core.vehicles import get_vehicle  # noqa: E402
from dgt_lib.logs.ingest import ingest  # noqa: E402
from dgt_lib.logs.record import record_log  # noqa: E402
from dgt_lib.logs.streams import LogTopics  # noqa: E402
from dgt_lib.perception.bev import BEVAccumulator, BEVMap, bev_grid  # noqa: E402
from dgt_lib.perception.dataset import PatchDataset, episode_patches  # noqa: E402
from dgt_lib.world.terrain import get_world  # noqa: E402

SMOKE = get_profile("smoke")
CFG = replace(SMOKE.collect, episode_duration_s=16.0)
RENAMED = LogTopics(rgb="/front/rgb", depth="/front/depth", camera_info="/front/info", odom="",
                    cmd="/base/cmd", world_frame="odom", base_frame="base_link")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A 16 s jeep drive on the training world as an MCAP log, and its episode."""
    folder = tmp_path_factory.mktemp("log")
    path, (episode,) = record_log(get_world("training", SMOKE), get_vehicle("jeep"),
                                  folder / "drive.mcap", seed=3, config=CFG)
    return path, episode


def _ingested(path, topics, data, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(data))
    ingest(path, get_vehicle("jeep"), topics, CFG)
    folder = data / "logs" / path.name.replace(".", "_")
    return (BEVMap.from_arrays(artifacts.load(folder / "bev.npz")),
            PatchDataset.from_arrays(artifacts.load(folder / "dataset.npz")))


def _same_map(log_bev, episode, height_m, colour):
    """The log's BEV against the pipeline's map of the same drive, on the cells both see."""
    world = get_world("training", SMOKE)
    direct = BEVAccumulator(bev_grid(world.grid.extent)).add_sparse(episode.bev).result()
    rows, cols = np.nonzero(log_bev.observed)
    g = log_bev.grid
    r, c = direct.grid.xy_to_cell(g.origin_xy[0] + (cols + 0.5) * g.resolution,
                                  g.origin_xy[1] + (rows + 0.5) * g.resolution)
    both = direct.observed[r, c]
    assert both.sum() > 0.8 * direct.observed.sum()  # the log sees what the drive saw
    dh = np.abs(log_bev.mean_height[rows, cols][both] - direct.mean_height[r, c][both])
    assert np.median(dh) < height_m and np.percentile(dh, 95) < 5 * height_m
    dc = np.abs(log_bev.rgb[rows, cols][both] - direct.rgb[r, c][both]).mean()
    assert dc < colour
    return direct


def test_a_recorded_log_has_a_robots_topics_at_a_robots_rates(recorded, capsys):
    path, _ = recorded
    assert main(["log", "topics", str(path)]) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines()[1:]}
    rate = {topic: float(row[-2]) for topic, row in rows.items()}
    assert rate["/odom"] == pytest.approx(50, rel=0.05)
    assert rate["/cmd_vel"] == pytest.approx(20, rel=0.05)
    assert 9.0 < rate["/camera/color/image_raw"] <= 10.1  # a few frames dropped
    assert rows["/tf_static"][1] == "tf2_msgs/msg/TFMessage"


def test_ingesting_the_log_gives_the_map_and_labels_the_pipeline_makes_of_the_drive(
        recorded, tmp_path, monkeypatch):
    path, episode = recorded
    bev, ds = _ingested(path, LogTopics(), tmp_path, monkeypatch)
    direct = _same_map(bev, episode, height_m=0.03, colour=0.03)
    mine = episode_patches(episode, direct, CFG)
    assert len(mine["labels"]) >= 8
    # every patch the pipeline cuts, the log cuts at the same place with the same label
    gap = np.hypot(*(ds.pose[:, None, :2] - mine["pose"][None, :, :2]).transpose(2, 0, 1))
    assert gap.min(axis=0).max() < 0.1  # [m]
    np.testing.assert_allclose(ds.labels[gap.argmin(axis=0)], mine["labels"], atol=0.02)


def test_renamed_topics_jpeg_colour_a_tf_pose_and_sqlite_give_the_same_map(
        tmp_path, monkeypatch):
    path, (episode,) = record_log(get_world("training", SMOKE), get_vehicle("jeep"),
                                  tmp_path / "drive.db3", seed=3, config=CFG, topics=RENAMED,
                                  compressed=True)
    bev, ds = _ingested(path, replace(RENAMED, rgb="/front/rgb/compressed"), tmp_path / "d",
                        monkeypatch)
    _same_map(bev, episode, height_m=0.03, colour=0.05)
    assert len(ds.labels) >= 8


def test_a_log_of_three_drives_is_three_runs_split_into_train_validation_and_test(
        tmp_path, monkeypatch):
    cfg = replace(CFG, episode_duration_s=8.0)
    path, episodes = record_log(get_world("training", SMOKE), get_vehicle("jeep"),
                                tmp_path / "three.mcap", seed=5, config=cfg, runs=3)
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    summary = ingest(path, get_vehicle("jeep"), LogTopics(), cfg)
    assert len(episodes) == 3 and summary["runs"] == 3
    assert all(n > 0 for n in summary["patches"].values())  # one run each: 70/15/15 by run


def _run(args, capsys):
    profile = [] if args[0] == "topics" else ["--profile", "smoke"]
    status = main(["log", *map(str, args), *profile])
    err = capsys.readouterr().err.strip()
    return status, err


@pytest.mark.parametrize("options, says", [
    (["--rgb", "/nope"], "no topic /nope in the log; it has: "),
    (["--odom", "/cmd_vel"], "/cmd_vel is a geometry_msgs/msg/Twist; expected nav_msgs"),
    (["--camera-info", "/camera/color/image_raw"], "expected sensor_msgs/msg/CameraInfo"),
    (["--pose-source", "tf"], "no transform from odom to base_link"),
])
def test_a_log_read_with_topics_it_does_not_have_ends_in_one_line(
        recorded, tmp_path, monkeypatch, capsys, options, says):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    status, err = _run(["ingest", recorded[0], "--vehicle", "jeep", *options], capsys)
    assert status == 2 and len(err.splitlines()) == 1 and says in err
    assert not (tmp_path / "logs").exists() or not any((tmp_path / "logs").iterdir())


def _copy(src: Path, dst: Path, drop=(), shift_s=0.0, shifted=()) -> Path:
    """``src`` rewritten to ``dst`` without the topics ``drop``, the header stamps of the
    topics ``shifted`` moved by ``shift_s``."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer

    from dgt_lib.logs.bag import typestore

    ts = typestore()
    with AnyReader([src], default_typestore=ts) as reader, \
            Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        cons = {}
        for con, t_ns, raw in reader.messages():
            if con.topic in drop:
                continue
            if con.topic not in cons:
                cons[con.topic] = writer.add_connection(con.topic, con.msgtype, typestore=ts)
            if con.topic in shifted:
                msg = reader.deserialize(raw, con.msgtype)
                msg.header.stamp.sec += int(shift_s)
                raw = ts.serialize_cdr(msg, con.msgtype)
            writer.write(cons[con.topic], t_ns, raw)
    return dst


def test_logs_that_cannot_be_used_end_in_one_line_and_leave_nothing(
        recorded, tmp_path, monkeypatch, capsys):
    path = recorded[0]
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    truncated = tmp_path / "truncated.mcap"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 3])
    empty = tmp_path / "empty"
    from rosbags.rosbag2 import StoragePlugin, Writer

    from dgt_lib.logs.bag import typestore

    with Writer(empty, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=typestore())
    camera = ("/camera/color/image_raw", "/camera/aligned_depth_to_color/image_raw",
              "/camera/color/camera_info")
    cases = {
        tmp_path / "missing.mcap": "no such file",
        truncated: "",
        empty: "holds no messages",
        _copy(path, tmp_path / "no_info", drop=("/camera/color/camera_info",)):
            "no topic /camera/color/camera_info",
        _copy(path, tmp_path / "late", shift_s=5000, shifted=camera): "never overlap",
        _copy(path, tmp_path / "no_cmd", drop=("/cmd_vel",)): "no topic /cmd_vel",
    }
    for log, says in cases.items():
        status, err = _run(["ingest", log, "--vehicle", "jeep"], capsys)
        assert status == 2 and len(err.splitlines()) == 1 and says in err, (log, err)
    status, err = _run(["topics", tmp_path / "missing.mcap"], capsys)
    assert status == 2 and "no such file" in err
    logs = tmp_path / "data" / "logs"
    assert not logs.exists() or not any(logs.iterdir())
