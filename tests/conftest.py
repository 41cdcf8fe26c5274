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
