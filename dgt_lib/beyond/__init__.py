"""Beyond the paper: research annexes built on the paper's pipeline, kept apart from it.

The sub-packages ``learning``, ``mapping``, ``navigation`` hold the paper's method and
its baselines only. What goes further lives here and plugs into them through small
interfaces (e.g. :func:`dgt_lib.mapping.costmap.field_costmap`, the training loop's
:class:`~dgt_lib.learning.training.MultiHeadNet`), never through an
``isinstance`` on an annex type inside a paper module:

==================  ===================================================================
``pooled``          PooledNet: a window network that dense evaluation computes exactly
``dense``           dense evaluation of DGTNet (a measured negative result)
``incremental``     costmaps updated only where new BEV cells changed them
``explore``         driving an unknown world: frames → BEV → incremental costmap → replan
==================  ===================================================================

This layer sits above ``navigation`` and below ``evaluation``: it may import any paper
module, and no paper module imports it.
"""
