"""The questions docs/results.md answers, one section each (issue 58 §1): the registry that
:mod:`wearnav.bench.results` builds the page from and refuses to break. A suite's page joins the
results page only where its folder answers a question here; a rerun replaces that question's
section, and the number "At a glance" (and the README's first screen) leads with comes from its
:class:`Pick`."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Pick:
    """One number a question leads with: the cell of column ``column`` (a header cell containing it)
    in the first row whose label cells, joined by `` | ``, match the regex ``row``, in the first
    table below a ``### `` heading matching ``under`` ('' = any table of the section)."""

    label: str
    row: str
    column: str
    under: str = ""


@dataclass(frozen=True)
class Question:
    """A question the results page answers: ``title`` heads its section; ``suites`` are the suite
    folder names whose page answers it (the first is the one that answers it now); ``picks`` the
    numbers "At a glance" (and, with ``readme``, the README's first screen) lead with, else the
    section's first metric column."""

    id: str
    group: str
    title: str
    suites: tuple[str, ...]
    picks: tuple[Pick, ...] = ()
    readme: str = ""


_IPIN, _ILC2 = r"^IPIN 2023[^|]*", r"^ILC2[^|]*"  # a row's building, protocol and path cells
_KNOWN, _USER = r" \| known start[^|]*", r" \| user \(own fixes[^|]*"
_SHIPPED_PHONE = r"the shipped recipe · cadence speed, pointing within 30°"  # `track`'s path: speed snapped
_SHIPPED_MULTI = r"the shipped recipe · cadence speed"  # multi_speed cadence (its MODEL_CARD.md)
_PHONE, _MULTI = "The phone model", "The multi-device model"  # the `### ` headings of its page

# The questions, in the page's order. Chosen from the 60 sections of docs/results.md at 26c9b80:
# for each question the newest section, and for the shipped models the section of the run whose
# weights ship (src/wearnav/pretrained/models/*/MODEL_CARD.md: phone at dc3c296, phone-watch-earbuds
# at 74b7527); the 41 others (older runs, and variants measured and not shipped) are listed in
# docs/history.md. Each question's suites: the folder that answers it now, then the folder the
# README's command writes (`runs/pretrained`, `runs/fusion`, ...), whose rerun replaces it. A suite
# folder that answers no question here is refused: register it (a new question, or the one it
# answers now), so an experiment's page never stands beside the answer unasked.
QUESTIONS: tuple[Question, ...] = (
    Question(
        "shipped-phone",
        "Shipped models in buildings they never saw",
        "How good is the shipped `phone` model against PDR in buildings it never saw?",
        ("pretrain-phone", "pretrained"),
        (
            Pick("IPIN 2023: `track`", _IPIN + _KNOWN + r" \| " + _SHIPPED_PHONE + "$", "median (m)", _PHONE),
            Pick("PDR", _IPIN + _KNOWN + r" \| pdr$", "median (m)", _PHONE),
            Pick("ILC2: `track`", _ILC2 + _KNOWN + r" \| " + _SHIPPED_PHONE + "$", "median (m)", _PHONE),
            Pick("PDR", _ILC2 + _KNOWN + r" \| pdr$", "median (m)", _PHONE),
        ),
        readme="The path from a phone alone (`track`, shipped `phone` model), known start, against PDR",
    ),
    Question(
        "shipped-multi",
        "Shipped models in buildings they never saw",
        "How good is the shipped `phone-watch-earbuds` model against PDR in buildings it never saw (the phone alone there)?",
        ("pretrain-multi-mse", "pretrained"),
        (
            Pick("IPIN 2023: `track`", _IPIN + _KNOWN + r" \| " + _SHIPPED_MULTI + "$", "median (m)", _MULTI),
            Pick("PDR", _IPIN + _KNOWN + r" \| pdr$", "median (m)", _MULTI),
            Pick("ILC2: `track`", _ILC2 + _KNOWN + r" \| " + _SHIPPED_MULTI + "$", "median (m)", _MULTI),
            Pick("PDR", _ILC2 + _KNOWN + r" \| pdr$", "median (m)", _MULTI),
        ),
    ),
    Question(
        "seeds-phone",
        "Shipped models in buildings they never saw",
        "How much does the shipped `phone` recipe vary over training seeds?",
        ("seeds-simonly-snapped-polar-heading",),
    ),
    Question(
        "seeds-multi",
        "Shipped models in buildings they never saw",
        "How much does the shipped `phone-watch-earbuds` recipe vary over training seeds?",
        ("seeds-multi-mse",),
    ),
    Question(
        "users-path",
        "The user's path",
        "How close is `track`'s path on the user's own fixes (smoother, beacons, a floor plan) against the raw fixes?",
        ("pretrain-phone", "pretrained"),
        (
            Pick(
                "IPIN 2023: smoother",
                _IPIN + _USER + r" \| " + _SHIPPED_PHONE + r" · smoother[^|]*$",
                "median (m)",
                _PHONE,
            ),
            Pick(
                "fixes + beacons + barometer",
                _IPIN + _USER + r" \| " + _SHIPPED_PHONE + r" · particle filter[^|]*$",
                "median (m)",
                _PHONE,
            ),
            Pick("raw fixes", _IPIN + _USER + r" \| raw phone fixes$", "median (m)", _PHONE),
            Pick(
                "ILC2 from a known start, with its floor plan",
                _ILC2 + _KNOWN + r" \| " + _SHIPPED_PHONE + " · map-aware$",
                "median (m)",
                _PHONE,
            ),
        ),
        readme="Your path on your own location fixes (`track`), against the raw fixes",
    ),
    Question(
        "map-lofo",
        "The user's path",
        "Does a floor plan help in a building the filter was not tuned in (every floor held out in turn), and what does it cost where it does not fit?",
        ("map-lofo",),
        tuple(Pick(f"{f} held out", rf"^{f}$", "median ratio", "Every floor") for f in ("B1", "F1", "F2", "F3", "F4")),
    ),
    Question(
        "radio-track",
        "The user's path",
        "Indoors, where fixes fail: how close does a radio map of other walks bring the user's path (no start, no truth), with the shipped model and with PDR?",
        ("radio-track",),
        (
            Pick("IPIN 2023: fixes + radio map", r"^fixes \+ radio map · phone$", "median (m)"),
            Pick("raw fixes", r"^raw phone fixes$", "median (m)"),
            Pick("ILC2: radio map + plan, no GNSS", r"^radio map \+ plan · phone$", "median (m)"),
        ),
    ),
    Question(
        "sim-fusion",
        "The user's path",
        "On the simulator's dense truth, what do the fixes and the smoother add to the shipped `phone` model?",
        ("fusion-phone", "fusion"),
    ),
    Question(
        "adapt",
        "The user's path",
        "How much does adapting a model to the user's own fixes help (`wearnav adapt`, IPIN 2023)?",
        ("adapt",),
    ),
    Question(
        "lobo-ipin",
        "Trained on real walks",
        "Trained on another building's real walks and the simulator, how good is Suite-IN++ in IPIN 2023?",
        ("seeds-lobo-ipin-polar-heading", "lobo-ipin-polar"),
    ),
    Question(
        "lobo-ilc2",
        "Trained on real walks",
        "Trained on another building's real walks and the simulator, how good is Suite-IN++ in ILC2?",
        ("seeds-lobo-ilc2-polar-heading",),
    ),
    Question(
        "in-building",
        "Trained on real walks",
        "Trained on the building's own walks, how close does Suite-IN++ get?",
        ("seeds-ipin-polar-heading",),
    ),
    Question(
        "sim-tables",
        "The simulator (Suite-IN++ Tables III–VI)",
        "On the simulator, how does Suite-IN++ compare with its baselines (Tables III–VI)?",
        ("odometry",),
    ),
    Question(
        "sim-tables-shipped",
        "The simulator (Suite-IN++ Tables III–VI)",
        "On the simulator, how good is the shipped three-device recipe (MSE loss, the phone's heading frame)?",
        ("odometry-small-suitein-mse-heading",),
    ),
    Question(
        "demo",
        "The simulator (Suite-IN++ Tables III–VI)",
        "What does `make demo` give (Suite-IN++, RoNIN and PDR on simulated walking)?",
        ("demo",),
    ),
    Question(
        "frame-alignment",
        "The simulator (Suite-IN++ Tables III–VI)",
        "How well is each device's heading aligned (yaw error on the simulator)?",
        ("frame-alignment",),
    ),
    Question(
        "activity",
        "Activity",
        "How good are the shipped activity models on datasets they never saw (leave one dataset out)?",
        ("har-lodo",),
        (
            Pick("MotionSense", r"^motionsense$", "LODO accuracy"),
            Pick("UCI HAPT", r"^uci-hapt$", "LODO accuracy"),
            Pick("UJI", r"^uji-phone$", "LODO accuracy"),
            Pick("Oxford", r"^oxford$", "LODO accuracy"),
            Pick("ILC2", r"^ilc2$", "LODO accuracy"),
            Pick("IPIN 2023", r"^ipin$", "LODO accuracy"),
        ),
        readme="Activity labels from a phone (`classify`, shipped `activity` model), each dataset held out",
    ),
    Question(
        "har-techniques",
        "Activity",
        "Which of paper 002's techniques help activity recognition (7 datasets, 3 seeds)?",
        ("har",),
    ),
    Question(
        "easytrack",
        "EasyTrack (paper 004)",
        "Does EasyTrack, learning from the phone's own fixes, beat its baselines (paper 004, Figure 3)?",
        ("easytrack",),
    ),
    Question(
        "easytrack-amended",
        "EasyTrack (paper 004)",
        "Where labels are nearly clean (today's simulator), does the amended CoAdapt stop costing accuracy against BaseModel?",
        ("easytrack-amended",),
    ),
    Question(
        "easytrack-base",
        "EasyTrack (paper 004)",
        "Why is BaseModel-GT far from the paper's 11.2 cm?",
        ("easytrack-base",),
    ),
    Question(
        "live",
        "Live and efficiency",
        "How many walkers can one `wearnav live` server keep up with?",
        ("live-bench-phone-batched", "live-bench"),
    ),
    Question(
        "efficiency",
        "Live and efficiency",
        "How big and how fast is each model (Table VI)?",
        ("efficiency-h100", "efficiency"),
    ),
)


__all__ = ["QUESTIONS", "Pick", "Question"]
