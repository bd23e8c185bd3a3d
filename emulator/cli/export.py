"""``psns-hil export RUN --kml / --gpx / --mcap``, and the viewer outputs of ``psns-hil run``.

``export`` converts an existing run directory (an old run, a campaign member kept with ``--keep-all``):
``--mcap`` writes ``run.mcap`` (:mod:`emulator.postrun.mcap_out`), ``--kml`` / ``--gpx`` the truth and estimated
tracks with faults and outages (:mod:`emulator.postrun.tracks`), ``--tables`` the raw sensor tables
(:mod:`emulator.postrun.sensor_tables`). ``psns-hil run`` writes the sensor tables at the end of every run
(``--no-tables``: not), ``run.mcap`` with ``--mcap``, and serves the run live with ``--foxglove``
(:mod:`emulator.postrun.live`: the same channels as run.mcap, D-7.28) (run.mcap's cost is half the run: docs/
decisions/emulator-runtime.md D-7.15).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..errors import EmulatorError

__all__ = ["add_parser", "add_run_arguments", "after_run", "run"]


def add_run_arguments(r: argparse.ArgumentParser) -> None:
    """The viewer switches of ``psns-hil run``."""
    r.add_argument("--mcap", action="store_true",
                   help="also write run.mcap (Foxglove / any MCAP reader) at the end of the run")
    r.add_argument("--no-tables", action="store_true",
                   help="do not write the raw sensor tables (imu.csv, gnss.csv, psns_frames.csv) at the end")
    r.add_argument("--foxglove", nargs="?", const="127.0.0.1:8765", default=None, metavar="HOST:PORT", type=_host_port,
                   help="serve the run live over the Foxglove WebSocket protocol, read-only (default 127.0.0.1:8765; "
                        "port 0: any free port)")


def _host_port(text: str) -> str:
    from ..postrun.live import parse_host_port

    try:
        parse_host_port(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{text}: {exc} (HOST:PORT, HOST or :PORT)") from None
    return text


def on_started(args: argparse.Namespace, emu: Any) -> None:
    """Start the live Foxglove view (``--foxglove``) once the run's links and recorder exist."""
    spec = getattr(args, "foxglove", None)
    if spec is None or emu.recorder is None:
        return
    import sys

    from ..postrun.live import LiveServer, parse_host_port

    host, port = parse_host_port(spec)
    server = LiveServer(host, port)
    server.follow(emu.recorder.run_dir)  # the run directory as the recorder flushes it: run.mcap's channels
    try:
        port = server.start()
    except OSError as exc:  # the run is under way: it goes on, without the live view
        sys.stderr.write(f"foxglove: cannot listen on {host}:{port} ({exc.strerror}); the run goes on without the "
                         "live view\n")
        return
    args.live_server = server
    sys.stderr.write(f"foxglove: ws://{host}:{port} (Foxglove WebSocket, read-only)\n")
    sys.stderr.flush()


def after_run(args: argparse.Namespace, run_dir: Path) -> list[Path]:
    """The viewer outputs ``psns-hil run`` writes once the run directory is complete; returns the files written."""
    live = getattr(args, "live_server", None)
    if live is not None:
        live.close()
        if live.error is not None:
            import sys

            sys.stderr.write(f"foxglove: the live view stopped following the run: {live.error}\n")
    if not (run_dir / "capture.psnscap").exists():
        return []
    written: list[Path] = []
    if not getattr(args, "no_tables", False):
        from ..postrun.sensor_tables import write_sensor_tables

        written += [run_dir / name for name in write_sensor_tables(run_dir)]
    if getattr(args, "mcap", False):
        from ..postrun.mcap_out import write_run_mcap

        written.append(write_run_mcap(run_dir).path)
    return written


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register ``psns-hil export`` on an argparse sub-parser collection."""
    e: argparse.ArgumentParser = sub.add_parser(
        "export", help="write KML / GPX tracks, run.mcap or the raw sensor tables of an existing run directory",
        description="convert a run directory for navigation tools: Google Earth / GIS (KML, GPX), Foxglove and "
                    "other MCAP readers (run.mcap), spreadsheets (imu.csv, gnss.csv, psns_frames.csv)")
    e.add_argument("run_dir", help="a run directory (nav.csv, truth.csv, events.jsonl, capture.psnscap)")
    e.add_argument("--kml", nargs="?", const="", metavar="FILE", help="KML tracks (default RUN/tracks.kml)")
    e.add_argument("--gpx", nargs="?", const="", metavar="FILE", help="GPX tracks (default RUN/tracks.gpx)")
    e.add_argument("--mcap", nargs="?", const="", metavar="FILE", help="MCAP recording (default RUN/run.mcap)")
    e.add_argument("--tables", action="store_true", help="raw sensor tables beside nav.csv")
    return e


def run(args: argparse.Namespace) -> int:
    """``psns-hil export``: 0 written, 2 not a run directory or nothing asked."""
    from rich.console import Console

    run_dir = Path(args.run_dir)
    if not (run_dir / "nav.csv").is_file():
        raise EmulatorError(f"{run_dir}: not a run directory (no nav.csv)")
    if args.kml is None and args.gpx is None and args.mcap is None and not args.tables:
        raise EmulatorError("psns-hil export: say what to write (--kml, --gpx, --mcap, --tables)")
    console = Console(highlight=False)
    if args.kml is not None or args.gpx is not None:
        from ..postrun.tracks import load_tracks, write_gpx, write_kml

        tracks = load_tracks(run_dir)
        if args.kml is not None:
            console.print(f"kml: {write_kml(tracks, Path(args.kml) if args.kml else run_dir / 'tracks.kml')}")
        if args.gpx is not None:
            console.print(f"gpx: {write_gpx(tracks, Path(args.gpx) if args.gpx else run_dir / 'tracks.gpx')}")
    if args.mcap is not None:
        from ..postrun.mcap_out import write_run_mcap

        st = write_run_mcap(run_dir, Path(args.mcap) if args.mcap else None)
        console.print(f"mcap: {st.path} ({sum(st.messages.values())} messages on {len(st.messages)} channels)")
    if args.tables:
        from ..postrun.sensor_tables import write_sensor_tables

        for name, n in write_sensor_tables(run_dir).items():
            console.print(f"{name}: {n} rows")
    return 0
