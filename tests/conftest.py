"""Shared pytest set-up: headless MuJoCo and a private data directory per test session."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("DGT_PROFILE", "smoke")


import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def one_torch_thread():
    """One torch thread per test process: CI runs two pytest workers on two cores, and
    torch with two threads on a busy core is many times slower than with one."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture
def synthetic_pipeline(tmp_path, monkeypatch):
    """A private data directory whose pipeline trains on a synthetic dataset (no driving
    episodes: seconds); returns ``tmp_path``."""
    from dgt_lib.core import artifacts
    from dgt_lib.learning.synthetic import synthetic_dataset
    from dgt_lib.stages import costmaps, train
    from dgt_lib.stages.dataset import dataset_fingerprint

    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    dataset = synthetic_dataset((120, 60, 60, 40), seed=0)
    for module in (costmaps, train):  # where the model's key and its training look it up
        monkeypatch.setattr(module, "ensure_dataset", lambda prof, progress=True: dataset)
    monkeypatch.setattr(costmaps, "dataset_digest",
                        lambda prof, progress=True: dataset_fingerprint(dataset))
    return tmp_path
