"""docs/results.md: the suites' generated pages stitched into one, one section per question.

Every suite (odometry comparison, efficiency, frame alignment, ...) writes its own ``results.md``
and PNGs into its folder from run folders only; this module never computes a number, it only
collects those pages, so every figure in the docs was produced by a suite command.

The page is organised by the questions in :data:`QUESTIONS` (the one registry of what the page
answers and which suite folders may answer it). A question has exactly one section: a suite given
again, or another suite answering the same questions, replaces the section (the replaced one gets
a line in ``docs/history.md``; git keeps its text), and a page on which two sections would answer
one question, or a suite that answers no registered question, is refused (``ConfigError``)
before anything is written. "At a glance" has one row per answered question; the README's first
screen takes its table from the same page (:func:`readme_table`).
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path

from wearnav.bench.questions import QUESTIONS, Pick, Question
from wearnav.core.fileio import atomic_path, shown_path, write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.core.textio import read_text
from wearnav.errors import ConfigError, MissingFileError

# Every metric a suite's page shows: (name, unit, one sentence). The glossary lists those the
# page uses; docs/design.md "Metric definitions" has the formulas.
GLOSSARY: tuple[tuple[str, str, str], ...] = (
    (
        "ATE",
        "m",
        "absolute trajectory error: RMS distance between the estimated and the true position over a "
        "whole walk, the estimate starting at the true start with no alignment.",
    ),
    (
        "RTE",
        "m",
        "relative trajectory error: the same over Δ = 60 s stretches (scaled for shorter walks, as "
        "RoNIN does), so it measures drift wherever the walk started.",
    ),
    (
        "STW, PVW, MVW, DRW, DLW",
        "—",
        "Suite-IN++'s walking modes (standard walking; holding the phone in "
        "front, calmly or moving; a device removed mid-walk; daily-living "
        "episodes); `STW ATE` is ATE over that mode's walks only.",
    ),
    (
        "ADE",
        "cm",
        "average displacement error: mean distance between each 1 s segment's estimated and true "
        "displacement (EasyTrack).",
    ),
    ("drift", "% of distance", "final position error divided by the distance walked."),
    (
        "label noise",
        "cm",
        "distance between a segment's displacement as the phone's location fixes give it and "
        "its true displacement (EasyTrack eqs. 5–7).",
    ),
    ("accuracy", "%", "share of test windows whose predicted class is the true one."),
    (
        "macro-F1",
        "%",
        "F1 = 2·TP / (2·TP + FP + FN) per class, averaged over classes with equal weight, so "
        "rare activities count as much as common ones.",
    ),
    ("Δ acc, Δ F1", "points", "a technique's accuracy or macro-F1 minus the baseline's, same seeds."),
    (
        "p < 0.05",
        "—",
        "p is Welch's two-sided t-test p-value of a technique against the baseline over "
        "seeds; a difference counts as real where the Benjamini–Hochberg-adjusted p < 0.05.",
    ),
    (
        "surveyed points",
        "m",
        "real buildings' errors: distance between the estimated position and each "
        "surveyed waypoint of a real walk (the only truth they have); mean, median, p75, p95.",
    ),
    (
        "params, MFLOPs per window",
        "count, 10⁶",
        "a model's weights, and the floating-point operations of one forward pass on one window (a multiply-add = 2).",
    ),
    (
        "MMACs per window",
        "10⁶",
        "multiply-accumulates of one forward pass on one window, LSTM/GRU included: "
        "what Suite-IN++'s Table VI calls FLOPs.",
    ),
    (
        "HD, MP, PK, BG",
        "—",
        "the phone's placement (Suite-IN++ Table IV): handheld, multi-changed, pocket, bag; "
        "no training walk has PK or BG.",
    ),
    (
        "†",
        "—",
        "a difference beyond seed spread: Welch's t-test over per-seed values, Benjamini–Hochberg-adjusted "
        "p < 0.05 (the page says against what).",
    ),
    ("windows/s", "1/s", "inference throughput on this machine at batch 1 or 256 (median of repeats)."),
    ("train s/epoch, train min", "s, min", "measured training time per epoch, and in total over a run's attempts."),
    (
        "yaw",
        "°",
        "frame alignment: error of a device's estimated heading about the vertical against the "
        "simulator's, RMS over time per recording.",
    ),
)


HEADLINE, GLOSSARY_HEADING = "## At a glance", "## Glossary"
HISTORY = "history.md"  # beside the page: one line per section a rerun replaced or --drop removed
README_BEGIN = "<!-- results:begin: generated by `wearnav results` from docs/results.md; do not edit -->"
README_END = "<!-- results:end -->"
_GENERATED = re.compile(
    r"Generated by `(?P<cmd>[^`]+)`[^(]*\((?P<date>[0-9T:+-]+), wearnav (?P<version>\S+) ?"
    r"(?P<commit>\w*)\)"
)
# The generator's own lines under a section's heading: the questions' anchors, then what produced it.
_ANCHORS = re.compile(r'^(?:<a id="[A-Za-z0-9_-]+"></a>)+$')
_SOURCE = re.compile(r"^> Suite `(?P<tag>[A-Za-z0-9_-]+)` \(its page: \*(?P<title>.*)\*\)")
_ABSOLUTE = re.compile(r"(?<![\w.~/])/(?:work|root|home|Users|tmp|mnt|data|scratch|opt|srv)/[^\s`)\]|,;]+")


def _relative_paths(text: str) -> str:
    """Absolute paths of the machine that wrote a page shown as :func:`shown_path` shows them."""
    return _ABSOLUTE.sub(lambda m: shown_path(m.group(0)), text)


def _tables(text: str) -> list[tuple[list[str], list[list[str]]]]:
    """Every Markdown table of ``text``: (header cells, body rows)."""
    tables, block = [], []
    for line in text.splitlines() + [""]:
        if line.lstrip().startswith("|"):
            block.append([c.strip() for c in line.strip().strip("|").split("|")])
            continue
        rows = [r for r in block if not all(set(c) <= set(":- ") for c in r)]
        if len(rows) >= 2:
            tables.append((rows[0], [r for r in rows[1:] if len(r) == len(rows[0])]))
        block = []
    return tables


_NUMBER = re.compile(r"[-+]?\d[\d.]*(e[-+]?\d+)?( ± [\d.]+)?( †)?")  # †: beyond seed spread
_METRIC_WORDS = ("ATE", "ADE", "accuracy", "F1", "error", "mean (m)", "median")


def _numbers(text: str, shown: int = 6) -> str:
    """The numbers a section leads with: in its first table that has a metric column (else its
    first table), each row's label and that column, ``a 3.87, b 2.73 (ATE)``."""
    tables = _tables(text)
    for want_metric in (True, False):
        for head, body in tables:
            for k in range(1, len(head)):
                values = [r[k] for r in body]
                if not any(_NUMBER.fullmatch(v) for v in values):
                    continue
                if want_metric and not any(w in head[k] for w in _METRIC_WORDS):
                    continue
                labels = [" ".join(c for c in r[:k] if c and not _NUMBER.fullmatch(c)) or r[0] for r in body]
                pairs = [f"{lab} {v}" for lab, v in zip(labels, values) if _NUMBER.fullmatch(v)]
                more = ", ..." if len(pairs) > shown else ""
                return f"{', '.join(pairs[:shown])}{more} ({head[k]})"
    return "—"


def _seeds(text: str) -> str:
    m = re.search(r"(\d+) seed\(s\)|(\d+) seeds\b|\bseeds? (\d+(?:, \d+)*)", text, flags=re.I)
    if not m:
        return "not stated"
    if m.group(3) is not None:
        return f"seed {m.group(3)}"
    return f"{m.group(1) or m.group(2)} seed(s)"


def _machine(text: str) -> str:
    m = re.search(r"(?:x86_64|aarch64|arm64|AMD64)[^;\n]*?(?=\.\s|;|\.?$)", text, flags=re.M)
    return m.group(0).strip().rstrip(",") if m else "not stated"


def _paper(text: str) -> str:
    m = re.search(r"Paper(?:'s)? [^.:]{0,40}: [^\n]*?\.(?=\s|$)", text)
    return m.group(0) if m else "not on its page"


@dataclass(frozen=True)
class Section:
    """One suite's section: its folder name (``tag``; None for a section from before sections were
    marked), its page's own title, and its page's text below that title."""

    tag: str | None
    title: str
    body: str


def questions_of(tag: str | None, questions: tuple[Question, ...] = QUESTIONS) -> tuple[Question, ...]:
    """The registered questions a suite folder's page answers (in the page's order)."""
    return tuple(q for q in questions if tag in q.suites)


def _pick(body: str, pick: Pick) -> str | None:
    """The cell :class:`Pick` names in ``body``, or None where no table has it."""
    parts = re.split(r"^(?=### )", body, flags=re.M)
    for part in parts:
        if pick.under and not re.match(rf"### [^\n]*{pick.under}", part):
            continue
        for head, rows in _tables(part):
            cols = [k for k, h in enumerate(head) if pick.column in h]
            if not cols:
                continue
            k = cols[0]
            for r in rows:
                if re.search(pick.row, " | ".join(c for c in r[:k] if c and not _NUMBER.fullmatch(c))):
                    return r[k] if _NUMBER.fullmatch(r[k]) else None
    return None


def lead(body: str, question: Question) -> str:
    """The numbers ``question``'s row leads with: its picks (``label value, ...  (column)``, "not on
    its page" for a pick its section lacks), else the section's first metric column (:func:`_numbers`)."""
    if not question.picks:
        return _numbers(body)
    cells = []
    for p in question.picks:
        value = _pick(body, p)
        cells.append(f"{p.label} {value}" if value is not None else f"{p.label}: not on its page")
    return f"{', '.join(cells)} ({question.picks[0].column})"


def produced(body: str) -> dict[str, str]:
    """What produced a suite's page, from its "Generated by" line: command, commit, date (day), and
    the machine where the page names one; "not recorded" for what the page does not say."""
    g = _GENERATED.search(body)
    machine = _machine(body)
    return {
        "command": g["cmd"] if g else "not recorded",
        "commit": g["commit"] if g and g["commit"] else "not recorded",
        "date": g["date"][:10] if g else "not recorded",
        "machine": "not recorded" if machine == "not stated" else machine,
    }


def render(section: Section, questions: tuple[Question, ...]) -> str:
    """A section under its first question's title: an anchor per question it answers (the links of
    "At a glance" and the README), what produced it, then the suite's page as the suite wrote it."""
    p = produced(section.body)
    return "\n".join(
        [
            f"## {questions[0].title} <!-- suite: {section.tag} -->",
            "",
            "".join(f'<a id="{q.id}"></a>' for q in questions),
            f"> Suite `{section.tag}` (its page: *{section.title}*) · produced by `{p['command']}` · "
            f"commit {p['commit']} · {p['date']} · machine: {p['machine']}",
            "",
            section.body,
        ]
    ).strip()


def _parse(heading: str, text: str) -> Section:
    """The :class:`Section` a page's ``## `` section holds (the generator's own lines dropped)."""
    tag = _tag(heading)
    title = re.sub(r"\s*<!--.*?-->\s*$", "", heading[3:]).strip()
    lines = text.splitlines()[1:]
    while lines and (not lines[0].strip() or _ANCHORS.match(lines[0]) or _SOURCE.match(lines[0])):
        m = _SOURCE.match(lines[0])
        if m:
            title = m["title"]
        lines.pop(0)
    return Section(tag, title, "\n".join(lines).strip())


def headline(answered: list[tuple[Question, Section]]) -> list[str]:
    """One screen: per answered question, one row: its current section's numbers (linked), the
    paper's figure where the section quotes one, the seeds, and the commit and date that produced it."""
    lines = [
        HEADLINE,
        "",
        "One row per question, its current answer only: the numbers its section leads with (the system and "
        "its baselines, row by row), linked to the section, where the command, commit, date and machine "
        "that produced it are named. Answers replaced by later runs: [history.md](history.md). "
        "Units and meanings: the glossary below.",
        "",
        "| | question | current answer | paper | seeds | commit | date |",
        "|:--|:--|:--|:--|:--|:--|:--|",
    ]
    group = None
    for q, s in answered:
        p = produced(s.body)
        cells = [
            f"**{q.group}**" if q.group != group else "",
            f"[{q.title}](#{q.id})",
            lead(s.body, q),
            _paper(s.body),
            _seeds(s.body),
            p["commit"],
            p["date"],
        ]
        group = q.group
        lines.append("| " + " | ".join(c.replace("|", "/") for c in cells) + " |")
    return lines + [""]


def glossary(text: str) -> list[str]:
    """The :data:`GLOSSARY` entries whose names occur in ``text``."""
    lines = [GLOSSARY_HEADING, ""]
    for name, unit, sentence in GLOSSARY:
        if any(re.search(rf"(?<!\w){re.escape(part.strip())}(?!\w)", text) for part in name.split(",")):
            lines.append(f"- **{name}** ({unit}): {sentence}")
    return lines + [""]


def _sections(text: str) -> list[tuple[str, str]]:
    """(heading, text) of each ``## `` section of a page this module wrote (its preamble dropped)."""
    parts = re.split(r"^(?=## )", text, flags=re.M)
    return [(p.splitlines()[0], p.strip()) for p in parts if p.startswith("## ")]


def _tag(heading: str) -> str | None:
    """The suite folder a section's heading is marked with (``<!-- suite: TAG -->``), if any."""
    m = re.search(r"<!-- suite: ([A-Za-z0-9_-]+) -->$", heading)
    return m.group(1) if m else None


def page_sections(text: str) -> list[Section]:
    """The suites' sections of a page this module wrote ("At a glance" and the glossary left out)."""
    return [_parse(h, t) for h, t in _sections(text) if h not in (HEADLINE, GLOSSARY_HEADING)]


def answers(sections: list[Section], questions: tuple[Question, ...] = QUESTIONS) -> list[tuple[Question, Section]]:
    """(question, the section answering it) in the registry's order. Refused (ConfigError): a section
    whose suite answers no registered question, and two sections answering one question."""
    for s in sections:
        if not questions_of(s.tag, questions):
            what = f"suite {s.tag!r}" if s.tag else f"section {s.title!r} (no suite marker)"
            raise ConfigError(
                f"{what} answers no registered question: add it to a question in "
                "wearnav.bench.questions.QUESTIONS, or --drop it"
            )
    out = []
    for q in questions:
        by = [s for s in sections if q in questions_of(s.tag, questions)]
        if len(by) > 1:
            raise ConfigError(
                f"two sections answer question {q.id!r}: suites {' and '.join(repr(s.tag) for s in by)}; "
                "--drop the superseded one"
            )
        out += [(q, s) for s in by]
    return out


def readme_table(text: str, page: str = "docs/results.md", questions: tuple[Question, ...] = QUESTIONS) -> list[str]:
    """The README's first-screen table from the results page ``text``: one row per question with a
    ``readme`` line, its numbers as "At a glance" gives them, linked to its section in ``page``."""
    lines = [
        README_BEGIN,
        "",
        "| what you get | how good, where it never trained | measured |",
        "|:--|:--|:--|",
    ]
    for q, s in answers(page_sections(text), questions):
        if q.readme:
            p = produced(s.body)
            lines.append(
                f"| {q.readme} | {lead(s.body, q)} | [its section]({page}#{q.id}), commit {p['commit']}, {p['date']} |"
            )
    return lines + ["", README_END]


def _readme_text(readme: Path, text: str, page: str, questions: tuple[Question, ...]) -> str | None:
    """The README with the block between its markers replaced by :func:`readme_table` (None: no
    markers, or nothing changed)."""
    old = read_text(readme)
    if README_BEGIN not in old or README_END not in old:
        return None
    head, rest = old.split(README_BEGIN, 1)
    new = head + "\n".join(readme_table(text, page, questions)) + rest.split(README_END, 1)[1]
    return new if new != old else None


def _history_lines(gone: list[tuple[Section, str]], commit: str, date: str) -> list[str]:
    """One table row per section that left the page: title, suite, what produced it, its numbers,
    the commit whose docs/results.md still holds it, and why it left."""
    rows = []
    for s, why in gone:
        p = produced(s.body)
        cells = [
            s.title,
            f"`{s.tag}`" if s.tag else "not marked",
            f"{p['commit']}, {p['date']}",
            _numbers(s.body),
            f"`{commit}`" if commit else "not recorded",
            f"{date}: {why}",
        ]
        rows.append("| " + " | ".join(c.replace("|", "/") for c in cells) + " |")
    return rows


HISTORY_HEAD = [
    "# Results that left the page",
    "",
    "Each row: a section of [results.md](results.md) that a later run replaced (a question has one "
    "section) or that was dropped as superseded, one line each, written by `wearnav results`. Its text "
    "and figures stay in git: `git show COMMIT:docs/results.md` (the commit in the fifth column).",
    "",
    "| section (its page's title) | suite | produced at (commit, date) | its numbers | in git at | left the page |",
    "|:--|:--|:--|:--|:--|:--|",
]


def _append_history(path: Path, rows: list[str]) -> None:
    text = read_text(path) if path.is_file() else "\n".join(HISTORY_HEAD) + "\n"
    write_text_atomic(text.rstrip("\n") + "\n" + "\n".join(rows) + "\n", path)


def collect(
    suites: list[Path],
    out: Path,
    title: str = "Measured results",
    keep: bool = False,
    drop: tuple[str, ...] = (),
    questions: tuple[Question, ...] = QUESTIONS,
) -> Path:
    """Write ``out`` from each suite's results.md (headings demoted one level), one section per
    question of ``questions``, and copy the PNGs each page links into ``out.parent/img/<suite>_<file>``.

    With ``keep``, the sections of the existing ``out`` stay, in the registry's order, unless a suite
    given now has the same folder name, or answers every question a kept section answers: that
    section is replaced (results measured on another machine or session are updated suite by suite
    instead of being lost, and a rerun replaces what it answers anew). ``drop``: suite folder names
    (or, for a section from before sections were marked, its heading text) whose kept sections are
    removed (superseded; ``SUITE=WHY`` says why in the history). Each section that leaves the page
    gets a line in ``out.parent/history.md``.
    Refused before anything is written (ConfigError / MissingFileError): a suite whose folder name
    answers no registered question, two sections answering one question, a page linking a figure
    its suite does not hold. Where ``out`` is ``docs/results.md`` beside a README.md holding the
    markers, the README's first-screen table is rewritten from the new page (:func:`readme_table`)."""
    out = Path(out)
    img = out.parent / "img"
    p = provenance()
    parts = [
        f"# {title}",
        "",
        f"Generated by `wearnav results` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) from the "
        "pages that the suite commands wrote; no number here is typed by hand. One section per question; "
        "a rerun replaces it.",
        "",
    ]
    # Every page and every figure it links is checked before anything is written, so a refused
    # call leaves docs/ (its page, its img/, history.md and the README) as it was.
    new: list[Section] = []
    copies: list[tuple[Path, Path]] = []
    for suite in map(Path, suites):
        page = suite / "results.md"
        if not page.is_file():
            raise MissingFileError("no results.md: run its suite command first", suite)
        text = read_text(page)
        tag = re.sub(r"[^A-Za-z0-9_-]+", "_", suite.name)

        # suite and tag bound as defaults: re.sub calls relink within this iteration, so the late
        # binding of a closure was no bug here, but the binding keeps it right if that ever changes
        def relink(m: re.Match, suite: Path = suite, tag: str = tag) -> str:
            src = suite / m.group(2)
            if not src.is_file():
                raise MissingFileError(f"results.md links {m.group(2)}, which is not in the suite folder", suite)
            dst = img / f"{tag}_{src.name}"
            copies.append((src, dst))
            return f"![{m.group(1)}]({dst.relative_to(out.parent).as_posix()})"

        text = re.sub(r"!\[([^\]]*)\]\(([^)\s]+\.png)\)", relink, text)
        text = re.sub(r"^(#+) ", lambda m: "#" + m.group(1) + " ", text, flags=re.M)
        # the suite's folder name marks its section, so two suites may share a title
        text = re.sub(r"^(## .*)$", rf"\1 <!-- suite: {tag} -->", text, count=1, flags=re.M)  # tag: [A-Za-z0-9_-]
        new += page_sections(text)
    old = page_sections(read_text(out)) if keep and out.is_file() else []
    why: dict[str, str] = {}  # suite folder name (or an unmarked section's heading) -> why it goes
    for d in drop:  # SUITE[=WHY]
        name, _, reason = d.partition("=")
        why[name] = why[re.sub(r"[^A-Za-z0-9_-]+", "_", name)] = reason or "dropped as superseded"
    gone = [(s, why.get(s.tag or "", why.get(s.title, ""))) for s in old if s.tag in why or s.title in why]
    old = [s for s in old if not (s.tag in why or s.title in why)]

    def ids(s: Section) -> set[str]:
        return {q.id for q in questions_of(s.tag, questions)}

    merged: list[Section] = []
    for s in old:
        by = next((n for n in new if n.tag == s.tag or (ids(s) and ids(s) <= ids(n))), None)
        if by is None:
            merged.append(s)
            continue
        if by.tag != s.tag or by.body != s.body:
            gone.append((s, f"replaced by suite `{by.tag}`"))
        if by not in merged:
            merged.append(by)
    merged += [n for n in new if n not in merged]
    answered = answers(merged, questions)
    order = {q.id: k for k, q in enumerate(questions)}
    merged.sort(key=lambda s: min(order[i] for i in ids(s)))
    merged = [Section(s.tag, s.title, _relative_paths(s.body)) for s in merged]
    answered = [(q, next(m for m in merged if m.tag == s.tag)) for q, s in answered]
    body = "\n".join(s.body for s in merged)
    parts += headline(answered) + glossary(body)
    for s in merged:
        parts += [render(s, questions_of(s.tag, questions)), ""]
    page_text = "\n".join(parts)
    readme = out.parent.parent / "README.md"
    readme_new = (
        _readme_text(readme, page_text, f"{out.parent.name}/{out.name}", questions)
        if out.parent.name == "docs" and readme.is_file()
        else None
    )
    for src, dst in copies:
        with atomic_path(dst) as tmp:
            shutil.copyfile(src, tmp)
    written = write_text_atomic(page_text, out)
    if gone:
        _append_history(out.parent / HISTORY, _history_lines(gone, p["commit"], p["created"][:10]))
    if readme_new is not None:
        write_text_atomic(readme_new, readme)
    return written
