"""The ``wearnav`` commands that label a recording: ``label-from-fixes`` (IMU segments labelled by the
phone's own location fixes, EasyTrack's labels) and ``classify`` (its activity or placement per
window). Registered on the main app by :mod:`wearnav.cli`; imports stay inside the commands so
that ``--help`` stays fast."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import typer

from wearnav.cli.common import check_input, check_out_folder_path, progress_enabled

_LABEL_FROM_FIXES_HELP = (
    "Label IMU segments by the phone's location fixes (EasyTrack); their noise where truth is known."
)


def label_from_fixes(
    dataset: Path = typer.Argument(..., help="A dataset folder whose recordings have phone IMU and location fixes."),
    out: Path = typer.Option(
        ...,
        "--out",
        help="Folder for segments.npz, label_noise.json and, where the recordings "
        "have dense truth, label_noise_cdf.png.",
    ),
    segment: float = typer.Option(1.0, "--segment", help="Segment length, seconds (between fix times)."),
    rate: float = typer.Option(25.0, help="IMU rate of the segments, Hz."),
):
    """Phone labels (EasyTrack eq. 4): IMU segments labelled by the fixes at their ends; label-noise
    statistics (eqs. 5–7) where the recordings have dense truth.

    \b
    Example:
      wearnav label-from-fixes data/sim --out labels
    """
    from wearnav.dataset import Dataset
    from wearnav.fixlabels import LabelConfig, label_dataset, noise_summary, plot_noise_cdf
    from wearnav.outputs import staged_output
    from wearnav.runs import write_json

    seg = label_dataset(Dataset.open(dataset), LabelConfig(segment_s=segment, rate=rate), progress=progress_enabled())
    summary = noise_summary(seg)
    with staged_output(out, "label_noise.json", "label-from-fixes") as stage:  # all three files or none
        seg.save(stage / "segments.npz")
        write_json(stage / "label_noise.json", summary)
        png = plot_noise_cdf(seg, stage / "label_noise_cdf.png")
    for name in ("segments.npz", "label_noise.json") + (("label_noise_cdf.png",) if png else ()):
        typer.echo(str(out / name))
    median = summary["label_noise_median_cm"]
    noise = (
        f"median label noise {median} cm"
        if median is not None
        else "label noise not measured: the recordings have no dense truth to compare the labels with "
        "(so no label_noise_cdf.png)"
    )
    typer.echo(f"{summary['segments']} segments, {summary['length_km']} km; {noise}")


def classify_(
    input_: Path = typer.Argument(
        ..., metavar="INPUT", help="A recording (.h5), a dataset folder, or a Sensor Logger export (folder or zip)."
    ),
    model: Path | None = typer.Option(
        None,
        "--model",
        help="A classifier run folder (from `wearnav bench har`) "
        "or its file of `wearnav export` (.onnx, .pt); default: the shipped activity "
        "model (`wearnav models`).",
    ),
    out: Path = typer.Option(..., "--out", help="Folder for <name>_intervals.csv and <name>_timeline.png."),
):
    """Label a recording's activity (or placement) per window: intervals CSV + timeline PNG over |acc|.

    \b
    Example:
      wearnav classify my_walk.zip --out activity
      wearnav classify data/sim --model runs/har/runs/uci-hapt/baseline --out activity
    """
    from wearnav.train.resolve import locate_model

    # Refused before torch is imported: --out, --model (a shipped model's folder where none is
    # given or one is named), the input.
    check_out_folder_path(out)
    located = locate_model(model, "classify") if model is not None else None
    check_input(input_)
    from wearnav.recording import Recording
    from wearnav.train.labelling import label_recordings
    from wearnav.train.resolve import resolve_model

    classifier = resolve_model(located, "classify") if located is not None else None  # refused before the input is read
    recs: Iterable[Recording]
    if input_.is_file() and input_.suffix == ".h5":
        one = Recording.load(input_)
        recs, devices = [one], set(one.devices)
    elif (input_ / "manifest.csv").is_file():
        from wearnav.dataset import Dataset

        ds = Dataset.open(input_)
        recs = iter(ds)
        devices = {d for row in ds.manifest["devices"].astype(str) for d in row.split(";")}
    else:
        from wearnav.importers import sensorlogger

        read = list(sensorlogger.read(input_))
        recs, devices = read, {d for r in read for d in r.devices}
    if located is None:  # the shipped model for the devices the input has (phone, else watch)
        located = locate_model(None, "classify", sorted(devices))
        typer.echo(f"model: shipped {Path(located).name} (the input has {', '.join(sorted(devices))})")
        classifier = resolve_model(located, "classify")
    labelled = label_recordings(recs, located, out, classifier)
    for path in labelled["files"]:
        typer.echo(str(path))
    typer.echo(f"labels the model knows: {', '.join(labelled['classes'])}")
    assert classifier is not None  # resolved above, from --model or the input's devices
    thr = getattr(classifier[0], "unknown_threshold", None)
    if thr is not None:
        typer.echo(f"windows whose top probability is under {thr:.2f} are labelled unknown")
    if (still := getattr(classifier[0], "still_rule", None)) is not None:
        typer.echo(f"  (standing or sitting: where the two together are under {still.threshold:.2f})")


def register(app: typer.Typer) -> None:
    app.command("label-from-fixes", short_help=_LABEL_FROM_FIXES_HELP)(label_from_fixes)
    app.command("classify")(classify_)
