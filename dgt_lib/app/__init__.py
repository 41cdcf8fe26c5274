"""The command-line application ``dgt`` and what only it uses.

- :mod:`~dgt_lib.app.cli` (with :mod:`~dgt_lib.app.cli_args`): ``dgt reproduce``,
  ``dgt plan``, ``dgt costmap``, ``dgt settings`` and the rest, parsed and dispatched;
- :mod:`~dgt_lib.app.report`: a run's results report, figures and rerun recordings, and
  the seed's run record;
- :mod:`~dgt_lib.app.query`: one planning query on a loaded world (notebooks call
  :func:`~dgt_lib.app.query.plan_on_world`); :mod:`~dgt_lib.app.plan_one` resolves a named
  world, a height map or a DEM for it (``dgt plan``), and
  :mod:`~dgt_lib.app.never_driven` for a vehicle the kit never drove;
- :mod:`~dgt_lib.app.costmap_export`: ``dgt costmap`` (GeoTIFF, Nav2);
- :mod:`~dgt_lib.app.figures`: the README's figures (``make figures``).

Nothing below this package imports it.
"""
