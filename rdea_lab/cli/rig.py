"""CLI commands for the rig: ``rdea-lab rig serve`` (the built-in emulator)."""

from __future__ import annotations

import gc
import signal
import threading

import click

from ..api import _cli as api
from .errors import EXIT_HELP, die, flush_stdout


@click.group(epilog=EXIT_HELP)
def rig():
    """The test rig: serve the built-in emulator."""


@rig.command(epilog=EXIT_HELP)
@click.option("--specimen", "card_path", required=True, type=click.Path(dir_okay=False),
              help="Specimen card (YAML) of the roll on the emulated rig.")
@click.option("--truth", "truth_path", type=click.Path(dir_okay=False),
              help="Truth file: true physics and instrument effects [default: truth/paper2021.yaml].")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; anything but loopback needs --token-file.")
@click.option("--port", default=5025, show_default=True, type=click.IntRange(0, 65535),
              help="TCP port (0: any free port).")
@click.option("--realtime", is_flag=True, help="Pace runs at wall-clock speed (default: as fast as fetched).")
@click.option("--token-file", "token_file", type=click.Path(dir_okay=False),
              help="File holding the token clients must send first (SYST:AUTH <token>).")
@click.option("--fault", "faults", multiple=True, metavar="KIND-at=SECONDS[:DURATION]",
              help="Inject a fault at a run time: disconnect-at=, breakdown-at=, stall-at=; for DURATION s or "
                   "to the end: interlock-at= (door open), overheat-at=, drift-at= (repeatable).")
@click.option("--max-voltage", default="3 kV", show_default=True, help="The rig's own voltage limit.")
@click.option("--max-field", default="80 V/um", show_default=True,
              help="The rig's own field limit, checked with the card's thickness.")
@click.option("--max-stretch", default="2", show_default=True, help="The rig's own stretch limit.")
@click.option("--max-force", default="50 N", show_default=True, help="The rig's own force limit.")
@click.option("--heartbeat", type=click.FloatRange(0.1, 3600), default=10.0, show_default=True,
              help="Seconds a run may go without a command from its client before the rig aborts it.")
def serve(card_path, truth_path, host, port, realtime, token_file, faults, max_voltage, max_field, max_stretch,
          max_force, heartbeat):
    """Serve the built-in rig emulator (docs/rig-protocol.md) until Ctrl-C.

    The emulated roll has its own "true" physics and instrument effects
    (the truth file); every dataset it makes says so (*IDN? model
    rig-emulator, SYST:TRUTH?). The rig keeps its own limits (--max-*), which
    no client can raise, and aborts a run whose client falls silent
    (--heartbeat); any connection may stop a run (ABOR, *RST).

    \b
    Example:
      rdea-lab rig serve --specimen specimens/specimen2.yaml --port 5025
      rdea-lab run protocols/blocking_force.yaml --specimen specimens/specimen2.yaml \\
          --backend rig --rig tcp://127.0.0.1:5025
    """
    from ..specs import Limits, load_specimen, read_token  # here: the module loads for --help too

    parsed = api.parse_faults(faults)
    limits = Limits.from_options({"max_voltage": max_voltage, "max_field": max_field, "max_stretch": max_stretch,
                                  "max_force": max_force})
    token = read_token(token_file, "--token-file", warn=lambda m: click.echo(f"rdea-lab: warning: {m}", err=True)) \
        if token_file else None
    if token is None and not api.is_loopback(host):
        die(f"--host {host}: not a loopback address; give --token-file so that only clients "
            "with the token can drive the rig")
    truth_path = str(api.project_default(truth_path, api.DEFAULT_TRUTH, "--truth"))
    card = load_specimen(card_path)
    truth = api.load_truth(truth_path)
    try:
        server = api.RigServer(card, truth, host=host, port=port, token=token, realtime=realtime, faults=parsed,
                               truth_source=truth_path, limits=limits, heartbeat=heartbeat)
        bound_host, bound_port = server.start()
    except OSError as exc:
        die(f"--host/--port: cannot listen on {host}:{port} ({exc.strerror or exc})")
    stop = threading.Event()
    try:
        previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    except ValueError:  # not the main thread (embedded use): Ctrl-C / stop only
        previous = None
    shown = f"[{bound_host}]" if ":" in bound_host else bound_host
    try:
        api.dedicate_process()  # serving is all this process does now: no full collection delays an ABOR
        click.echo(f"rig emulator: {card.id} (truth {truth.name}, {'realtime' if realtime else 'virtual time'}"
                   f"{', faults ' + ', '.join(faults) if faults else ''}; limits {max_voltage}, {max_field}, "
                   f"stretch {max_stretch}, {max_force}) listening on tcp://{shown}:{bound_port}",
                   nl=True)
        flush_stdout()
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        server.shutdown()  # voltage off, connections closed
        gc.unfreeze()  # an embedded serve hands its caller's heap back to the collector
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
