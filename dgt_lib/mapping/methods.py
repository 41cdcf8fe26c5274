"""The compared methods: one vocabulary for code, tables, figures and the CLI
(paper: Baselines).

=============  ================  ===============================================
key            label (paper)     costmap
=============  ================  ===============================================
``dgt``         DGT-Map           directional costmap of the multi-task model
``isotropic``   DGT-Map(Iso)      mean of the ``dgt`` layers, one layer
``single-task`` DGT-Map(ST)       directional costmap of the vehicle's single-task model
``slope``       Slope-Based       L_sb of the plane-fit forward slope, fitted with Optuna
``binary``      Binary            zero cost: the occupancy map alone
=============  ================  ===============================================
"""

from __future__ import annotations

from dgt_lib.core.config import VEHICLES

METHODS: tuple[str, ...] = ("dgt", "isotropic", "single-task", "slope", "binary")
"""The compared methods, in the order of the paper's Table I."""

METHOD_LABELS: dict[str, str] = {
    "dgt": "DGT-Map", "isotropic": "DGT-Map(Iso)", "single-task": "DGT-Map(ST)",
    "slope": "Slope-Based", "binary": "Binary"}
"""Each method's name in the paper's tables."""


def check_method(method: str, vehicle: str | None = None) -> None:
    """Raise a ValueError naming the valid choices for an unknown method or vehicle."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
    if vehicle is not None and vehicle not in VEHICLES:
        raise ValueError(f"unknown vehicle {vehicle!r}; valid vehicles: {', '.join(VEHICLES)}")
