"""Which OpenGL MuJoCo renders with (``MUJOCO_GL``), checked before a command does any
work: a value MuJoCo does not know, or a platform whose library or display is missing,
otherwise fails deep inside ``import mujoco`` or at the first frame, after minutes.
``dgt_lib`` sets ``MUJOCO_GL=egl`` (headless) unless it is set already.
"""

from __future__ import annotations

import ctypes
import os
import sys

from dgt_lib.core.faults import SetupError

WHAT_WORKS = ("egl (headless, the default: needs libEGL, e.g. a GPU driver or Mesa), "
              "osmesa (software: needs libOSMesa), glfw (needs a display)")
"""What ``MUJOCO_GL`` may be, for the error message."""

NEEDS_DISPLAY = ("glfw", "glx", "", "enable", "enabled", "on", "true", "1")
"""Values with which MuJoCo opens a window-system context (GLFW): they need a display."""


class RendererError(SetupError):
    """``MUJOCO_GL`` names no renderer that can work on this machine."""


def _library_found(name: str) -> bool:
    """Whether the shared library ``lib<name>`` loads, tried as PyOpenGL (which MuJoCo
    renders through) tries it: ``lib<name>.so``, then ``.so.9`` down to ``.so.0``, on the
    linker's path (``LD_LIBRARY_PATH`` included). Loading it here costs nothing more:
    ``import mujoco`` loads it in every process that renders."""
    for filename in [f"lib{name}.so", *(f"lib{name}.so.{i}" for i in range(9, -1, -1))]:
        try:
            ctypes.CDLL(filename)
        except OSError:
            continue
        return True
    return False


def check_mujoco_gl(value: str | None = None) -> None:
    """Raise :class:`RendererError`, one sentence naming ``MUJOCO_GL``, its value and what
    works, when the renderer it selects cannot work here: a value MuJoCo does not know, or
    off; ``egl`` without libEGL; ``osmesa`` without libOSMesa; ``glfw`` without a display.
    ``value``: default ``$MUJOCO_GL``. Only Linux is checked (elsewhere MuJoCo picks
    its platform's own context)."""
    raw = os.environ.get("MUJOCO_GL", "egl") if value is None else value
    gl = raw.lower().strip()
    if not sys.platform.startswith("linux"):
        return
    problem = None
    if gl == "egl" and not _library_found("EGL"):
        problem = "libEGL is not installed"
    elif gl == "osmesa" and not _library_found("OSMesa"):
        problem = "libOSMesa is not installed (apt install libosmesa6)"
    elif gl in NEEDS_DISPLAY and not (os.environ.get("DISPLAY")
                                      or os.environ.get("WAYLAND_DISPLAY")):
        problem = "there is no display (DISPLAY is not set)"
    elif gl not in ("egl", "osmesa", *NEEDS_DISPLAY):
        problem = ("MuJoCo renders nothing with it" if gl in ("disable", "disabled", "off",
                                                              "false", "0")
                   else "it is not a renderer MuJoCo knows")
    if problem is not None:
        raise RendererError(f"MUJOCO_GL={raw!r} cannot render here: {problem}; what works: "
                            f"{WHAT_WORKS}")
