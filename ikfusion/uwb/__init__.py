"""UWB positioning: constellations, TOA logs, per-transmission fixes, DOP maps, reader planning.

- :mod:`~ikfusion.uwb.constellation`: reader files (SPEC section 3);
- :mod:`~ikfusion.uwb.toa_log`: TOA CSV logs and their grouping into transmissions (section 4);
- :mod:`~ikfusion.uwb.toa_model` and :mod:`~ikfusion.uwb.simulate`: the measurement model;
- :mod:`~ikfusion.uwb.locate`: the positioning solver (position + transmit time, NLOS handling);
- :mod:`~ikfusion.uwb.dop`: dilution of precision at points and as maps;
- :mod:`~ikfusion.uwb.placement`: choosing reader positions;
- :mod:`~ikfusion.uwb.plot`: figures (needs matplotlib);
- :mod:`~ikfusion.uwb.calibration`: reader positions and clock offsets from a calibration log
  (:func:`calibrate`), with its first estimate, CasADi problem, frames and simulator in the
  ``calibration_*`` modules.
"""

from .calibration import (
    CalibrationError,
    CalibrationOptions,
    OutlierReport,
    UwbCalibration,
    calibrate,
    load_heights,
    load_survey,
)
from .calibration_sim import (
    SimulatedCalibration,
    hall_constellation,
    simulate_calibration_log,
    wand_path,
)
from .constellation import (
    DEFAULT_RANGE_SIGMA,
    Constellation,
    Reader,
    constellation_from_dict,
    load_constellation,
    make_constellation,
    save_constellation,
)
from .dop import (
    Dop,
    DopMap,
    PlanSummary,
    capture_area,
    compute_dop,
    constellation_dop,
    dop_map,
    min_readers,
    summarize,
)
from .ekf import EkfOptions, UnitTrack, UwbTotals
from .locate import (
    FIX_COLUMNS,
    Fixes,
    FixStatus,
    LocateOptions,
    estimate_range_sigma,
    locate,
    locate_transmissions,
    write_fixes_csv,
)
from .placement import (
    PlacementResult,
    border_candidates,
    optimize_placement,
    perimeter_layout,
)
from .simulate import SimulatedToa, simulate_toa
from .toa_log import (
    TOA_COLUMNS,
    ToaLog,
    Transmissions,
    group_transmissions,
    read_toa_csv,
    toa_log_from_matrix,
    write_toa_csv,
)
from .toa_model import predict_toa, toa_residuals
from .tracking import ImuUnit, TagInfo, load_tags, save_tags, track_tags

__all__ = [
    "EkfOptions",
    "ImuUnit",
    "TagInfo",
    "UnitTrack",
    "UwbTotals",
    "load_tags",
    "save_tags",
    "track_tags",
    "DEFAULT_RANGE_SIGMA",
    "CalibrationError",
    "CalibrationOptions",
    "OutlierReport",
    "SimulatedCalibration",
    "UwbCalibration",
    "calibrate",
    "hall_constellation",
    "load_heights",
    "load_survey",
    "simulate_calibration_log",
    "wand_path",
    "FIX_COLUMNS",
    "TOA_COLUMNS",
    "Constellation",
    "Dop",
    "DopMap",
    "FixStatus",
    "Fixes",
    "LocateOptions",
    "PlacementResult",
    "PlanSummary",
    "Reader",
    "SimulatedToa",
    "ToaLog",
    "Transmissions",
    "border_candidates",
    "capture_area",
    "compute_dop",
    "constellation_dop",
    "constellation_from_dict",
    "dop_map",
    "estimate_range_sigma",
    "group_transmissions",
    "load_constellation",
    "locate",
    "locate_transmissions",
    "make_constellation",
    "min_readers",
    "optimize_placement",
    "perimeter_layout",
    "predict_toa",
    "read_toa_csv",
    "save_constellation",
    "simulate_toa",
    "summarize",
    "toa_log_from_matrix",
    "toa_residuals",
    "write_fixes_csv",
    "write_toa_csv",
]
