"""`dgt plan --vehicle FILE.toml`: a vehicle never driven planned on the vehicle-conditioned
network's costmap, saying so; a spec outside the training vehicles' range warns naming the
field; an impossible one stops before any work; the plan drives in MuJoCo."""

from pathlib import Path

import numpy as np
import pytest

from dgt_lib.app.cli import main
from dgt_lib.app.never_driven import plan_vehicle_query
from dgt_lib.core import artifacts
from dgt_lib.core.vehicle_file import vehicle_toml
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.stages import conditioned
from dgt_lib.stages.dataset import dataset_fingerprint

TRUCK = Path(__file__).resolve().parents[1] / "examples" / "my_truck.toml"
QUERY = ["--start", "8,16,0", "--goal", "30,16", "--profile", "smoke"]
pytestmark = pytest.mark.filterwarnings("ignore:.*near-constant")  # smoke's 2 epochs


@pytest.fixture
def data(tmp_path, monkeypatch):
    """A fresh data directory, a flat world file with a block to drive around, and a
    synthetic dataset in place of the smoke collection (τ_s fixed: no hill or ridge maps)."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    dataset = synthetic_dataset((80, 60, 60, 60), seed=0)
    monkeypatch.setattr(conditioned, "ensure_dataset", lambda prof, progress=True: dataset)
    monkeypatch.setattr(conditioned, "dataset_digest",
                        lambda prof, progress=True: dataset_fingerprint(dataset))
    for module in ("dgt_lib.stages.costmaps", "dgt_lib.app.never_driven"):
        monkeypatch.setattr(f"{module}.ensure_tau_s", lambda prof: 0.6)
    heights = np.zeros((80, 120), np.float32)
    heights[30:50, 55:65] = 3.0
    np.save(tmp_path / "tiny.npy", heights)
    return tmp_path


def _truck_file(path: Path, **changes: str) -> Path:
    text = TRUCK.read_text()
    for line, new in changes.items():
        text = text.replace(line, new)
    path.write_text(text)
    return path


def test_a_vehicle_never_driven_plans_on_the_conditioned_networks_costmap(data, capsys):
    args = ["plan", "--world", str(data / "tiny.npy"), "--vehicle", str(TRUCK), *QUERY]
    assert main(args) == 0
    out = capsys.readouterr().out
    told = ("never driven: costmap from the vehicle-conditioned network trained on jeep, "
            "vw_van, mercedes_van, carla_cola")
    assert told in out and "training it first" in out
    assert "DGT-Map plan for my_truck" in out and "found: length" in out
    # a height map has no colour: the geometry-only conditioned network maps it
    assert (data / "data" / "smoke" / "seed-0" / "models" / "conditioned_geometry.pt").exists()
    assert main(args) == 0  # the second query reuses the network
    again = capsys.readouterr().out
    assert told in again and "training it first" not in again


def test_a_named_vehicle_plans_as_itself_by_name_or_from_its_own_file(data, capsys):
    (data / "jeep.toml").write_text(vehicle_toml(get_vehicle("jeep")))
    for vehicle in ("jeep", str(data / "jeep.toml")):
        assert main(["plan", "--world", str(data / "tiny.npy"), "--vehicle", vehicle,
                     "--method", "binary", *QUERY]) == 0
        out = capsys.readouterr().out
        assert "plan for jeep" in out and "never driven" not in out


def test_an_impossible_vehicle_is_one_error_line_before_any_work(data, capsys):
    bad = _truck_file(data / "bad.toml", **{"track_m = 1.75": "track_m = 2.5"})
    assert main(["plan", "--world", str(data / "tiny.npy"), "--vehicle", str(bad),
                 *QUERY]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dgt plan: error: ") and "track_m = 2.5" in err
    assert "width_m" in err and len(err.strip().splitlines()) == 1
    assert not any((data / "data").iterdir())  # nothing surveyed, collected or trained


def test_a_vehicle_outside_the_training_range_warns_naming_the_field(data, capsys):
    heavy = _truck_file(data / "heavy.toml", **{"mass_kg = 4000.0": "mass_kg = 20000.0"})
    assert main(["plan", "--world", str(data / "tiny.npy"), "--vehicle", str(heavy),
                 "--method", "binary", *QUERY]) == 0
    captured = capsys.readouterr()
    assert "warning:" in captured.err and "mass_kg = 20000 (trained on 1490" in captured.err
    assert "warning:" in captured.out  # the summary repeats it


def test_no_single_task_model_exists_for_a_vehicle_never_driven(data, capsys):
    assert main(["plan", "--world", str(data / "tiny.npy"), "--vehicle", str(TRUCK),
                 "--method", "single-task", *QUERY]) == 2
    assert "never driven" in capsys.readouterr().err


def test_the_never_driven_vehicle_drives_its_plan_in_mujoco(data):
    report = plan_vehicle_query(str(data / "tiny.npy"), TRUCK, (8.0, 16.0, 0.0), (20.0, 16.0),
                        method="binary", profile="smoke", drive=True, progress=False)
    assert report.vehicle == "my_truck" and report.plan.success
    assert report.outcome is not None and report.outcome.success
    assert report.as_dict()["never_driven"].startswith("my_truck was never driven")
