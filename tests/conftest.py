"""Shared pytest set-up: headless MuJoCo and a private data directory per test session."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("DGT_PROFILE", "smoke")
