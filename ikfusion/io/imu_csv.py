"""Generic IMU CSV for data from other vendors (SPEC section 4).

Columns ``time,sensor,qw,qx,qy,qz`` and optionally ``ax,ay,az,gx,gy,gz``: one row per sensor
and sample, time in seconds, quaternion ``R_world_sensor`` scalar first (ENU world), specific
force [m/s^2] and rate [rad/s] in the sensor frame. Samples are placed on a common time base at
the median sample interval; missing samples are lost packets (slerp-filled, flagged invalid).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..rotations import quat_wxyz_to_matrix
from .mtmanager import ImuRecording, SensorStream, _fill_gaps

REQUIRED = ("time", "sensor", "qw", "qx", "qy", "qz")
OPTIONAL = ("ax", "ay", "az", "gx", "gy", "gz")


def read_imu_csv(path: str | Path) -> ImuRecording:
    """Read a generic IMU CSV.

    Raises:
        InputError: Missing columns, non-numeric values (naming line and column), one sample.
    """
    file = Path(path)
    try:
        with file.open(newline="") as f:
            rows = list(csv.reader(f))
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", path=file) from err
    if not rows:
        raise InputError("empty file", path=file, line=1)
    header = [h.strip() for h in rows[0]]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputError(f"columns missing: {', '.join(missing)} (need {','.join(REQUIRED)})",
                         path=file, line=1, field=missing[0])
    numeric = [c for c in (*REQUIRED, *OPTIONAL) if c in header and c != "sensor"]
    index = {c: header.index(c) for c in (*numeric, "sensor")}
    values = np.full((len(rows) - 1, len(numeric)), np.nan)
    sensors = []
    for r, row in enumerate(rows[1:]):
        if len(row) < len(header):
            raise InputError(f"{len(row)} fields where the header has {len(header)}", path=file,
                             line=r + 2, field=header[min(len(row), len(header) - 1)])
        sensors.append(row[index["sensor"]].strip())
        for k, c in enumerate(numeric):
            text = row[index[c]].strip()
            if text and text.lower() != "nan":
                try:
                    values[r, k] = float(text)
                except ValueError:
                    raise InputError(f"not a number: {text!r}", path=file, line=r + 2,
                                     field=c) from None
    t = values[:, numeric.index("time")]
    if not np.isfinite(t).all():
        raise InputError("time must be given on every row", path=file,
                         line=int(np.argmin(np.isfinite(t))) + 2, field="time")
    steps = np.diff(np.unique(t))
    if not len(steps):
        raise InputError("fewer than two samples", path=file)
    dt = float(np.median(steps))
    slot = np.round((t - t.min()) / dt).astype(int)
    n = int(slot.max()) + 1
    streams = {}
    names = np.array(sensors)
    for sid in dict.fromkeys(sensors):
        sel = names == sid
        idx = slot[sel]
        block = values[sel]
        q = block[:, [numeric.index(c) for c in ("qw", "qx", "qy", "qz")]]
        R = np.full((n, 3, 3), np.nan)
        R[idx] = quat_wxyz_to_matrix(q)
        valid = np.zeros(n, dtype=bool)
        valid[idx] = np.isfinite(R[idx]).all(axis=(1, 2))
        _fill_gaps(R, valid, idx)

        def vector(cols: tuple[str, str, str], idx: np.ndarray = idx,
                   block: np.ndarray = block) -> np.ndarray | None:
            if not all(c in numeric for c in cols):
                return None
            out = np.full((n, 3), np.nan)
            out[idx] = block[:, [numeric.index(c) for c in cols]]
            return out

        span = int(idx.max() - idx.min() + 1)
        streams[sid] = SensorStream(sid, R, valid, vector(("ax", "ay", "az")), None,
                                    vector(("gx", "gy", "gz")), None, int(sel.sum()),
                                    span - len(np.unique(idx)), header, file)
    return ImuRecording(np.arange(n) * dt, 1.0 / dt, streams)
