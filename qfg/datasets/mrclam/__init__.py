"""The UTIAS MRCLAM dataset: loader, odometry integration and landmark-triplet histories.

MRCLAM (Leung, Halpern, Barfoot and Liu, IJRR 2011) has five robots with monocular cameras moving
among 15 point landmarks; each robot measures range and bearing to the barcoded landmarks (and to
the other robots) and logs its commanded forward and angular velocity ("odometry"). A dataset
directory holds, in the dataset's own text format (``#`` header lines, whitespace-separated
columns), each file plain (``.dat``) or gzip-compressed (``.dat.gz``):

=============================  =============================================================
``Barcodes.dat``               subject #, barcode #
``Landmark_Groundtruth.dat``   subject #, x [m], y [m], x std-dev [m], y std-dev [m]
``RobotN_Measurement.dat``     time [s], barcode #, range [m], bearing [rad]
``RobotN_Odometry.dat``        time [s], forward velocity [m/s], angular velocity [rad/s]
``RobotN_Groundtruth.dat``     time [s], x [m], y [m], orientation [rad]   (optional)
=============================  =============================================================

:func:`load` reads a directory into a :class:`MRCLAMDataset`. Measurements name what they saw by
barcode; barcodes are mapped to subjects through ``Barcodes.dat``, and only subjects listed in
``Landmark_Groundtruth.dat`` are landmarks: measurements of robots and of barcodes missing from
``Barcodes.dat`` are counted and set aside. Landmark measurements sharing one time stamp came from
one image and form one *view*.

:func:`triplet_histories` turns one robot's views into :class:`qfg.simulation.TripletHistory`
objects (landmark ids are MRCLAM *subject numbers*, 6-20 in the real data): for every landmark
triplet the views that saw all three, split where the triplet went unseen for longer than
``max_gap`` seconds and thinned so that consecutive kept views are at least ``min_travel`` metres
apart by odometry; the heading between kept views is the direction of travel from the odometry
integrated between their time stamps (:func:`integrate_odometry`), relative to the heading at the
earlier view. ``docs/mrclam.md`` explains and measures these choices.

:func:`measure_noise` measures the bearing, odometry heading and distance noise and the clock
offsets against motion capture (dataset 6); the ``DEFAULT_SIGMA_*`` values come from it.
:func:`measure_bearing_calibration` measures each robot's bearing bias and scale there;
:func:`calibrate_bearings` undoes them (``DEFAULT_BEARING_CALIBRATION``; docs/mrclam.md: not
adopted).

The data directory is never built in: pass it, or set ``QFG_MRCLAM_DIR`` (:func:`data_root`).

Data flows one way: this package reads files and produces measurements (histories); it does not
import solvers or plotting (figures are in ``qfg.harness.plotting_mrclam``). Modules, by concern:
``_io`` (bytes, text, tables, errors), ``_data`` (types and the load report), ``_load``,
``_odometry``, ``_checks`` (the data against itself), ``_histories``, ``_noise``,
``_calibration``, ``_cli``. The joint map's adapter, :mod:`qfg.datasets.mrclam.joint_map`
(a dataset as :class:`qfg.joint.JointMeasurements`, the joint method end to end), sits above
both this package and :mod:`qfg.joint` and is not imported here: import it by its name.

Run ``python -m qfg.datasets.mrclam [DIR ...] [--quirks] [--check] [--noise] [--calibration]``
for summaries.
"""


from ._calibration import (
                      DEFAULT_BEARING_CALIBRATION,
                      calibrate_bearings,
                      forward_axis,
                      measure_bearing_calibration,
)
from ._checks import (
                      LandmarkCheck,
                      LandmarkFixes,
                      anchored_dead_reckoning,
                      bearing_residuals,
                      check_landmarks,
                      landmark_fixes,
                      odometry_check,
                      swap_landmarks,
)
from ._cli import quirk_table
from ._constants import (
                      DATA_ENV,
                      DEFAULT_GROUNDTRUTH_MAX_GAP,
                      DEFAULT_MAX_GAP,
                      DEFAULT_MIN_INTERVAL,
                      DEFAULT_MIN_TRAVEL,
                      DEFAULT_ODOMETRY_LEAD,
                      DEFAULT_SIGMA_BEARING,
                      DEFAULT_SIGMA_DISTANCE_RATIO,
                      DEFAULT_SIGMA_HEADING,
                      DEFAULT_VIEW_GAP,
)
from ._data import (
                      LoadReport,
                      MRCLAMDataset,
                      Odometry,
                      RobotData,
                      RobotQuirks,
                      interpolate_poses,
                      repeated_views,
)
from ._histories import (
                      MRCLAMHistory,
                      TripletSegment,
                      history_counts,
                      summary_rows,
                      triplet_histories,
                      triplet_segments,
                      view_poses,
)
from ._io import DataFormatError
from ._load import data_root, find_datasets, load
from ._noise import (
    NoiseMeasurement,
    RobustStats,
    landmark_rows,
    measure_noise,
    noise_table,
    refit_landmarks,
    truth_bearing_residuals,
)
from ._odometry import dead_reckon, integrate_odometry, travelled

__all__ = [
    "DataFormatError",
    "Odometry",
    "RobotData",
    "MRCLAMDataset",
    "LoadReport",
    "RobotQuirks",
    "load",
    "find_datasets",
    "data_root",
    "integrate_odometry",
    "travelled",
    "dead_reckon",
    "landmark_fixes",
    "LandmarkFixes",
    "LandmarkCheck",
    "check_landmarks",
    "swap_landmarks",
    "anchored_dead_reckoning",
    "bearing_residuals",
    "truth_bearing_residuals",
    "landmark_rows",
    "refit_landmarks",
    "odometry_check",
    "repeated_views",
    "interpolate_poses",
    "TripletSegment",
    "MRCLAMHistory",
    "triplet_segments",
    "triplet_histories",
    "history_counts",
    "summary_rows",
    "quirk_table",
    "NoiseMeasurement",
    "DEFAULT_BEARING_CALIBRATION",
    "calibrate_bearings",
    "forward_axis",
    "measure_bearing_calibration",
    "RobustStats",
    "view_poses",
    "measure_noise",
    "noise_table",
    "DATA_ENV",
    "DEFAULT_VIEW_GAP",
    "DEFAULT_GROUNDTRUTH_MAX_GAP",
    "DEFAULT_SIGMA_BEARING",
    "DEFAULT_SIGMA_HEADING",
    "DEFAULT_SIGMA_DISTANCE_RATIO",
    "DEFAULT_ODOMETRY_LEAD",
    "DEFAULT_MAX_GAP",
    "DEFAULT_MIN_TRAVEL",
    "DEFAULT_MIN_INTERVAL",
]
