"""Figures and small Markdown tables for the notebooks and the results report.

One module per notebook, each named after what it draws:

- :mod:`~dgt_lib.viz.terrain` (01): worlds, vehicles, RGB-D frames, premise runs, the
  mapping survey and the BEV map;
- :mod:`~dgt_lib.viz.labels` (02): locomotion labels, the dataset, L against slope;
- :mod:`~dgt_lib.viz.training` (03): the network's parts and shapes, learning curves,
  multi-task against single-task errors, predictions, the width trade-off;
- :mod:`~dgt_lib.viz.costmaps` (04): directional costmap layers in metres (per heading,
  per method, uphill against downhill, per vehicle), the occupancy map, one heading's
  rotate → slide → average → rotate back;
- :mod:`~dgt_lib.viz.planner` (05 and ``dgt plan``): Hybrid A* primitives, cost
  amplification, planned paths, one planning query;
- :mod:`~dgt_lib.viz.experiments` (06–08 and :mod:`dgt_lib.app.report`): queries, planned
  and driven paths, where failed trials ended, trial speeds, success rates;
- :mod:`~dgt_lib.viz.accuracy` (09 and :mod:`dgt_lib.app.report`): the measured ground truth
  beside the learned costmap layers, predicted against measured cost;
- :mod:`~dgt_lib.viz.common`: colours and helpers several of them share, among them
  :func:`source_markdown` to show an implementation next to its paper equation.

Every plotting function returns the matplotlib ``Figure`` (or draws into a given
``ax``), so notebooks stay one call per picture; the few functions that compute
something (:func:`survey_footprints`, :func:`height_errors`, :func:`gallery_indices`,
:func:`binned_mean`, the ``*_table`` functions) are tested in ``tests/test_viz.py``
(:func:`primitive_lookups` and :func:`plan_table` in ``tests/test_viz_planner.py``, the
training helpers in ``tests/test_viz_training.py``). Every public name is re-exported
here, so notebooks call ``viz.<name>``::

    from dgt_lib import viz
    viz.plot_world(get_world("hill"))

The package sits above the whole pipeline: it may import any layer, and none of the
library's lower layers imports it. :func:`inference_rate` and :func:`width_tradeoff`
measure and train models rather than draw: they live in :mod:`dgt_lib.learning.tradeoff`
and are re-exported here for notebook 03.
"""

# ruff: noqa: F401 - the names below are this package's interface, re-exported
from dgt_lib.learning.tradeoff import inference_rate, width_tradeoff
from dgt_lib.viz.accuracy import (
    plot_ground_truth_beside_layers,
    plot_predicted_vs_measured,
    plot_truth_dots,
)
from dgt_lib.viz.common import (
    COST_CMAP,
    COST_LABEL,
    METHOD_COLORS,
    ROUTE_COLORS,
    VEHICLE_COLORS,
    source_markdown,
)
from dgt_lib.viz.costmaps import (
    OCCUPANCY_COLORS,
    plot_cost_layer,
    plot_heading_explained,
    plot_heading_layers,
    plot_layer_panels,
    plot_method_layers,
    plot_occupancy,
    plot_uphill_downhill,
    plot_vehicle_layers,
)
from dgt_lib.viz.experiments import (
    FAILURE_MARKERS,
    QUERY_FATES,
    end_position,
    plot_failure_map,
    plot_failures,
    plot_planned_paths,
    plot_queries,
    plot_query_draw,
    plot_success_rates,
    plot_trial_speeds,
)
from dgt_lib.viz.labels import (
    PAPER_DATASET,
    binned_mean,
    dataset_table,
    directional_table,
    gallery_indices,
    plot_dataset_counts,
    plot_label_histograms,
    plot_label_vs_slope,
    plot_locomotion_curve,
    plot_patch_gallery,
    plot_run_labels,
)
from dgt_lib.viz.planner import (
    PLAN_COLORS,
    PRIMITIVE_COLORS,
    PRIMITIVES,
    plan_table,
    plot_cost_amplification,
    plot_motion_primitives,
    plot_plans,
    plot_query,
    primitive_lookups,
)
from dgt_lib.viz.terrain import (
    chase_view,
    height_errors,
    plot_backprojection,
    plot_bev,
    plot_bev_error,
    plot_images,
    plot_rgbd,
    plot_slope_histogram,
    plot_speed_vs_distance,
    plot_survey,
    plot_world,
    plot_worlds,
    quality_table,
    survey_footprints,
    vehicle_table,
)
from dgt_lib.viz.training import (
    METRIC_NAMES,
    TRAINING_COLORS,
    comparison_table,
    head_gradient_norms,
    own_head_predictions,
    parameter_table,
    plot_head_init,
    plot_learning_curves,
    plot_metric_comparison,
    plot_predicted_patches,
    plot_predicted_vs_true,
    plot_width_tradeoff,
    shape_table,
    shape_trace,
    tradeoff_table,
)
