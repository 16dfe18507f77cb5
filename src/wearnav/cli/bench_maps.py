"""The bench command of the map-aware path: every constant chosen by leaving one floor out (issue 57).
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


def register(app: typer.Typer) -> None:
    app.command("map-lofo")(bench_map_lofo)
