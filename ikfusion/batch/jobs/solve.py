"""``ikfusion batch solve``: many recordings through ``ikfusion solve``.

An input is either a capture folder as ``ikfusion simulate`` writes it (``imu/``,
``sensors.yaml`` and, when present, ``body.yaml`` and the UWB files ``toa.csv``,
``readers.yaml``, ``tags.yaml``) or an IMU recording (MT Manager trial prefix, folder or file, an
MVNX or an IMU CSV) solved with the ``--map`` of the batch command line. Options given on the
command line win over a capture folder's files (``--map`` over ``sensors.yaml``, ``--body`` or
``--height`` over ``body.yaml``); ``--no-uwb`` ignores the UWB files.

Each input is solved in-process by :func:`ikfusion.app.session.solve_actor`, the function behind
``ikfusion solve`` (same defaults, same result folder), so a batch output equals what
``ikfusion solve`` writes. The options are parsed once, when the inputs are expanded.
"""

from __future__ import annotations

import glob
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...app.session import ActorInputs, solve_actor
from ...app.uwb_aiding import UwbInputs
from ...errors import InputError
from ...results.folder import RESULT_FILES
from ..kinds import BatchInput, JobKind, JobOutput, Option, expand_paths, files_under

#: The UWB files of a capture folder, as (solve option, file name).
UWB_FILES: tuple[tuple[str, str], ...] = (
    ("toa", "toa.csv"), ("readers", "readers.yaml"), ("tags", "tags.yaml"))


@dataclass(frozen=True)
class SolveSource:
    """The files one ``solve`` reads (absolute paths; ``None`` when not used)."""

    imu: str
    map: str
    body: str | None = None
    toa: str | None = None
    readers: str | None = None
    tags: str | None = None


@dataclass(frozen=True)
class SolveSettings:
    """The batch options that shape every solve, parsed once (see :func:`parse_options`).

    Attributes:
        height: Body height [m] (wins over a body file), or None.
        window_s: Calibration window [s] (None: automatic); ``pose``: ``npose``/``tpose``.
        forward: ``{segment: axis}`` overriding the heading found from the data, or None.
        rate: Rate [Hz] for files without one, or None.
        correction: How UWB corrects drift (None: the default of ``solve``).
        bvh_up: Up axis of ``motion.bvh`` (``z`` or ``y``).
    """

    height: float | None = None
    window_s: tuple[float, float] | None = None
    pose: str = "npose"
    forward: dict[str, str] | None = None
    rate: float | None = None
    correction: str | None = None
    bvh_up: str = "z"


@dataclass(frozen=True)
class SolveJob:
    """One input's solve: its files and the batch's parsed settings (pickles to workers)."""

    files: SolveSource
    settings: SolveSettings

    def actor(self) -> ActorInputs:
        """The actor :func:`ikfusion.app.session.solve_actor` solves."""
        s, f = self.settings, self.files
        body = None if s.height is not None or f.body is None else Path(f.body)
        return ActorInputs(None, Path(f.imu), Path(f.map), body, s.height, s.window_s, s.pose,
                           s.forward, s.rate)

    def uwb(self) -> UwbInputs | None:
        """The UWB files, when the input has all three."""
        f = self.files
        if f.toa is None or f.readers is None or f.tags is None:
            return None
        return UwbInputs(Path(f.toa), Path(f.readers), Path(f.tags))


def is_capture(path: Path) -> bool:
    """Whether ``path`` is a capture folder (``imu/`` and ``sensors.yaml``)."""
    return path.is_dir() and (path / "imu").is_dir() and (path / "sensors.yaml").is_file()


def _absolute(path: str | Path | None) -> str | None:
    """``path`` made absolute (workers of a remote scheduler run in another folder)."""
    return None if path is None else str(Path(path).resolve())


def _check_file(path: str | None, option: str) -> None:
    """Fail early on an option file that does not exist."""
    if path is not None and not Path(path).is_file():
        raise InputError(f"--{option} must be an existing file", path=path, field=option)


def parse_options(options: Mapping[str, Any]) -> SolveSettings:
    """Validate and parse the options once for the whole batch (the rules of ``solve``).

    Raises:
        InputError: A missing ``--map``/``--body`` file, both ``--body`` and ``--height``, a
            bad ``--calibrate`` or ``--forward``.
    """
    from ...cli import solve as cli_solve

    _check_file(options.get("map"), "map")
    _check_file(options.get("body"), "body")
    if options.get("body") and options.get("height") is not None:
        raise InputError("give --body or --height, not both", field="body")
    window, pose = cli_solve.parse_calibrate(str(options.get("calibrate") or "auto"))
    height, rate = options.get("height"), options.get("rate")
    return SolveSettings(
        height=None if height is None else float(height), window_s=window, pose=pose,
        forward=cli_solve.parse_forward(options.get("forward")),
        rate=None if rate is None else float(rate), correction=options.get("correction"),
        bvh_up=str(options.get("bvh_up") or "z"))


def _capture_input(folder: Path, options: Mapping[str, Any],
                   settings: SolveSettings) -> BatchInput:
    """A capture folder: its IMU files, sensor map and, when present, body and UWB files."""
    files = files_under(folder / "imu")
    sensor_map = options.get("map") or str(folder / "sensors.yaml")
    body = options.get("body")
    if body is None and options.get("height") is None and (folder / "body.yaml").is_file():
        body = str(folder / "body.yaml")
    uwb: dict[str, str | None] = {name: None for name, _ in UWB_FILES}
    present = [folder / f for _, f in UWB_FILES if (folder / f).is_file()]
    if not options.get("no_uwb") and len(present) == len(UWB_FILES):
        uwb = {name: str(folder / f) for name, f in UWB_FILES}
    used = [sensor_map, body, *uwb.values()]
    files += [Path(p) for p in used if p is not None]
    source = SolveSource(imu=str(folder.resolve() / "imu"), map=str(_absolute(sensor_map)),
                         body=_absolute(body), **{k: _absolute(v) for k, v in uwb.items()})
    return BatchInput(str(folder), folder.name, tuple(files), SolveJob(source, settings))


def _recording_files(path: Path) -> list[Path]:
    """The files of an IMU recording given as a file, a folder or an MT Manager prefix."""
    if path.is_file():
        return [path]
    if path.is_dir():
        return files_under(path)
    return sorted(Path(p) for p in glob.glob(glob.escape(str(path)) + "*")
                  if Path(p).is_file())


def _recording_stem(path: Path) -> str:
    """Output folder name of a recording: file stem, folder name or trial prefix."""
    if path.is_file():
        return path.stem
    return path.name.strip("_-. ") or path.parent.name


def _recording_input(path: Path, options: Mapping[str, Any],
                     settings: SolveSettings) -> BatchInput:
    """An IMU recording solved with the batch's ``--map``."""
    files = _recording_files(path)
    if not files:
        raise InputError("no such input: not a file, a folder or an MT Manager trial prefix "
                         "with files", path=path, field="INPUTS")
    sensor_map = options.get("map")
    if sensor_map is None:
        raise InputError("this input is an IMU recording, not a capture folder (imu/ and "
                         "sensors.yaml): give the sensor map with --map", path=path,
                         field="map")
    body = options.get("body")
    files += [Path(p) for p in (sensor_map, body) if p is not None]
    source = SolveSource(imu=str(path.resolve()), map=str(_absolute(sensor_map)),
                         body=_absolute(body))
    return BatchInput(str(path), _recording_stem(path), tuple(files), SolveJob(source, settings))


def expand(inputs: Sequence[str], options: Mapping[str, Any]) -> list[BatchInput]:
    """Expand INPUTS (files, folders, globs) into capture folders and IMU recordings."""
    settings = parse_options(options)
    return [_capture_input(p, options, settings) if is_capture(p)
            else _recording_input(p, options, settings) for p in expand_paths(inputs)]


def run(job: SolveJob, out_dir: Path, options: Mapping[str, Any]) -> JobOutput:
    """Solve one input into ``out_dir`` as ``ikfusion solve`` does; return frames and warnings.

    ``options`` were parsed into ``job.settings`` by :func:`expand`.
    """
    from ...cli.solve import NO_UWB_CORRECTION

    uwb = job.uwb()
    motion = solve_actor(job.actor(), out_dir, uwb, job.settings.correction,
                         job.settings.bvh_up)
    warnings = list(motion.warnings)
    if uwb is None and job.settings.correction:
        warnings.insert(0, NO_UWB_CORRECTION)
    return JobOutput(frames=len(motion), warnings=tuple(warnings))


KIND = JobKind(
    name="solve",
    help="solve many recordings or capture folders in parallel",
    description="Solve every input (a capture folder from `ikfusion simulate`, or an IMU "
    "recording with --map) into its own folder under --out, as `ikfusion solve` does, in "
    "parallel on Dask. Reruns skip inputs already solved with the same files and options; "
    "DIR/batch_report.csv lists input,status,error,frames,seconds.",
    options=(
        Option(("--map",), {"metavar": "FILE", "help": "sensor map YAML or OpenSense XML (needed "
                            "for IMU recordings; overrides a capture folder's sensors.yaml)"}),
        Option(("--body",), {"metavar": "FILE", "help": "body dimensions YAML (overrides a "
                             "capture folder's body.yaml)"}, group="body"),
        Option(("--height",), {"type": float, "metavar": "M", "help": "body height [m] "
                               "(overrides a capture folder's body.yaml)"}, group="body"),
        Option(("--calibrate",), {"default": "auto", "metavar": "auto|T0:T1|npose|tpose",
                                  "help": "calibration window or pose (as for solve)"}),
        Option(("--forward",), {"metavar": "SEGMENT:AXIS", "help": "the sensor axis that "
                                "points forward, e.g. Pelvis:-z"}),
        Option(("--rate",), {"type": float, "metavar": "HZ",
                             "help": "rate for files without one"}),
        Option(("--correction",), {"choices": ["off", "slide", "no-slide"],
                                   "help": "how UWB corrects drift"}),
        Option(("--no-uwb",), {"action": "store_true",
                               "help": "ignore the UWB files of capture folders"}),
        Option(("--bvh-up",), {"choices": ["z", "y"], "default": "z",
                               "help": "up axis of motion.bvh"}),
    ),
    expand=expand,
    run=run,
    outputs=lambda options: RESULT_FILES,
)
