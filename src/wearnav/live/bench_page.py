"""The page of `wearnav live bench` (:mod:`wearnav.live.bench`): results.md from the bench's results,
and what the bench and its page share: how the walkers batch their pushes and what keeping up means.
The page states what a message and a walker-second cost and what that makes a process's and the
machine's capacity (:func:`costs`, issue 61)."""

from __future__ import annotations

from wearnav.live.tracker import STEP_S

BATCH_S = 0.2  # each push holds this much of a walk (s), as Sensor Logger's HTTP push batches it
LATENCY_GOAL_S = 1.0  # issue 23: a push's 200 → the updated path, p95
# Keeping up with real time: the path trails the pushes by a bounded time, not a growing one. The
# tracker reads the buffer once per STEP_S of new data (live/tracker.py), so even an idle server
# shows about that plus an update; 2 s means the updates no longer keep pace.
KEPT_UP_UPDATE_S = 2.0

WALKER_NAMES = {"phone": "phone-only", "all": "three-device"}


def _yes(x) -> str:
    return "–" if x is None else ("yes" if x else "no")


def capacity_line(rows: list[dict]) -> str:
    """The largest count of ``rows`` (one kind of walker, counts in increasing order) that kept up,
    and the first that did not."""
    kept = [w["walkers"] for w in rows if w["kept_up"]]
    goal = [w["walkers"] for w in rows if w.get("latency_goal_met")]
    tried = ", ".join(str(w["walkers"]) for w in rows)
    if not kept:
        line = f"none of {tried} walkers kept up"
    elif len(kept) == len(rows):
        line = f"at least {max(kept)} walkers (all of {tried} kept up)"
    else:
        line = f"{max(kept)} walkers kept up, {rows[-1]['walkers']} did not (tried {tried})"
    if rows and rows[0]["tracking"]:
        line += f", {max(goal) if goal else 'none'} within the {LATENCY_GOAL_S:g}-s p95 goal"
    return line


# What receiving and tracking cost before issue 61 (docs/live-scaling.md): the receiver's CPU per
# message (100 phone-only walkers' pushes, storing only) and the tracker's per walker-second
# (phone-only, in one process; 16 ms on a quiet machine, 38–42 ms under load).
BEFORE_RECEIVER_MS = 1.9
BEFORE_TRACKER_MS = (16.0, 42.0)


def costs(r: dict) -> dict:
    """What receiving and tracking cost, from the rows that kept up (a row that fell behind did less
    than it was given, so its CPU per walker says nothing), and what that makes a core and this
    machine. Measured, not subtracted: ``server_ms_per_walker_s`` per tracking row is its CPU
    (receiver and trackers) per walker-second; with tracker processes the receiver's own CPU gives
    its ``receiver_ms_per_message`` at that crowd's rate and the trackers' the
    ``tracker_ms_per_walker_s``; without them the receiver and the tracking share a process and
    only their sum is known. ``load_receiver_ms_per_message``: the load phase's (one sender at 50
    messages a second: its idle wake-ups included, not a crowd's rate)."""
    ld, cores = r["load"], r["machine"].get("cores") or 1
    share = ld.get("cpu_share_of_one_core")
    out: dict = {
        "load_receiver_ms_per_message": None
        if share is None or not ld["messages"]
        else round(1e3 * share * ld["wall_s"] / ld["messages"], 3),
        "server_ms_per_walker_s": {},
        "receiver_ms_per_message": {},
        "tracker_ms_per_walker_s": {},
    }
    kept = [
        w for w in r["walkers"] if w.get("tracking") and w["kept_up"] and w.get("cpu_share_of_one_core") is not None
    ]
    for w in kept:
        key = f"{w['devices']}-{w['walkers']}"
        out["server_ms_per_walker_s"][key] = round(1e3 * w["cpu_share_of_one_core"] / w["walkers"], 2)
        rx = w.get("receiver_cpu_share_of_one_core")
        if rx is not None and w["messages"]:
            out["receiver_ms_per_message"][key] = round(1e3 * rx * w["seconds"] / w["messages"], 3)
            out["tracker_ms_per_walker_s"][key] = round(1e3 * (w["cpu_share_of_one_core"] - rx) / w["walkers"], 2)
    if kept:  # the largest crowd kept up: where the costs of a crowd show (fixed costs spread the most)
        big = max(kept, key=lambda w: w["walkers"])
        key = f"{big['devices']}-{big['walkers']}"
        per = out["server_ms_per_walker_s"][key]
        out["largest_kept_up"] = key
        out["walkers_per_core"] = int(1e3 / per) if per > 0 else None
        out["walkers_per_machine_estimate"] = int(cores * 1e3 / per) if per > 0 else None
        if key in out["tracker_ms_per_walker_s"] and out["tracker_ms_per_walker_s"][key] > 0:
            out["walkers_per_tracker_core"] = int(1e3 / out["tracker_ms_per_walker_s"][key])
            out["messages_per_s_per_receiver_core"] = int(1e3 / out["receiver_ms_per_message"][key])
    return out


def _cost_rows(cost: dict, cores: int) -> list[str]:
    """The summary table's cost and capacity rows (:func:`costs`)."""
    big = cost.get("largest_kept_up")
    rx, trk = cost["receiver_ms_per_message"].get(big), cost["tracker_ms_per_walker_s"].get(big)
    n = None if big is None else big.rsplit("-", 1)[1]  # the walkers of the largest crowd kept up
    load_rx = cost["load_receiver_ms_per_message"]
    rows = [
        f"| receiver CPU per message (ms; {BEFORE_RECEIVER_MS:g} before issue 61) | "
        + (
            f"{rx:g} (the receiver process at {n} walkers)"
            if rx is not None
            else f"{'?' if load_rx is None else f'{load_rx:g}'} (the load phase: one sender at 50 messages a second, its idle wake-ups included)"
        )
        + " |",
        f"| tracking CPU per walker-second (ms; {BEFORE_TRACKER_MS[0]:g}–{BEFORE_TRACKER_MS[1]:g} before issue 61) | "
        + (
            f"{trk:g} (the tracker processes at {n} walkers)"
            if trk is not None
            else "not apart from receiving (one process): see the next row"
        )
        + " |",
    ]
    if big is not None:
        per = cost["server_ms_per_walker_s"][big]
        rows.append(f"| receiving and tracking CPU per walker-second (ms; at {n} walkers) | {per:g} |")
        rows.append(
            "| capacity per process | "
            + (
                f"a tracker core: {cost['walkers_per_tracker_core']} walkers; a receiver core: "
                f"{cost['messages_per_s_per_receiver_core']} messages a second"
                if cost.get("walkers_per_tracker_core")
                else f"a core receiving and tracking: {cost['walkers_per_core']} walkers"
            )
            + " (from the largest crowd kept up) |"
        )
        rows.append(
            f"| capacity of this machine ({cores} cores) | measured: {n} walkers kept up; "
            f"the cores' worth at that cost: {cost['walkers_per_machine_estimate']} (the senders and the "
            "latency goal not counted) |"
        )
    return rows


def page(r: dict) -> str:
    ld, rows, p = r["load"], r["walkers"], r["provenance"]
    cost = costs(r)
    bad, fl = r["bad_inputs"], r["faults"]
    lost = sum(d["lost"] for d in ld["devices"].values())
    dup = sum(d["duplicated"] for d in ld["devices"].values())
    devs = "\n".join(
        f"| {dev} | {d['samples']} | {d['lost']} | {d['duplicated']} | {'yes' if d['equal'] else 'no'} |"
        for dev, d in ld["devices"].items()
    )
    one = rows[0]
    tracking = one["tracking"]
    # the odometry each kind of walker was tracked by (recorded since the phone-only default became a choice)
    models = {w["devices"]: f" (`{w['model']}`)" for w in rows if w.get("model")}

    def pc(x):
        return "?" if x is None else f"{100 * x:.1f} %"

    def _kept(w: dict) -> str:
        gave = w.get("gave_up")
        return "yes" if w["kept_up"] else f"no ({gave['walkers']} gave up: {gave['first']})" if gave else "no"

    table = "\n".join(
        f"| {WALKER_NAMES[w.get('devices', 'all')]} | {w['walkers']} | {pc(w['cpu_share_of_one_core'])} | "
        f"{pc(w.get('senders_cpu_share_of_one_core'))} | "
        f"{w['ack_ms']['p50']} | {w['ack_ms']['p99']} | "
        f"{w['update_ms']['p50'] if tracking else '–'} | {w['update_ms']['p95'] if tracking else '–'} | "
        f"{w['behind_at_end_s']} | {_kept(w)} | {_yes(w.get('latency_goal_met'))} | "
        f"{' → '.join(f'{x:g}' for x in w['load_1min']) if 'load_1min' in w else '?'} |"
        for w in rows
    )
    kinds = list(dict.fromkeys(w.get("devices", "all") for w in rows))
    kept = {k: [w["walkers"] for w in rows if w.get("devices", "all") == k and w["kept_up"]] for k in kinds}
    capacity = "; ".join(
        f"{WALKER_NAMES[k]}: {capacity_line([w for w in rows if w.get('devices', 'all') == k])}" for k in kinds
    )
    return "\n".join(
        [
            "# Live receiver (wearnav live)",
            "",
            f"Generated by `wearnav live bench` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) on this machine: "
            f"{r['machine']['cpu']}, {r['machine']['cores']} CPUs, odometry models on {r['machine'].get('models_on', 'cpu')}; a real `wearnav live` process on 127.0.0.1 fed by "
            "`wearnav replay` over HTTP from a simulated walk written as an iPhone's Sensor Logger export (phone's four "
            "motion sensors and the watch at 100 Hz, earbuds at 25 Hz, fixes at 1 Hz: 526 samples per second of walk; "
            f"{BATCH_S:g}-s batches). Ack latency: POST sent → 200 received, the message committed to SQLite "
            "(WAL, synchronous=FULL) first. The machine is shared: timings vary with load.",
            "",
            "| measure | value |",
            "|---|---|",
            f"| ack latency p99 at {ld['speed']:g}× real time (ms) | {ld['ack_ms']['p99']} |",
            f"| lost samples at {ld['speed']:g}× | {lost} |",
            f"| duplicated samples at {ld['speed']:g}× | {dup} |",
            f"| server CPU, one walker (% of one core) | {'?' if one['cpu_share_of_one_core'] is None else round(100 * one['cpu_share_of_one_core'], 1)} |",
            *([f"| tracker update p95, one walker (ms) | {one['update_ms']['p95']} |"] if tracking else []),
            *[f"| {WALKER_NAMES[k]} walkers kept up at real time | {max(kept[k]) if kept[k] else 0} |" for k in kinds],
            *_cost_rows(cost, r["machine"].get("cores") or 1),
            f"| bad inputs refused as expected | {bad['catalogue'] - len(bad['catalogue_wrong'])} |",
            f"| acknowledged messages lost in {fl['kills']} SIGKILLs | {fl['acknowledged_missing']} |",
            "",
            f"## Load: {ld['data_s']:g} s of walk at {ld['speed']:g}× real time",
            "",
            f"{ld['messages']} messages ({ld['samples']} samples) in {ld['wall_s']} s (schedule {ld['schedule_s']} s; "
            f"{ld['behind_at_end_s']} s behind at the end), {ld['acknowledged']} acknowledged, {ld['retries']} retries. "
            f"Ack latency: p50 {ld['ack_ms']['p50']} ms, p95 {ld['ack_ms']['p95']} ms, p99 {ld['ack_ms']['p99']} ms, "
            f"max {ld['ack_ms']['max']} ms. The server process used {pc(ld['cpu_share_of_one_core'])} of one core "
            f"(storing only, no tracking: {ld['speed']:g} walkers' worth of pushes). Lost samples: {lost}, duplicated: "
            f"{dup} (the stored session exported with `wearnav live export`, compared with `wearnav import` of the same "
            "export):",
            "",
            "| device | samples | lost | duplicated | equal to the import |",
            "|---|---|---|---|---|",
            devs,
            "",
            f"## Walkers at real time ({one['seconds']} s each, {'with' if tracking else 'without'} live tracking)",
            "",
            "Each walker is one session pushing in real time (phone-only: the phone's four motion sensors and fixes, "
            f"tracked by the default phone-only model{models.get('phone', '')}; three devices: phone, watch, earbuds, "
            f"tracked by the shipped three-device model{models.get('all', '')}); all at once into one server"
            + (
                f", which only stores: {one['tracker_processes']} `wearnav live track` processes beside it track the "
                "sessions (sharded), reading its store. CPU: the user + system time of the server and the trackers "
                "together over the wall time, as a share of one core. "
                if one.get("tracker_processes")
                else ", which tracks every session in batched ticks (one forward pass per tick for all sessions). CPU: "
                "the server process's user + system time over the wall time, as a share of one core. "
            )
            + (
                "Update: from the oldest 200 whose samples are not yet on the page (with tracker processes: from the "
                "receiver storing it, just before its 200) to the tracker update that put them "
                "there (an update that changed the path, fixes or activity; the tracker reads the buffer once "
                f"{STEP_S:g} s of new data have arrived). "
                if tracking
                else "No live tracker in this installation: storing and serving only. "
            )
            + "Kept up: every message acknowledged, under 1 s behind schedule at the end"
            + (
                f", update p95 under {KEPT_UP_UPDATE_S:g} s (the path trails by a bounded time); the issue's goal is a "
                f"p95 under {LATENCY_GOAL_S:g} s."
                if tracking
                else "."
            ),
            "",
            "| walker | walkers | server CPU | senders' CPU | ack p50 ms | ack p99 ms | update p50 ms | update p95 ms "
            f"| behind at end s | kept up | p95 under {LATENCY_GOAL_S:g} s | machine load (1 min, before → after) |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
            table,
            "",
            f"CPU share at one walker ({WALKER_NAMES[one.get('devices', 'all')]}): {pc(one['cpu_share_of_one_core'])} "
            f"of one core. Capacity (the largest count kept up): {capacity}."
            + (
                ""
                if not tracking or one["update_ms"]["p95"] is None
                else f" Push → path p95 at one walker: {one['update_ms']['p95'] / 1e3:.2f} s, the {LATENCY_GOAL_S:g}-s goal "
                + (
                    "met."
                    if one["latency_goal_met"]
                    else f"not met: the tracker waits for {STEP_S:g} s of new data "
                    "before it reads the buffer, and a push carries 0.2 s."
                )
            ),
            "",
            "## Bad input and faults",
            "",
            f"Bad input (token required, 64-KiB body limit, 20 messages a second): {bad['catalogue']} bad bodies "
            f"(malformed JSON, not UTF-8, NaN / inf, wrong types, missing columns, values no sensor reports, times a day "
            f"ahead or years back, ids with path characters, a body over the limit): {bad['catalogue'] - len(bad['catalogue_wrong'])} answered "
            f"with the expected 4xx{' (not: ' + '; '.join(bad['catalogue_wrong']) + ')' if bad['catalogue_wrong'] else ''}; "
            f"{bad['fuzz']} random byte mutations of a good body: {bad['fuzz_answers']['refused']} refused with 400/422, "
            f"{bad['fuzz_answers']['accepted']} still valid pushes and accepted ({bad['fuzz_answers']['stored']} new), "
            f"{bad['fuzz_answers']['other']} answered otherwise; rows in the store after all of these: "
            f"{bad['rows_after_bad']} (the new valid ones only). Without the "
            f"token: {bad['no_token_401']} of 5 answered 401. A flood of {bad['flood']} messages at once: "
            f"{bad['flood_429']} answered 429, {bad['flood_200']} accepted, {bad['flood_stored']} stored.",
            "",
            f"Faults: {fl['kills']} SIGKILLs of the server during a {fl['messages']}-message replay at {ld['speed']:g}×, "
            f"each followed by a restart on the same store; acknowledged messages missing after a restart: "
            f"{fl['acknowledged_missing']}; the replay's retries ({fl['retries']}) filled in the rest "
            f"({fl['acknowledged']} acknowledged); the final export "
            f"{'equals' if fl['export_equal'] else 'differs from'} importing the export directly.",
            "",
        ]
    )
