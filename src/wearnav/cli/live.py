"""The ``wearnav`` commands of the live receiver: ``live`` (serve Sensor Logger's HTTP Push),
``live export`` (a stored session as a wearnav dataset folder), ``live bench`` (load, latency and
CPU share) and ``replay`` (send an export as the app would). Registered on the main app by
:mod:`wearnav.cli`; imports stay inside the commands so that ``--help`` stays fast."""

from __future__ import annotations

import secrets
import signal
import socket
import subprocess
import threading
from pathlib import Path

import typer

from wearnav.cli.common import echo_json, on_interrupt, split_list
from wearnav.errors import ConfigError
from wearnav.live.process import start_tracker  # stdlib only: 8 ms at the command line's start
from wearnav.outputs import check_new_dataset, check_suite_folder

# The signals that stop `wearnav live` cleanly (exit 0), as its stop line names them.
STOP_SIGNALS = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM"}

LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")

live_app = typer.Typer(invoke_without_command=True)  # its help: the docstring of live() below


def _lan_address() -> str:
    """This machine's address on its local network, as a phone would reach it (a guess: the
    interface a UDP socket would use; nothing is sent)."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("10.255.255.255", 1))
            return s.getsockname()[0]
    except OSError:
        return "<this machine's address>"


STORE_KINDS = "a SQLite file, or a postgresql:// URL: a store that spans machines, the [postgres] extra"
STORE_HELP = f"The session store ({STORE_KINDS}); created, and the sessions in it resumed."


def redact(url: str) -> str:
    """A store URL without its password (what is printed)."""
    from wearnav.live.store_pg import redact as _redact

    return _redact(url)


def _reuse_port_socket(host: str, port: int) -> socket.socket:
    """A listening socket on ``host:port`` that other processes may bind too (SO_REUSEPORT: the
    kernel spreads new connections over every process listening)."""
    if not hasattr(socket, "SO_REUSEPORT"):
        raise ConfigError("--workers needs SO_REUSEPORT (Linux, BSD, macOS)")
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        raise ConfigError(f"could not listen on {host}:{port} ({exc.strerror})") from None
    sock.listen(2048)
    sock.set_inheritable(False)
    return sock


def _start_workers(workers: int, token: str | None) -> list[subprocess.Popen]:
    """``workers`` − 1 more receiver processes: this command again with ``--workers 1 --reuse-port``,
    each binding the same port with SO_REUSEPORT."""
    import os
    import sys

    argv = list(sys.argv[1:])
    for i, a in enumerate(argv):  # --workers N / --workers=N → 1 (they start no workers of their own)
        if a == "--workers" and i + 1 < len(argv):
            argv[i + 1] = "1"
        elif a.startswith("--workers="):
            argv[i] = "--workers=1"
    env = {**os.environ, **({"WEARNAV_LIVE_TOKEN": token} if token else {})}  # not on the command line
    return [
        subprocess.Popen([sys.executable, "-m", "wearnav", *argv, "--reuse-port"], env=env) for _ in range(workers - 1)
    ]


def _start_trackers(
    store: str, n: int, model: Path | None, plan: Path | None, model_device: str, radiomap: Path | None = None
) -> list[subprocess.Popen]:
    """``n`` ``wearnav live track --store STORE --shard i/n`` processes (stopped with this one)."""
    extra = [*(["--model", str(model)] if model else []), *(["--map", str(plan)] if plan else [])]
    extra += ["--radiomap", str(radiomap)] if radiomap else []
    return [start_tracker(store, (i, n), "--model-device", model_device, *extra) for i in range(n)]


MODEL_DEVICE_HELP = (
    "Where the odometry models run: cpu, cuda or auto (CUDA where there is one). The CPU is the default: "
    "on the GPU machine measured, the receiver kept up more walkers with them there (docs/live-scaling.md)."
)


def _tracker_factory(model: Path | None, plan: Path | None = None, model_device: str = "cpu", radiomap=None):
    """Trackers sharing one set of models (loaded once, on ``model_device``, while the server starts:
    ``SharedModels.preload``); ``plan``: a GeoJSON floor plan every session's page draws under its path;
    ``radiomap``: a loaded radio map (:func:`_load_radiomap`) whose positions of each session's Wi-Fi
    scans join its fixes."""
    from wearnav.live import models, tracker  # torch: only where the server tracks

    shared = models.SharedModels(model_device)
    threading.Thread(target=shared.preload, args=(model,), name="live-preload", daemon=True).start()
    return lambda: tracker.LiveTracker(model=model, models=shared, plan=plan, radiomap=radiomap)


def _load_radiomap(radiomap: Path | None, executor: str):
    """The ``--radiomap`` folder loaded once (a bad one said in one line before the server starts);
    not with Ray, whose tasks may not see the folder."""
    if radiomap is None:
        return None
    if executor == "ray":
        raise ConfigError("--radiomap is for --executor local (a Ray task may not see the folder)")
    from wearnav.fuse.radiomap import RadioMap  # pandas, scikit-learn: ~1.4 s, not at every command's start

    return RadioMap.load(radiomap)


def _check_plan(plan: Path | None) -> None:
    """A bad ``--map`` file is said in one line before the server starts (read about a dummy origin)."""
    if plan is not None:
        from wearnav.plans import read_geojson_plan

        read_geojson_plan(plan, 0.0, 0.0)


def _needs_live_extra() -> None:
    """One line, not a traceback, where the `[live]` extra (starlette, uvicorn) is not installed."""
    import importlib.util

    missing = [m for m in ("starlette", "uvicorn") if importlib.util.find_spec(m) is None]
    if missing:
        raise ConfigError(
            f"`wearnav live` needs {' and '.join(missing)}: pip install 'wearnav[live]' (`make install` includes it)"
        )


@live_app.callback()
def live(
    ctx: typer.Context,
    host: str = typer.Option(
        "127.0.0.1", help="Address to listen on (0.0.0.0: the phone on the same Wi-Fi; then a token is required)."
    ),
    port: int = typer.Option(8000, min=1, max=65535, help="TCP port."),
    store: str = typer.Option("runs/live/live.db", "--store", help=STORE_HELP),
    token: str | None = typer.Option(
        None,
        "--token",
        envvar="WEARNAV_LIVE_TOKEN",
        help="Token the phone sends (made and printed when listening beyond this machine and none is given).",
    ),
    require_token: bool = typer.Option(False, "--require-token", help="Want a token on 127.0.0.1 too."),
    max_body: int = typer.Option(4 * 1024 * 1024, "--max-body", min=1024, help="Largest push body, bytes (413 above)."),
    rate_limit: float = typer.Option(
        100.0, "--rate-limit", min=0.1, help="Messages a second per client (429 above; bursts of twice that)."
    ),
    platform: str | None = typer.Option(
        None,
        help="The phone's platform (ios, watchos, android) when the push "
        "URL does not say (?platform=...): it decides the acceleration sign. "
        "Default: decided from each session's data.",
    ),
    standardised: bool = typer.Option(
        False,
        "--standardised",
        help='"Standardise Units & Frames" is on in the app, when the push URL does not say (?standardisation=true).',
    ),
    model: Path | None = typer.Option(None, "--model", help="Odometry model (as for `wearnav track`)."),
    plan: Path | None = typer.Option(
        None,
        "--map",
        help="A GeoJSON floor plan (as `wearnav track --map`) drawn under every session's path once it has a fix.",
    ),
    radiomap: Path | None = typer.Option(
        None,
        "--radiomap",
        help="A radio map folder (`wearnav radiomap build`): each session's Wi-Fi scans (Android Sensor Logger's "
        "WiFi sensor) become fixes beside the phone's, as for `wearnav track --radiomap`.",
    ),
    no_track: bool = typer.Option(False, "--no-track", help="Store and serve only; no live path."),
    model_device: str = typer.Option("cpu", "--model-device", help=MODEL_DEVICE_HELP),
    mqtt: str | None = typer.Option(
        None, "--mqtt", help="Also subscribe to ws://broker:port/topic (Sensor Logger's MQTT publishing)."
    ),
    executor: str = typer.Option(
        "local",
        "--executor",
        help="Where sessions are tracked: local (in this process) or ray (--trackers processes on a Ray cluster, "
        "sharing --store; this process only stores and serves).",
    ),
    address: str | None = typer.Option(None, "--address", help="The Ray cluster (as ray.init's; --executor ray)."),
    trackers: int | None = typer.Option(
        None,
        "--trackers",
        min=0,
        help="Track in this many `wearnav live track` processes that this command starts and stops with itself "
        "(sharing --store; this process then stores and serves only: a multi-core machine's other cores); "
        "with --executor ray, processes placed on Ray (default 2). Default: track in this process.",
    ),
    workers: int = typer.Option(
        1,
        "--workers",
        min=1,
        help="Receiver processes sharing the port (SO_REUSEPORT; the kernel spreads the phones' connections over "
        "them) and the store; with more than one they only store and serve (as --no-track): `wearnav live track` "
        "tracks.",
    ),
    reuse_port: bool = typer.Option(False, "--reuse-port", hidden=True, help="(one of --workers' processes)"),
):
    """Receive Sensor Logger's HTTP Push: every message stored before its 200, a live path on a page.

    \b
    Example:
      wearnav live --host 0.0.0.0 --port 8000
      (in Sensor Logger: Settings > Data Streaming > HTTP Push, the push URL printed here)
    """
    if ctx.invoked_subcommand is not None:
        return
    _needs_live_extra()
    main = threading.current_thread() is threading.main_thread()
    import uvicorn

    from wearnav.importers.sensorlogger_map import PLATFORMS
    from wearnav.live.app import create_app

    if platform is not None:
        platform = platform.strip().lower()
        if platform not in PLATFORMS:
            raise typer.BadParameter(f"--platform must be one of {', '.join(PLATFORMS)}")
    elif standardised:
        platform = "ios"
    made = False
    if token is None and (require_token or host not in LOCAL_HOSTS):
        token, made = secrets.token_urlsafe(18), True
    if executor not in ("local", "ray"):
        raise typer.BadParameter("--executor: local or ray")
    if address is not None and executor != "ray":
        raise ConfigError("--address is for --executor ray only")
    if executor == "ray" and trackers == 0:
        raise ConfigError("--trackers: at least 1 with --executor ray")
    local = (trackers or 0) if executor == "local" else 0  # tracker processes this command starts
    if local and no_track:
        raise ConfigError("--no-track tracks nowhere and --trackers starts tracker processes: one or the other")
    _check_plan(plan)
    if plan is not None and executor == "ray":
        raise ConfigError("--map is drawn by trackers in this process: not with --executor ray")
    rmap = _load_radiomap(radiomap, executor)
    stores_only = no_track or executor == "ray" or local > 0
    if workers > 1 and not stores_only:
        raise ConfigError(
            "--workers above 1 store and serve only: add --trackers N (or --no-track and `wearnav live track` processes)"
        )
    if reuse_port and not stores_only:
        raise ConfigError("--reuse-port is for --workers' receivers, which store and serve only (--no-track)")
    sock = _reuse_port_socket(host, port) if workers > 1 or reuse_port else None
    factory = None if stores_only else _tracker_factory(model, plan, model_device, rmap)
    app = create_app(
        store,
        token=token,
        max_body=max_body,
        rate_limit=rate_limit,
        tracker_factory=factory,
        platform=platform,
        standardised=standardised,
        shared=sock is not None,
    )
    shown_store = redact(store)
    if mqtt:
        from wearnav.live.mqtt import subscribe

        subscribe(mqtt, app.state.receiver)
    placed: list = []
    if executor == "ray" and not no_track:
        from wearnav.live.trackers import place_on_ray

        placed = place_on_ray(store, trackers or 2, model, address, model_device=model_device)
        typer.echo(f"{trackers or 2} tracker processes placed on Ray (sharing {shown_store})")
    shown = _lan_address() if host in ("0.0.0.0", "::") else host
    query = "" if token is None else (f"?token={token}" if made else "?token=<your token>")
    if not reuse_port:  # (a --workers child says nothing: its parent has said it)
        typer.echo(f"push URL (Sensor Logger > HTTP Push): http://{shown}:{port}/push{query}")
        typer.echo(f"live page: http://{shown}:{port}/{query}")
        if made:
            typer.echo("(the token was made now; give --token to keep one across restarts)")
        if workers > 1:
            typer.echo(f"{workers} receiver processes share port {port} and the store")
    on_interrupt(f"stopped; every acknowledged message is in {shown_store} (`wearnav live` resumes its sessions)")
    children = _start_workers(workers, token) if workers > 1 else []
    if local and not reuse_port:  # (a --workers child starts none: its parent has)
        children += _start_trackers(store, local, model, plan, model_device, radiomap)
        typer.echo(f"{local} tracker processes (`wearnav live track --shard i/{local}`) track the sessions")
    # Ctrl-C and SIGTERM are how a server is stopped: uvicorn shuts down cleanly (open requests
    # answered, every acknowledged message stored) and raises the signal again once it has stopped;
    # it is noted here, and the command ends with one neutral line and exit 0 (README, "wearnav live").
    stopped: list[int] = []
    noted = {s: signal.signal(s, lambda signum, frame: stopped.append(signum)) for s in STOP_SIGNALS} if main else {}
    import gc

    gc.freeze()  # the modules and models loaded so far: out of the collector's sight (issue 61)
    where = {"fd": sock.fileno()} if sock is not None else {"host": host, "port": port}
    try:
        uvicorn.run(app, **where, access_log=False, log_level="warning", proxy_headers=False)
    except SystemExit as exc:  # uvicorn exits when it cannot bind
        raise ConfigError(f"could not listen on {host}:{port} (in use?)") from exc
    finally:
        for s, handler in noted.items():
            signal.signal(s, handler)
        for child in children:
            child.terminate()
        for child in children:
            try:
                child.wait(15)
            except subprocess.TimeoutExpired:
                child.kill()
        app.state.receiver.commits.stop()
        if placed:
            import ray

            for ref in placed:
                ray.cancel(ref, force=True)
    if stopped:
        n = len(app.state.receiver.store.sessions())
        typer.echo(
            f"live: stopped ({STOP_SIGNALS[signal.Signals(stopped[0])]}); {n} session{'s' * (n != 1)} stored in "
            f"{shown_store} "
            "(`wearnav live` resumes them)",
            err=True,
        )


@live_app.command("track")
def live_track(
    store: str = typer.Option(
        "runs/live/live.db", "--store", help="The receiver's session store (" + STORE_KINDS + ")."
    ),
    shard: str = typer.Option(
        "0/1", "--shard", help="i/n: track the sessions of shard i of n (the k-th session to arrive: shard k mod n)."
    ),
    model: Path | None = typer.Option(None, "--model", help="Odometry model (as for `wearnav track`)."),
    executor: str = typer.Option(
        "local", "--executor", help="local (this process tracks --shard) or ray (--trackers processes on Ray)."
    ),
    address: str | None = typer.Option(None, "--address", help="The Ray cluster (as ray.init's; --executor ray)."),
    trackers: int = typer.Option(2, "--trackers", min=1, help="Tracker processes to place (--executor ray)."),
    stats: Path | None = typer.Option(
        None, "--stats", help="Write what this tracker did (sessions, update latency) to this JSON file, every second."
    ),
    plan: Path | None = typer.Option(
        None, "--map", help="A GeoJSON floor plan drawn under every session's path (as `wearnav live --map`)."
    ),
    radiomap: Path | None = typer.Option(
        None,
        "--radiomap",
        help="A radio map folder (`wearnav radiomap build`): each session's Wi-Fi scans (Android Sensor Logger's "
        "WiFi sensor) become fixes beside the phone's, as `wearnav live --radiomap`.",
    ),
    model_device: str = typer.Option("cpu", "--model-device", help=MODEL_DEVICE_HELP),
):
    """Track the sessions a receiver stores, in a process of its own (the receiver runs --no-track).

    \b
    Example:
      wearnav live track --store runs/live/live.db --shard 0/2
      (two trackers beside one receiver: `wearnav live --no-track --store runs/live/live.db`, this,
      and the same with --shard 1/2)
    """
    from wearnav.live.trackers import parse_shard, place_on_ray, run_tracker

    if executor not in ("local", "ray"):
        raise typer.BadParameter("--executor: local or ray")
    if address is not None and executor != "ray":
        raise ConfigError("--address is for --executor ray only")
    from wearnav.live.store import store_missing

    if store_missing(store):
        raise ConfigError(f"no session store at {store} (start `wearnav live --no-track --store {store}` first)")
    on_interrupt("tracker stopped; the store keeps every session (a tracker started again resumes them)")
    _check_plan(plan)
    if plan is not None and executor == "ray":
        raise ConfigError("--map is for --executor local (a Ray task may not see the file)")
    _load_radiomap(radiomap, executor)  # a bad folder said here; run_tracker loads it for its trackers
    if executor == "local":
        run_tracker(
            str(store),
            parse_shard(shard),
            None if model is None else str(model),
            stats=None if stats is None else str(stats),
            plan=None if plan is None else str(plan),
            model_device=model_device,
            radiomap=None if radiomap is None else str(radiomap),
        )
        return
    import ray

    refs = place_on_ray(store, trackers, model, address, model_device=model_device)
    typer.echo(f"{trackers} tracker processes placed on Ray (sharing {store}); Ctrl-C stops them")
    try:
        ray.get(refs)
    finally:
        for ref in refs:
            ray.cancel(ref, force=True)


@live_app.command("export")
def live_export(
    session: str = typer.Argument(..., help="Session id (`/sessions` lists them)."),
    store: str = typer.Option("runs/live/live.db", "--store", help="The session store (" + STORE_KINDS + ")."),
    out: Path = typer.Option(..., "--out", help="Dataset folder to write (as `wearnav import` writes)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace the dataset that --out already holds."),
):
    """Write a stored session as a wearnav dataset folder that `track`, `classify` and the benchmarks read.

    \b
    Example:
      wearnav live export replay-3f2a --store runs/live/live.db --out data/my_walk
    """
    from wearnav.live.export import export_session

    check_new_dataset(out, overwrite, "live export")
    echo_json(export_session(store, session, out).summary())


@live_app.command("bench")
def live_bench(
    out: Path = typer.Option(Path("runs/live-bench"), "--out", help="Folder for results.md / results.json."),
    duration: float = typer.Option(60.0, min=1.0, help="Wall seconds of the load phase."),
    speed: float = typer.Option(10.0, min=1.0, help="Replay speed of the load phase (× real time)."),
    cpu_s: float = typer.Option(30.0, "--cpu-s", min=2.0, help="Seconds of each real-time walkers phase."),
    walkers: str = typer.Option("1,2,4,8", help="Walkers (sessions at once, real time) to try, comma-separated."),
    devices: str = typer.Option(
        "all",
        "--devices",
        help="Walkers' devices, comma-separated: phone (phone-only walkers: the default phone-only model, PDR or the shipped phone model) and/or all (phone, watch, earbuds).",
    ),
    track: bool = typer.Option(
        True, "--track/--no-track", help="Run the live tracker in the CPU phase (where this installation has one)."
    ),
    trackers: int = typer.Option(
        0, "--trackers", min=0, help="Track in this many `wearnav live track` processes beside the receiver (0: in it)."
    ),
    model_device: str = typer.Option("cpu", "--model-device", help=MODEL_DEVICE_HELP),
):
    """Load the receiver (3 devices × 100 Hz at SPEED× for DURATION s) and measure ack latency,
    lost / duplicated samples, then walkers at once at real time: CPU share, update latency, capacity.

    \b
    Example:
      wearnav live bench --out runs/live-bench
    """
    from wearnav.live.bench import run_bench

    try:
        counts = tuple(int(x) for x in split_list(walkers))
    except ValueError:
        raise typer.BadParameter("--walkers: whole numbers, comma-separated") from None
    kinds = tuple(split_list(devices))
    if not kinds or set(kinds) - {"phone", "all"}:
        raise typer.BadParameter("--devices: phone and/or all, comma-separated")
    _needs_live_extra()  # the bench starts `wearnav live`: say so here, not as that child's failure
    check_suite_folder(out, "live bench")
    typer.echo(
        str(
            run_bench(
                out,
                duration_s=duration,
                speed=speed,
                cpu_s=cpu_s,
                track=track,
                walkers=counts,
                devices=kinds,
                trackers=trackers,
                model_device=model_device,
            )
        )
    )


cost_app = typer.Typer(help="What receiving a message and tracking a walker cost this machine (issue 61).")
live_app.add_typer(cost_app, name="cost")


@cost_app.command("receiver")
def cost_receiver(
    messages: int = typer.Option(5000, min=1, help="Messages to post (phone-only pushes of 0.2 s)."),
    walkers: int = typer.Option(100, min=1, help="Sessions they are spread over."),
    senders: int = typer.Option(100, min=1, help="Keep-alive connections sending them (a walker's phone keeps one)."),
    rate: float = typer.Option(500.0, min=0.0, help="Messages a second in all (0: as fast as they go)."),
    store: str | None = typer.Option(
        None, "--store", help="The receiver's store (default a SQLite file in a tmp dir)."
    ),
    workers: int = typer.Option(1, "--workers", min=1, help="Receiver processes sharing the port."),
    floor: bool = typer.Option(
        False,
        "--floor",
        help="Then the same pushes to an app that only reads each body and answers 200, under the same "
        "HTTP server: what no receiver on it goes below here (server_floor_ms_per_message).",
    ),
):
    """Post MESSAGES pushes over HTTP to a real `wearnav live --no-track` on 127.0.0.1 and print its
    CPU per message (user + system, /proc), every message acknowledged and stored.

    \b
    Example:
      wearnav live cost receiver --messages 5000 --walkers 100 --rate 500
    """
    from wearnav.live.cost import receiver_cost

    _needs_live_extra()
    args = ("--workers", str(workers)) if workers > 1 else ()
    echo_json(receiver_cost(messages, walkers, senders, rate, store=store, server_args=args, floor=floor))


@cost_app.command("tracker")
def cost_tracker(
    walk_s: float = typer.Option(90.0, "--walk-s", min=10.0, help="Seconds of simulated walk."),
    walkers: int = typer.Option(8, min=1, help="Phone-only sessions tracked at once."),
    stages: bool = typer.Option(False, "--stages", help="Also where the time goes (each stage's CPU)."),
):
    """Track WALKERS phone-only sessions of a simulated walk in one process, message by message (no
    HTTP), and print the tracking CPU per walker-second of data.

    \b
    Example:
      wearnav live cost tracker --walk-s 90 --walkers 8
    """
    from wearnav.live.cost import tracker_cost

    echo_json(tracker_cost(walk_s, walkers, stages=stages))


def replay(
    export: Path = typer.Argument(..., help="A Sensor Logger export (folder or .zip)."),
    url: str = typer.Option("http://127.0.0.1:8000/push", "--url", help="The receiver's push URL."),
    speed: float = typer.Option(1.0, min=0.01, help="× real time."),
    batch_s: float = typer.Option(0.2, "--batch-s", min=0.01, help="Batch period (s), as set in the app."),
    token: str | None = typer.Option(None, "--token", help="The receiver's token."),
    session: str | None = typer.Option(None, "--session", help="Session id (default: a new one)."),
    no_platform: bool = typer.Option(
        False,
        "--no-platform",
        help="Leave the export's platform out of the URL "
        "(as the app's own push URL does; the receiver decides it from the data).",
    ),
):
    """Send a Sensor Logger export to a receiver as the app pushes while recording.

    \b
    Example:
      wearnav replay my_walk.zip --url http://127.0.0.1:8000/push --speed 10
    """
    from wearnav.live.replay import build, send

    rp = build(export, batch_s=batch_s, session_id=session)
    typer.echo(f"session {rp.session_id}: {len(rp.messages)} messages, {rp.samples} samples", err=True)
    res = send(rp, url, speed=speed, token=token, platform=not no_platform)
    lat = sorted(res.ack_latency_s)
    echo_json(
        {
            "session": rp.session_id,
            "messages": len(rp.messages),
            "acknowledged": len(res.acknowledged),
            "retries": res.retries,
            "wall_s": round(res.wall_s, 2),
            "ack_latency_p50_ms": round(1e3 * lat[len(lat) // 2], 2) if lat else None,
        }
    )


def register(app: typer.Typer) -> None:
    app.add_typer(live_app, name="live")
    app.command("replay")(replay)
