"""Defaults for reading MRCLAM and making histories, each with where it was measured.

The noise defaults are measured on dataset 6 against its motion capture by
:func:`qfg.datasets.mrclam.measure_noise` (table and command in docs/mrclam.md).
"""

from __future__ import annotations

import numpy as np

#: Landmark rows whose stamps follow each other within this many seconds form one view. The logger
#: stamps the rows of one image as it writes them: of the 119,772 gaps between distinct landmark
#: stamps of datasets 1-6, 8,327 are 1 ms and 29 are 2-10 ms, none is 11-147 ms (distinct images),
#: so 10 ms merges every split image and nothing else (docs/mrclam.md).
DEFAULT_VIEW_GAP = 0.010
#: Environment variable naming the directory that holds the ``MRCLAM_Dataset*`` directories.
DATA_ENV = "QFG_MRCLAM_DIR"
#: Ground-truth records further apart than this (s) do not cover the times between them: the
#: motion capture records every 16 ms and drops out for up to 2 s (dataset 6).
DEFAULT_GROUNDTRUTH_MAX_GAP = 0.1

#: Bearing noise (radians) the solver is told to assume by default: 0.66 deg, the ``sigma90`` of
#: measured minus motion-capture bearings on dataset 6 (robust std 0.45 deg, std 4.0 deg: a few
#: gross outliers; the normal with the measured 90th percentile of |error| sits between).
DEFAULT_SIGMA_BEARING = float(np.deg2rad(0.66))
#: Noise (radians) of the odometry's direction of travel between kept views: 1.57 deg, the
#: ``sigma90`` per step of the default histories on dataset 6 (robust std 1.08 deg, std 1.41 deg).
DEFAULT_SIGMA_HEADING = float(np.deg2rad(1.57))
#: Noise of log(ratio of consecutive step lengths) by odometry: 0.074 (7.4 %), the ``sigma90`` on
#: dataset 6 (robust std 7.0 %); for a motion model that uses the odometry's distances.
DEFAULT_SIGMA_DISTANCE_RATIO = 0.074
#: Seconds to add to odometry stamps to put them on the measurements' clock: a velocity command
#: stamped t moves the robot as the camera sees it at t + lead (measured, see module docstring).
DEFAULT_ODOMETRY_LEAD = 0.26  # dataset 6: capture = measurement stamp - 0.04 s = odometry + 0.22 s
#: Longest time (s) a triplet may go unseen inside one history; beyond it a new history starts.
DEFAULT_MAX_GAP = 10.0
#: Least odometry displacement (m) between consecutive kept views of a history.
DEFAULT_MIN_TRAVEL = 0.2
#: Least time (s) between consecutive kept views of a history for robots without odometry.
DEFAULT_MIN_INTERVAL = 4.0

# What a file of the format can plausibly hold; beyond it the file is refused (naming it) before
# it can take the machine's memory. The largest file of datasets 1-6 inflates to 4.1 MB in
# 123,776 lines of at most 71 bytes (dataset 3, Robot5_Odometry; docs/mrclam.md): the bounds
# leave 16x that for longer runs, and a file is read in blocks, so memory stays within about
# MAX_LINES x 5 columns x 8 bytes x 2 (the blocks and their concatenation).
#: Bytes of one file (compressed on disk, and inflated).
MAX_FILE_BYTES = 64 * 2**20
#: Lines of one file.
MAX_LINES = 2_000_000
#: Bytes of one line (header comments included).
MAX_LINE_BYTES = 4096
