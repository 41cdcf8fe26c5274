"""dgt-kit: a teaching and reproduction kit of DGT-Map on MuJoCo.

One module per pipeline stage (DESIGN.md → Data flow). ``MUJOCO_GL=egl`` is set
here, before any module imports mujoco, so headless rendering works.
"""

import os as _os

_os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
