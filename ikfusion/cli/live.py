"""``ikfusion live``: samples in as they arrive, each frame solved causally, poses streamed out."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..live.actor_pose import PoseSink
from ..live.actor_stream import ActorStream
from ..live.frames import FrameAssembler
from ..live.kinematics import PoseKinematics
from ..live.record import ResultRecorder
from ..live.replay import ReplaySource
from ..live.run import LiveActor, LiveLoop
from ..live.samples import SampleSource
from ..live.settings import LiveSettings
from ..live.setup import ActorSetup, replay_setups, source_setups
from ..output_folders import check_output_folder, prepare_output_folder
from . import add_force_option


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``live`` subcommand."""
    p = subparsers.add_parser(
        "live", help="solve samples as they arrive and stream the poses out",
        description="Read samples as they arrive, solve each frame once its samples are in (a "
        "late or lost sample never stalls a frame) with the past only, and send every actor's "
        "pose to the outputs. The first seconds calibrate: stand still in N-pose, then walk a "
        "few steps (the status line says so). 'solve --causal' of the same files gives the same "
        "poses as '--replay ... --speed 0'. Stop with Ctrl-C.")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--replay", metavar="CAPTURE_OR_RECORDING",
                        help="play a simulate capture folder (map, body and UWB files taken "
                        "from it), a session file or a recording (with --map) at its own pace")
    source.add_argument("--lsl", metavar="FILE", help="Lab Streaming Layer inlets named in FILE")
    source.add_argument("--udp", type=int, metavar="PORT", help="UDP sample packets on PORT")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="replay X times faster than recorded (0: as fast as possible, nothing "
                   "dropped)")
    p.add_argument("--map", metavar="FILE", help="sensor map (YAML or OpenSense XML)")
    body = p.add_mutually_exclusive_group()
    body.add_argument("--body", metavar="FILE", help="body dimensions YAML")
    body.add_argument("--height", type=float, metavar="M", help="body height [m]")
    p.add_argument("--session", metavar="FILE", help="several actors (as solve --session) for "
                   "--udp/--lsl; each actor is one character id, numbered from 0")
    p.add_argument("--rate", type=float, default=60.0, metavar="HZ",
                   help="sample rate of a live source [Hz] (a replay has its own)")
    p.add_argument("--correction", choices=["off", "slide", "no-slide"], default=None,
                   help="how UWB corrects drift (replay with UWB files)")
    p.add_argument("--mvn", metavar="HOST:PORT", help="send MVN network streaming over UDP")
    p.add_argument("--vmc", metavar="HOST:PORT", help="send the VMC protocol over OSC (VMC "
                   "has no actor id: actor i of a session goes to PORT + i)")
    p.add_argument("--lsl-out", action="store_true", help="open an LSL outlet of the poses")
    p.add_argument("--view", nargs="?", const="web", metavar="web|native|FILE.rrd",
                   help="draw the bodies in Rerun as they are solved, the timeline following "
                   "the newest frame: 'web' (default) serves the viewer page from the "
                   "installed package (offline), 'native' opens Rerun's desktop viewer (needs "
                   "a display), FILE.rrd writes a recording (open it with 'rerun FILE'); needs "
                   "pip install "
                   "'ikfusion[view]'")
    p.add_argument("--view-port", type=int, default=9090, metavar="PORT",
                   help="HTTP port of the --view web page (default 9090)")
    p.add_argument("--view-host", default="127.0.0.1", metavar="HOST",
                   help="interface the --view web page listens on (default 127.0.0.1: this "
                   "machine only; 0.0.0.0 shows it to a trusted network, no password)")
    p.add_argument("--no-browser", action="store_true",
                   help="--view web: print the page address, do not open a browser")
    p.add_argument("--record", metavar="DIR", help="write the result folder of solve as it "
                   "goes (one sub-folder per actor of a session); readable if the process is "
                   "killed, up to the last second")
    p.add_argument("--bvh-up", choices=["z", "y"], default="z", help="up axis of motion.bvh")
    add_force_option(p)
    p.add_argument("--quiet", action="store_true", help="no status line")
    p.set_defaults(func=run)


def optional_class(module: str, name: str, option: str) -> Any:
    """``module.name`` imported when the option is used; a clear error when it is absent.

    Raises:
        InputError: The module (or a package it needs) is not installed.
    """
    try:
        return getattr(importlib.import_module(module), name)
    except ModuleNotFoundError as err:
        if err.name is not None and module.startswith(err.name):
            raise InputError(f"{option} is not available in this installation ({module} is "
                             "missing)", field=option.lstrip("-")) from None
        raise InputError(f"{option} needs the Python package {err.name!r}; install it (pip "
                         f"install {err.name})", field=option.lstrip("-")) from None
    except AttributeError:
        raise InputError(f"{option} is not available in this installation ({module} has no "
                         f"{name})", field=option.lstrip("-")) from None


def host_port(text: str, option: str) -> tuple[str, int]:
    """``HOST:PORT`` as (host, port).

    Raises:
        InputError: Not of that form, or a port outside 1-65535.
    """
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError(f"{option} must be HOST:PORT (e.g. 127.0.0.1:9763), not {text!r}",
                         field=option.lstrip("-"))
    return host, int(port)


def _check_view(args: argparse.Namespace) -> None:
    """``--view`` checked before anything starts: Rerun installed, its target, port, display.

    Raises:
        InputError: rerun-sdk is missing (naming the ``view`` extra), the target is unknown,
            the page's port is taken, or ``native`` has no display.
    """
    if args.view is None:
        return
    from ..view.rerun_lib import require_rerun
    from ..view.serve import check_port_free

    require_rerun("live --view")
    if args.view not in ("web", "native") and not args.view.lower().endswith(".rrd"):
        raise InputError("--view takes web, native or a file name ending in .rrd, not "
                         f"{args.view!r}", field="view")
    if args.view == "web":
        check_port_free(args.view_port, args.view_host)
    if (args.view == "native" and sys.platform.startswith("linux")
            and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))):
        raise InputError("--view native needs a display (DISPLAY and WAYLAND_DISPLAY are "
                         "unset); use --view web and open the page from another machine "
                         "(--view-host 0.0.0.0), or --view FILE.rrd", field="view")


def _view_sink(args: argparse.Namespace, setups: list[ActorSetup],
               settings: LiveSettings) -> PoseSink:
    """The ``--view`` output, its viewer started (the UWB readers of the first actor drawn)."""
    from ..live.rerun_view import open_view
    from ..view.scene import Readers

    uwb = next((s.uwb for s in setups if s.uwb is not None), None)
    readers = None if uwb is None else Readers(uwb.constellation.ids,
                                               uwb.constellation.positions)
    return open_view(args.view, settings.view_rate_hz, readers, args.view_port,
                     args.view_host, not args.no_browser,
                     lambda text: print(text, file=sys.stderr, flush=True), len(setups) > 1)


def _sinks(args: argparse.Namespace, setups: list[ActorSetup],
           settings: LiveSettings) -> list[PoseSink]:
    sinks: list[PoseSink] = []
    if args.mvn:
        sinks.append(optional_class("ikfusion.live.mvn_stream", "MvnStreamSink", "--mvn")(
            *host_port(args.mvn, "--mvn")))
    if args.vmc:  # VMC has no actor id: one port per actor, from PORT on
        vmc = optional_class("ikfusion.live.vmc", "VmcSink", "--vmc")
        host, port = host_port(args.vmc, "--vmc")
        sinks += [vmc(host, port + i, actor=s.name if len(setups) > 1 else None)
                  for i, s in enumerate(setups)]
    if args.lsl_out:
        sinks.append(optional_class("ikfusion.live.lsl_outlet", "LslOutletSink", "--lsl-out")(
            setups[0].rate))
    if args.view is not None:  # last: the others' mistakes are found before a server starts
        sinks.append(_view_sink(args, setups, settings))
    return sinks


def _source(args: argparse.Namespace, setups: list[ActorSetup], toa: Any) -> SampleSource:
    if args.replay:
        streams = [s.samples(named=len(setups) > 1) for s in setups]
        return ReplaySource([*streams, *([toa] if toa is not None else [])], args.speed)
    if args.udp is not None:
        return optional_class("ikfusion.live.udp_source", "UdpSource", "--udp")(args.udp)
    return optional_class("ikfusion.live.lsl_source", "LslSource", "--lsl")(Path(args.lsl))


def _recorders(args: argparse.Namespace, setups: list[ActorSetup], settings: LiveSettings,
               contacts: list[list[str]]) -> list[ResultRecorder | None]:
    if not args.record:
        return [None] * len(setups)
    root = Path(args.record)
    if len(setups) == 1:
        folders = [root]
    else:
        check_output_folder(root, args.force)
        folders = [root / s.name for s in setups]
        for folder in folders:
            check_output_folder(folder, args.force)
        prepare_output_folder(root, "live --record --session", args.force)
    return [ResultRecorder(f, s.model, c, settings.flush_s, args.bvh_up, args.force)
            for f, s, c in zip(folders, setups, contacts)]


def run(args: argparse.Namespace) -> int:
    """Run ``ikfusion live``."""
    if args.speed < 0:
        raise InputError("--speed must be 0 (as fast as possible) or more", field="speed")
    _check_view(args)
    settings = LiveSettings.load()
    if args.replay:
        if args.session:
            raise InputError("--replay takes the session file itself; drop --session",
                             field="session")
        setups, toa = replay_setups(Path(args.replay), Path(args.map) if args.map else None,
                                    Path(args.body) if args.body else None, args.height,
                                    args.correction)
    else:
        setups, toa = source_setups(Path(args.map) if args.map else None,
                                    Path(args.body) if args.body else None, args.height,
                                    Path(args.session) if args.session else None,
                                    args.rate), None
    paced = not args.replay or args.speed > 0
    streams = [ActorStream(s.model, s.sensor_map, s.rate, correction_for=s.uwb,
                           settings=settings, solve_startup=not paced) for s in setups]
    recorders = _recorders(args, setups, settings,
                           [st.solver.contact_names for st in streams])
    sinks = _sinks(args, setups, settings)
    actors = []
    for i, (setup, stream, recorder) in enumerate(zip(setups, streams, recorders)):
        period = 1.0 / setup.rate
        wall = None if not paced else settings.deadline_periods * period / (
            args.speed if args.replay else 1.0)
        assembler = FrameAssembler(setup.sensor_map, setup.rate, settings.deadline_periods,
                                   settings.clock_jump_s, wall)
        actors.append(LiveActor(setup.name, i, stream, assembler, PoseKinematics(setup.model),
                                recorder))
    loop = LiveLoop(actors, sinks, paced, settings.latency_budget_s,
                    None if args.quiet else sys.stderr)
    stopped = False
    try:
        loop.run(_source(args, setups, toa))
    except KeyboardInterrupt:
        stopped = True
        loop.finish()
    finally:
        for sink in sinks:
            try:
                sink.close()
            except OSError as err:  # an output gone at the end: said, the results are kept
                loop.sink_errors.append(f"{type(sink).__name__}: {err}")
        for actor, setup in zip(actors, setups):
            _close(actor, setup, loop)
    if stopped:
        print("stopped (Ctrl-C)", file=sys.stderr)
    return 0


def _close(actor: LiveActor, setup: ActorSetup, loop: LiveLoop) -> None:
    """Final summary of one actor: its result folder closed, a line on the terminal."""
    warnings = actor.stream.all_warnings() + loop.sink_errors
    if actor.dropped:
        warnings.append(f"{actor.dropped} frame(s) dropped: the solver fell behind the source")
    summary = actor.summary()
    if actor.recorder is not None:
        extra: dict[str, Any] = {"live": summary, "actor": actor.name}
        cal = actor.stream.calibration
        if cal is not None:
            extra["calibration"] = {"method": cal.method, "heading_deg": cal.heading_deg,
                                    "window_s": [cal.window[0] / setup.rate,
                                                 cal.window[1] / setup.rate]}
        bridged = actor.stream.bridged()
        extra["bridged"] = bridged.summary() if bridged else {}
        if setup.uwb is not None and setup.uwb.correction is not None:
            aiding = setup.uwb.aiding()
            extra["uwb"] = aiding.summary()
            warnings += aiding.warnings
        actor.recorder.set_summary(extra)
        actor.recorder.close(warnings)
    for warning in warnings:
        print(f"warning: {actor.name}: {warning}", file=sys.stderr)
    p50, p99 = summary["latency_ms_p50"], summary["latency_ms_p99"]
    latency = "" if p50 is None else f", latency p50 {p50:.1f} ms p99 {p99:.1f} ms"
    where = f" into {actor.recorder.folder}" if actor.recorder is not None else ""
    print(f"{actor.name}: {actor.frames} frames solved{where}, {actor.dropped} dropped"
          f"{latency}")
