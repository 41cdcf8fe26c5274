"""The packed dataset that `benchmarks/bench_train_stage.py` ships to a GPU machine trains on
the very patches of the run it came from: it must rebuild them bit for bit, or refuse."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from dgt_lib.core.geometry import GridSpec
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.perception.patches import extract_patches

ROOT = Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location(
        "bench_train_stage", ROOT / "benchmarks" / "bench_train_stage.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _bev(seed: int, shape=(60, 50)) -> BEVMap:
    rng = np.random.default_rng(seed)
    channels = rng.uniform(0, 1, (6, *shape)).astype(np.float32)
    channels[3] = np.cumsum(rng.normal(0, 0.3, shape), axis=0)  # heights of a few metres
    observed = rng.random(shape) > 0.05
    channels[:, ~observed] = 0.0
    return BEVMap(GridSpec((-10.0, 5.0), 0.4, shape), channels, observed,
                  observed.astype(np.int64))


def _dataset(bev: BEVMap, n: int = 300, seed: int = 1) -> PatchDataset:
    """As `build_dataset` stores it: cut at float64 poses, kept as float16 and float32."""
    rng = np.random.default_rng(seed)
    pose = np.column_stack([rng.uniform(-5, 5, n) * 1.7, rng.uniform(10, 20, n),
                            rng.uniform(-np.pi, np.pi, n)])
    patches, observed = extract_patches(bev, pose)
    return PatchDataset(patches=patches.astype(np.float16), observed=observed,
                        labels=rng.random(n).astype(np.float32),
                        vehicle=rng.integers(0, 4, n).astype(np.int8),
                        trajectory=np.arange(n, dtype=np.int32) // 10,
                        pose=pose.astype(np.float32),
                        split=rng.integers(0, 3, n).astype(np.int8))


def test_a_packed_dataset_comes_back_bit_for_bit(tmp_path):
    bench = _bench()
    bev = _bev(0)
    dataset = _dataset(bev)
    n_fix = bench.write_pack(dataset, bev, tmp_path, {"profile": "smoke", "seed": 0})
    assert n_fix > 0  # the float32 poses do round some values differently: the fix is needed
    back, manifest = bench.read_pack(tmp_path)
    assert manifest["profile"] == "smoke"
    for name, array in dataset.to_arrays().items():
        assert np.array_equal(getattr(back, name), array), name
        assert getattr(back, name).dtype == array.dtype, name


def test_a_pack_of_patches_from_another_map_is_refused(tmp_path):
    bench = _bench()
    dataset = _dataset(_bev(0))
    with pytest.raises(ValueError, match="not cut from this BEV"):
        bench.write_pack(dataset, _bev(1), tmp_path, {})
    bench.write_pack(dataset, _bev(0), tmp_path, {})
    other = _bev(0)
    other.channels[0] += 0.01  # the map changed after packing
    np.savez_compressed(tmp_path / "bev_training.npz", **other.to_arrays())
    with pytest.raises(ValueError, match="fingerprint differs"):
        bench.read_pack(tmp_path)
