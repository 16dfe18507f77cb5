"""The bench commands of maps: the floor plan with every constant chosen by leaving one floor out
(issue 57, ``map-lofo``), the user's path with a radio map from other walks (issue 60, ``radio-track``).
Registered on :data:`wearnav.cli.bench.bench_app` by :func:`register`."""

from __future__ import annotations

from pathlib import Path

import typer

from wearnav.cli.common import progress_enabled, suite_folder


def bench_map_lofo(
    data: Path = typer.Option(
        ..., "--data", help="An imported dataset whose walks carry surveyed points and floor plans (ILC2 site 1)."
    ),
    out: Path = typer.Option(Path("runs/map-lofo"), "--out", help="Suite folder (odometry/, folds/, results.md)."),
    model: str = typer.Option("phone", "--model", help="The odometry: a shipped model name, a run folder or pdr."),
) -> None:
    """The map-aware path with every constant chosen by leaving one floor out (issue 57): each floor
    scored with the filter's settings, the site yaw and the odometry's drift taken from the other
    floors, beside the map-less path; plans moved, turned or another floor's, to show what the
    verdict catches; per walk, why it went wrong. The data: `wearnav import ilc2
    ../shared/data/ilc2_indoor_location --out data/ilc2`.

    \b
    Example:
      wearnav bench map-lofo --data data/ilc2 --out runs/map-lofo
    """
    from wearnav.bench.map_lofo import run_suite

    suite_folder(out, "bench map-lofo")
    run_suite(data, out, model, progress_enabled())
    typer.echo(f"wrote {out / 'results.md'}")


def bench_radio_track(
    out: Path = typer.Option(Path("runs/radio-track"), "--out", help="Suite folder (walks/, maps/, results.md)."),
    ipin: Path | None = typer.Option(
        None, "--ipin", help="IPIN 2023 walks: a dataset folder of `wearnav import ipin2023`."
    ),
    ilc2: Path | None = typer.Option(None, "--ilc2", help="ILC2 walks: a dataset folder of `wearnav import ilc2`."),
    folds: int = typer.Option(5, "--folds", min=2, help="ILC2: walks held out in this many groups."),
    per_floor: int = typer.Option(20, "--per-floor", min=1, help="ILC2: walks scored per floor."),
) -> None:
    """The path a user gets with a radio map built from other walks (issue 60 §5): `track` on each
    held-out walk (no start, no truth), the shipped phone model and PDR, IPIN 2023 leave one trial out
    (fixes, fixes + radio map, radio map without GNSS) and ILC2 walks held out in groups (radio map
    with and without the plan); scored at the surveyed points, with the issue's targets. Resumes.

    \b
    Example:
      wearnav bench radio-track --ipin data/ipin2023 --ilc2 data/ilc2 --out runs/radio-track
    """
    import warnings

    from wearnav.bench.radio_track import run_suite
    from wearnav.cli.radiomap import recordings_of, torch_one_thread
    from wearnav.errors import ConfigError, WearnavWarning

    if ipin is None and ilc2 is None:
        raise ConfigError("give --ipin and/or --ilc2 (dataset folders of `wearnav import`)")
    suite_folder(out, "bench radio-track")
    torch_one_thread()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WearnavWarning)  # the importers' notes on each walk
        ipin_recs = recordings_of(ipin) if ipin is not None else []
        ilc2_recs = recordings_of(ilc2) if ilc2 is not None else []
    run_suite(out, ipin_recs, ilc2_recs, folds, per_floor, log=typer.echo)
    typer.echo(f"wrote {out / 'results.md'}")


def register(app: typer.Typer) -> None:
    app.command("map-lofo")(bench_map_lofo)
    app.command("radio-track")(bench_radio_track)
